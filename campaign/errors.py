"""Errors that end a command with exit status 2 and one line on stderr starting with `error:`."""

from pathlib import Path
from typing import Any

from protocols.errors import FormatError, one_line


class InputError(Exception):
    """Bad input: a file, a config, a serial line or a command-line value.

    The message says what is wrong and where (file, line, column or key). The CLI prints it as
    `error: <message>` and exits with status 2. Control characters from the input (line breaks in
    a value, say) are escaped so that the message is always one line.
    """

    def __init__(self, message: str = ""):
        super().__init__(one_line(message))


BAD_INPUT = (InputError, FormatError)
"""Every error that means bad input (exit status 2): ours and the pure format code's."""


class CampaignInterrupted(KeyboardInterrupt):
    """Ctrl-C during a campaign, after the axis was asked to halt and the recording was flushed.
    `directory`: the campaign directory, for the resume hint."""

    def __init__(self, directory: str | Path) -> None:
        super().__init__(str(directory))
        self.directory = directory


class SafetyError(InputError):
    """A motion would leave the soft limits or exceed the velocity limit. Nothing was commanded."""


def read_input_bytes(path: str | Path, what: str, limit: int = -1) -> bytes:
    """The bytes of an input file (at most `limit`, all by default); InputError naming the file
    when it is missing, a directory or unreadable. `what` names the expected kind of file."""
    name = str(path)
    try:
        with open(path, "rb") as f:
            return f.read(limit)
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{name}: is a directory, not {what}") from None
    except OSError as exc:
        raise InputError(f"{name}: cannot read ({exc.strerror or exc})") from None


def read_input_text(path: str | Path, what: str) -> str:
    """An input file as UTF-8 text (BOM allowed); InputError for any problem."""
    try:
        return read_input_bytes(path, what).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (bad byte at offset {exc.start})") from None


def read_toml(path: str | Path, what: str) -> dict[str, Any]:
    """A TOML input file, parsed; InputError for any problem."""
    import tomllib

    try:
        return tomllib.loads(read_input_text(path, what))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None

"""Errors that end a command with exit status 2 and one line on stderr starting with `error:`."""


def one_line(text: str) -> str:
    """`text` with line breaks and other control characters escaped, so it prints as one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


class InputError(Exception):
    """Bad input: a file, a config, a serial line or a command-line value.

    The message says what is wrong and where (file, line, column or key). The CLI prints it as
    `error: <message>` and exits with status 2. Control characters from the input (line breaks in
    a value, say) are escaped so that the message is always one line.
    """

    def __init__(self, message: str = ""):
        super().__init__(one_line(message))


class SafetyError(InputError):
    """A motion would leave the soft limits or exceed the velocity limit. Nothing was commanded."""

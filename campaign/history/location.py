"""Where the campaign store is, and how to name it without its credentials.

The store is found without any set-up: `--db` (a command's option), else the environment
variable AXISCAL_DB, else a SQLite file at the default location,
$XDG_DATA_HOME/axiscal/history.sqlite (~/.local/share/axiscal/history.sqlite when XDG_DATA_HOME is
not set). Either names a database URL (`postgresql://user@host/db`, `sqlite:///path`) or a path
of a SQLite file. `none` (or `off`) records nothing.

A URL may carry a password; it is never printed, logged or written into a report or an event:
everything that names a store says `display_url(url)`, which masks it (and every message of a
database error passes through `scrub`).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from campaign.errors import InputError

ENV = "AXISCAL_DB"
"""The environment variable that names the store (a URL or a path)."""

OFF = ("none", "off")
"""Values of --db / AXISCAL_DB that turn the store off: nothing is recorded."""

DRIVERS = {"postgresql": "postgresql+psycopg", "postgres": "postgresql+psycopg"}
"""A URL without a driver gets the one axiscal ships (psycopg 3)."""


def data_dir() -> Path:
    """axiscal's data folder: $XDG_DATA_HOME/axiscal, or ~/.local/share/axiscal."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "axiscal"


def default_path() -> Path:
    """The embedded store's default file."""
    return data_dir() / "history.sqlite"


def chosen(option: str | None = None) -> str | None:
    """What names the store: `option` (--db), else $AXISCAL_DB, else the default file; None when
    the store is turned off."""
    value = option if option else os.environ.get(ENV, "")
    value = value.strip()
    if value.lower() in OFF:
        return None
    return value or str(default_path())


def store_url(option: str | None = None) -> str | None:
    """The SQLAlchemy URL of the store (None: turned off). A path becomes sqlite:///ABSOLUTE."""
    value = chosen(option)
    if value is None:
        return None
    if "://" not in value:
        return "sqlite:///" + str(Path(value).expanduser().resolve())
    scheme, rest = value.split("://", 1)
    if scheme.lower() not in DRIVERS and not scheme.lower().startswith(("sqlite", "postgresql")):
        raise InputError(f"--db: {display_url(value)}: not a store axiscal knows (use sqlite:///PATH, "
                         "postgresql://USER@HOST/DB or a file path)")
    return DRIVERS.get(scheme.lower(), scheme) + "://" + rest


_CREDENTIALS = re.compile(r"(?P<scheme>[a-z][a-z0-9+.-]*://)(?P<user>[^:/@\s]*)(?::(?P<password>[^@/\s]*))?@",
                          re.IGNORECASE)
_PASSWORD_ITEM = re.compile(r"(password\s*=\s*)('[^']*'|\S+)", re.IGNORECASE)


def display_url(url: str) -> str:
    """The URL as it may be shown: the password (if any) replaced by ***."""
    def mask(m: re.Match[str]) -> str:
        hidden = ":***" if m.group("password") is not None else ""
        return f"{m.group('scheme')}{m.group('user')}{hidden}@"

    return _CREDENTIALS.sub(mask, url)


def passwords(url: str) -> list[str]:
    """The secrets a URL carries (to be scrubbed from any message that might repeat them)."""
    found = [m.group("password") for m in _CREDENTIALS.finditer(url) if m.group("password")]
    from urllib.parse import unquote

    return [p for secret in found for p in {secret, unquote(secret)} if p]


def scrub(message: str, url: str) -> str:
    """A message (a driver's error, say) with the URL's credentials masked, one line."""
    text = display_url(message)
    for secret in passwords(url):
        text = text.replace(secret, "***")
    text = _PASSWORD_ITEM.sub(r"\1***", text)
    return " ".join(text.split())

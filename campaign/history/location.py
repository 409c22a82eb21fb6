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
from typing import Any

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


_CREDENTIALS = re.compile(r"(?P<scheme>[a-z][a-z0-9+.-]*://)(?P<user>[^:/@\s]*)(?::(?P<password>[^@\s]*))?@",
                          re.IGNORECASE)
"""A URL's user and password inside a message (the password may hold '/': the last '@' ends it)."""
_SECRET_KEY = re.compile(r"pass|pwd|secret|token", re.IGNORECASE)
"""Query keys whose value is a secret (password=, sslpassword=, ...)."""
_PASSWORD_ITEM = re.compile(r"((?:pass\w*|pwd|secret|token)\s*=\s*)('[^']*'|[^&\s]+)", re.IGNORECASE)
"""A `password=...` item in a message (a query string, a libpq connection string)."""


def _parsed(url: str) -> Any:
    """The URL as SQLAlchemy reads it (sqlalchemy.engine.URL), or None when it is not one."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(url)
    except Exception:  # noqa: BLE001 - not a URL SQLAlchemy reads: masked by pattern instead
        return None


def display_url(url: str) -> str:
    """The URL as it may be shown: the password replaced by ***, password-like query items
    (password=, sslpassword=, ...) left out. Read by SQLAlchemy's own parser (a password may hold
    '/' or '@'); what it cannot read is masked by pattern."""
    parsed = _parsed(url) if "://" in url else None
    if parsed is None:
        return _PASSWORD_ITEM.sub(r"\1***", _mask_urls(url))
    secret_keys = [key for key in parsed.query if _SECRET_KEY.search(key)]
    if secret_keys:
        parsed = parsed.difference_update_query(secret_keys)
    return str(parsed.render_as_string(hide_password=True))


def _mask_urls(text: str) -> str:
    def mask(m: re.Match[str]) -> str:
        hidden = ":***" if m.group("password") is not None else ""
        return f"{m.group('scheme')}{m.group('user')}{hidden}@"

    return _CREDENTIALS.sub(mask, text)


def passwords(url: str) -> list[str]:
    """The secrets a URL carries (to be scrubbed from any message that might repeat them): its
    password and its password-like query values, as given and URL-encoded."""
    from urllib.parse import quote, unquote

    found = [m.group("password") for m in _CREDENTIALS.finditer(url) if m.group("password")]
    parsed = _parsed(url) if "://" in url else None
    if parsed is not None:
        if parsed.password:
            found.append(str(parsed.password))
        for key, value in parsed.query.items():
            if _SECRET_KEY.search(key):
                found += [value] if isinstance(value, str) else list(value)
    secrets = {variant for secret in found for variant in (secret, unquote(secret), quote(secret, safe=""))}
    return sorted((s for s in secrets if s), key=len, reverse=True)  # the longest first: none left half-masked


def scrub(message: str, url: str) -> str:
    """A message (a driver's error, say) with the URL's credentials masked, one line."""
    text = message
    for secret in passwords(url):
        text = text.replace(secret, "***")
    text = _PASSWORD_ITEM.sub(r"\1***", _mask_urls(text))
    return " ".join(text.split())


def store_label(url: str) -> str:
    """The store's short name, as every line and report shows it: a SQLite store by its file name,
    a server store by its host and database ("db.plant:5432/axiscal"); never a URL, never a
    password."""
    parsed = _parsed(url) if "://" in url else None
    if parsed is None:
        return Path(url).name or display_url(url)
    if str(parsed.drivername).startswith("sqlite"):
        return Path(parsed.database or ":memory:").name
    host = f"{parsed.host or 'localhost'}" + (f":{parsed.port}" if parsed.port else "")
    return f"{host}/{parsed.database or ''}"


def store_place(url: str) -> str:
    """Where the store is, in full but without credentials: a SQLite store's path, a server
    store's URL with its password masked (for errors and `history store`)."""
    parsed = _parsed(url) if "://" in url else None
    if parsed is not None and str(parsed.drivername).startswith("sqlite"):
        return str(parsed.database or ":memory:")
    return display_url(url)

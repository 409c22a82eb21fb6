"""Part programs: the campaign's plan as an NC program for a controller axiscal does not drive
(pure text; one module per dialect with `render(program) -> str`). docs/part-programs.md cites
the manuals each dialect follows and says what is not verified."""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from protocols.errors import FormatError

DIALECTS = ("linuxcnc", "fanuc", "siemens", "heidenhain")
AXIS_LETTERS = "XYZABCUVW"


@dataclass(frozen=True)
class NcMove:
    """Move the axis to `position` (mm or degree) at `feed` (mm/min or degree/min), then dwell
    `dwell_s` seconds (0: none). `comment`: one line said before the move, or ''."""

    position: float
    feed: float
    dwell_s: float = 0.0
    comment: str = ""


@dataclass(frozen=True)
class NcProgram:
    """axis: the axis letter. unit: mm or deg. name: the program's name (letters, digits, _).
    header: comment lines at the start (campaign id, machine, software)."""

    axis: str
    unit: str
    name: str
    header: tuple[str, ...]
    moves: tuple[NcMove, ...]


def clean_comment(text: str) -> str:
    """A comment every dialect takes: printable ASCII, no parentheses or semicolons."""
    return "".join(c if 32 <= ord(c) < 127 and c not in "();" else " " for c in text).strip()


def render(dialect: str, program: NcProgram) -> str:
    """The program in `dialect` (one of DIALECTS). FormatError for an axis letter the dialect
    does not know."""
    if dialect not in DIALECTS:
        raise FormatError(f"unknown dialect '{dialect}' (one of {', '.join(DIALECTS)})")
    if len(program.axis) != 1 or program.axis.upper() not in AXIS_LETTERS:
        raise FormatError(f"axis name '{program.axis}' is not an NC axis letter ({', '.join(AXIS_LETTERS)}): "
                          "set [axis] name")
    return importlib.import_module(f"protocols.nc.{dialect}").render(program)

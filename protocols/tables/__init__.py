"""Compensation table formats: one module per controller, pure functions returning text.

Every module has `render(table, options) -> Rendered`. `table` is a
campaign.compensation.grid.ControllerTable (positions in the axis unit, corrections in the
deviation unit, correction = what the control adds to the command, ≈ -error); each module
converts to its controller's units and sign. docs/compensation-formats.md documents them all.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field

FORMATS = ("linuxcnc", "pmac", "twincat_cnc", "siemens", "fanuc", "heidenhain", "csv", "json")


@dataclass(frozen=True)
class FormatOptions:
    """axis_name: the controller's axis name (Siemens AX1, Heidenhain X, ...). joint: LinuxCNC
    joint number. motor: PMAC motor number. counts_per_unit: encoder counts (PMAC) or detection
    units (Fanuc) per axis unit (mm or degree); None when the format does not use it."""

    axis_name: str = "X"
    joint: int = 0
    motor: int = 1
    counts_per_unit: float | None = None
    provenance: tuple[tuple[str, str], ...] = ()
    """Where the table comes from (machine, axis, points file, software), for formats that can
    carry it."""


@dataclass(frozen=True)
class Rendered:
    """text: the file's content. notes: what else to set on the controller (INI lines,
    parameters), one line each."""

    text: str
    notes: list[str] = field(default_factory=list)


def render(name: str, table, options: FormatOptions = FormatOptions()) -> Rendered:
    """Render `table` in format `name` (one of FORMATS)."""
    if name not in FORMATS:
        raise ValueError(f"unknown format '{name}'")
    return importlib.import_module(f"protocols.tables.{name}").render(table, options)

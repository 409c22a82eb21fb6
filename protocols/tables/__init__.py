"""Compensation table formats: one module per controller, pure functions of text.

Every module has `render(table, options) -> Rendered` and `parse(text, path, options) -> TableRead`
(what `verify` loads back; json is read by campaign.compensation.table_file). `table` is a
campaign.compensation.grid.ControllerTable (positions in the axis unit, corrections in the
deviation unit, correction = what the control adds to the command, ≈ -error); each module
converts to its controller's units and sign. docs/compensation-formats.md documents them all.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


class CorrectionTable(Protocol):
    """What a renderer reads of an equidistant correction table (campaign.compensation.grid's
    ControllerTable): positions in the axis unit, corrections in the deviation unit (µm, arcsec)."""

    @property
    def kind(self) -> str: ...
    @property
    def start(self) -> float: ...
    @property
    def spacing(self) -> float: ...
    @property
    def forward(self) -> np.ndarray: ...
    @property
    def reverse(self) -> np.ndarray: ...
    @property
    def common(self) -> np.ndarray: ...
    @property
    def mode(self) -> str: ...
    @property
    def backlash(self) -> float | None: ...
    @property
    def overrun(self) -> float: ...
    @property
    def reference(self) -> float | None: ...
    @property
    def positions(self) -> np.ndarray: ...
    @property
    def unit_factor(self) -> float: ...


FORMATS = ("linuxcnc", "pmac", "twincat_cnc", "siemens", "fanuc", "heidenhain", "csv", "json", "ecmc")


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
    units: str = "mm"
    """LinuxCNC: the machine's units, mm or inch (an inch machine needs an inch table)."""
    axis_number: int | None = None
    """TwinCAT CNC: kopf.achs_nr, the logical axis number (1..65534; 0 is not allowed)."""
    control: str | None = None
    """The control's generation where it matters: siemens 840d|828d|808d (point limit),
    heidenhain tnc640|tnc426 (the older TNCs need a power-of-two spacing)."""
    """Where the table comes from (machine, axis, points file, software), for formats that can
    carry it."""


@dataclass(frozen=True)
class Rendered:
    """text: the file's content. notes: what else to set on the controller (INI lines,
    parameters), one line each."""

    text: str
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class TableRead:
    """A correction table read back from a controller file. start, spacing: position of point 0
    and the distance between points, axis unit (mm or degree). forward, reverse: the correction
    the control adds to the command when moving +/-, axis unit, one per point. mode: bi, or uni
    when the file holds one table (forward == reverse; a backlash parameter is not in the file).
    kind: linear or rotary when the file says, else None."""

    start: float
    spacing: float
    forward: tuple[float, ...]
    reverse: tuple[float, ...]
    mode: str
    kind: str | None = None


SIGNATURES = (("%_N_AX_EEC_INI", "siemens"), ("kw.ssfk.", "twincat_cnc"), ("DEFINE COMP", "pmac"),
              ("pitch[", "fanuc"), ("BEGIN ", "heidenhain"), ("position_", "csv"), ("\nPREC=", "ecmc"))
"""Text that only one format's files hold near their start, in the order tried."""


def sniff(text: str) -> str | None:
    """The format of a table file's text, or None when nothing matches. LinuxCNC files have no
    marker: three numbers on the first line."""
    head = text.lstrip("\ufeff")[:2000]
    if head.lstrip().startswith("{"):
        return "json"
    if head.startswith("PREC="):  # ecmc's precision line, first in the file
        return "ecmc"
    for marker, name in SIGNATURES:
        if marker in head:
            return name
    first = head.strip().splitlines()[0].split() if head.strip() else []
    try:
        return "linuxcnc" if len(first) == 3 and all(float(x) == float(x) for x in first) else None
    except ValueError:
        return None


def number(text: str, path: str, line: int, what: str = "value") -> float:
    """A finite number from a table file; FormatError naming the line otherwise."""
    import math

    from protocols.errors import FormatError

    try:
        value = float(text)
    except ValueError:
        raise FormatError(f"{path}: line {line}: {what} '{text}' is not a number") from None
    if not math.isfinite(value):
        raise FormatError(f"{path}: line {line}: {what} '{text}' is not a finite number")
    return value


def provenance_lines(options: FormatOptions, prefix: str) -> list[str]:
    """The provenance as comment lines starting with `prefix` (where the format has comments)."""
    return [f"{prefix}{key}: {value}" for key, value in options.provenance if value]


def equidistant(positions: list[float], path: str) -> tuple[float, float]:
    """(start, spacing) of equidistant, increasing positions; FormatError otherwise."""
    from protocols.errors import FormatError

    if len(positions) < 2:
        raise FormatError(f"{path}: a table needs at least 2 points, found {len(positions)}")
    spacing = (positions[-1] - positions[0]) / (len(positions) - 1)
    if spacing <= 0 or any(abs(p - (positions[0] + i * spacing)) > 1e-6 * max(1.0, abs(spacing))
                           for i, p in enumerate(positions)):
        raise FormatError(f"{path}: the table's positions are not equidistant and increasing")
    return positions[0], spacing


def parse(name: str, text: str, path: str, options: FormatOptions = FormatOptions()) -> TableRead:
    """Read a table file of format `name` (one of FORMATS but json)."""
    if name not in FORMATS or name == "json":
        raise ValueError(f"no reader for format '{name}'")
    return importlib.import_module(f"protocols.tables.{name}").parse(text, path, options)


def render(name: str, table: CorrectionTable, options: FormatOptions = FormatOptions()) -> Rendered:
    """Render `table` in format `name` (one of FORMATS)."""
    if name not in FORMATS:
        raise ValueError(f"unknown format '{name}'")
    return importlib.import_module(f"protocols.tables.{name}").render(table, options)

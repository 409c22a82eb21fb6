"""Resampling corrections to a controller's table: equidistant points, a point limit, a zero at
the reference position, end zones. Values keep the sign and unit of campaign/compensation/corrections.py
(correction, deviation unit: µm or arcsec); positions are in the axis unit (mm or degree).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from campaign.compensation.corrections import AXIS_UNIT_PER_DEVIATION_UNIT, Corrections
from campaign.errors import InputError
from protocols.compensator import table_lookup
from protocols.plc_contract import CompTable

POINT_LIMITS = {"linuxcnc": 256, "pmac": 256, "twincat_cnc": 1500, "siemens": 1000, "fanuc": 128,
                "heidenhain": 256, "csv": 1024, "json": 1024, "ecmc": 1024}
"""Format -> largest number of points the controller takes (TwinCAT CNC: kw.ssfk.max_points default;
Fanuc: about 128 between the extremes,
reference.md §3; Siemens: MD38000 sets it, 1000 is a common limit; csv/json/ecmc: our own cap, ecmc's
lookup table sets none)."""


@dataclass(frozen=True)
class ControllerTable:
    """An equidistant correction table.

    start, spacing: position of point 0 and distance between points, axis unit (spacing > 0).
    forward, reverse: correction when moving +/-, deviation unit, one value per point.
    common: the single table of `uni` mode, deviation unit. backlash: B̄ of `uni` mode with both
    directions measured (forward = common - B̄/2, reverse = common + B̄/2), deviation unit, else
    None. overrun: end-zone length L1, axis unit (0: none). reference: position where the table
    was shifted to 0 (axis unit), or None.
    """

    kind: str
    start: float
    spacing: float
    forward: np.ndarray
    reverse: np.ndarray
    common: np.ndarray
    mode: str
    backlash: float | None
    overrun: float = 0.0
    reference: float | None = None

    @property
    def positions(self) -> np.ndarray:
        """Position of every point, axis unit."""
        return self.start + self.spacing * np.arange(len(self.forward))

    @property
    def unit_factor(self) -> float:
        """Axis unit per deviation unit (mm/µm or degree/arcsec)."""
        return AXIS_UNIT_PER_DEVIATION_UNIT[self.kind]

    def correction(self, position: float, direction: int) -> float:
        """The correction (deviation unit) at `position` (axis unit) moving in `direction` (+1/-1),
        with the end zones, as the PLC evaluates it."""
        values = self.forward if direction > 0 else self.reverse
        return table_lookup(list(values), self.start, self.spacing, self.overrun, position)

    def to_plc(self, max_rate: float, max_accel: float, enabled: bool = True) -> CompTable:
        """The table for GVL_Axiscal.astComp[n]: values in axis unit. max_rate (axis unit/s) and
        max_accel (axis unit/s²) bound the planned correction."""
        f = self.unit_factor
        return CompTable(tuple(self.forward * f), tuple(self.reverse * f), self.start, self.spacing,
                         self.overrun, max_rate, max_accel, enabled)


def grid(targets: np.ndarray, max_points: int, spacing: float | None = None,
         reference: float | None = None, origin: float | None = None) -> tuple[float, float, int]:
    """(start, spacing, count) of an equidistant grid covering the measured targets (axis unit).

    Without `spacing`: the targets' own spacing when they are equidistant and few enough, else
    span/(max_points - 1). With `reference` (else `origin`: a campaign's first nominal target),
    the grid is aligned so that point is a grid point, and it reaches one spacing beyond the
    targets where needed to cover them. More than `max_points` points with a given spacing is an
    InputError.
    """
    if max_points < 2:
        raise InputError(f"--max-points must be at least 2, got {max_points}")
    low, high = float(targets[0]), float(targets[-1])
    span = high - low
    steps = np.diff(targets)
    if spacing is not None and not (math.isfinite(spacing) and spacing > 0):
        raise InputError(f"--spacing must be a number > 0, got {spacing}")
    if reference is not None and not low <= reference <= high:
        raise InputError(f"--reference {reference:g} is outside the measured range {low:g}..{high:g}")
    equidistant = np.allclose(steps, steps[0], rtol=1e-9, atol=1e-12 * max(1.0, span))
    derived = spacing is None
    if spacing is None:
        spacing = float(steps[0]) if equidistant and len(targets) <= max_points else span / (max_points - 1)
    origin = reference if reference is not None else (origin if origin is not None else low)
    for _ in range(2):
        first = math.floor((low - origin) / spacing + 1e-9)
        last = math.ceil((high - origin) / spacing - 1e-9)
        count = last - first + 1
        if count <= max_points:
            return origin + first * spacing, spacing, count
        if not derived:
            break
        spacing = span / (max_points - 2)  # aligned to a reference: one spacing more to cover
    raise InputError(f"spacing {spacing:g} gives {count} points over {low:g}..{high:g}; "
                     f"the controller takes at most {max_points} (use a larger --spacing)")


def resample(corr: Corrections, max_points: int, spacing: float | None = None,
             reference: float | None = None, overrun: float = 0.0, origin: float | None = None) -> ControllerTable:
    """The corrections on a controller's grid (see `grid`), by linear interpolation between the
    measured targets (end values held beyond them). With `reference` (axis unit), every table is
    shifted by the same amount so that the correction is 0 there: the common table in `uni`
    mode, the forward table in `bi` mode (the reverse table keeps its offset, the reversal).
    `origin`: a point the grid goes through (the campaign's first nominal target)."""
    if overrun < 0 or not math.isfinite(overrun):
        raise InputError(f"--overrun must be >= 0, got {overrun}")
    start, step, count = grid(corr.targets, max_points, spacing, reference, origin)
    points = start + step * np.arange(count)
    forward = np.interp(points, corr.targets, corr.forward)
    reverse = np.interp(points, corr.targets, corr.reverse)
    common = np.interp(points, corr.targets, corr.common)
    if reference is not None:
        zeroed = corr.common if corr.mode == "uni" else corr.forward
        shift = float(np.interp(reference, corr.targets, zeroed))
        forward, reverse, common = forward - shift, reverse - shift, common - shift
    return ControllerTable(corr.kind, start, step, forward, reverse, common, corr.mode, corr.backlash,
                           overrun, reference)

"""The compensation calculator: from a point table to the correction a controller should apply.

Signs, everywhere in axiscal:

- **error** e = measured position - target (the ISO 230-2 deviation), in the deviation unit
  (µm for a linear axis, arcsec for a rotary axis);
- **correction** c = what the control adds to the commanded position so that the axis lands on
  the target, in the same deviation unit. To first order c = -e.

Steps: the mean unidirectional deviations x̄↑, x̄↓ per target (iso230.evaluate); the mode
(`uni`: one table from the mean of both directions and a constant backlash B̄; `bi`: one table
per direction; `auto`: see `choose_mode`); per direction, the correction at each target by
inverse interpolation (the 2024 motion-planning patent, see `inverse_corrections`) of the means, smoothed where they
lie on a polynomial within their scatter (campaign/compensation/smooth.py). Resampling to a
controller's grid and the end zones are in campaign/compensation/grid.py; the predicted result
in campaign/compensation/predict.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from campaign.compensation.smooth import SMOOTHING, Smoothing, pool, scatter_within_runs, smooth_means
from campaign.errors import InputError
from campaign.iso230 import evaluate
from campaign.pointtable import PointTable
from protocols.units import DEVIATION_SCALE, UNITS, unit_label

MODES = ("uni", "bi", "auto")

AXIS_UNIT_PER_DEVIATION_UNIT = {kind: 1.0 / DEVIATION_SCALE[units[0]] for kind, units in UNITS.items()}
"""Axis kind -> axis unit per deviation unit: mm per µm, degree per arcsec."""


@dataclass(frozen=True)
class Corrections:
    """Corrections at the measured targets.

    targets: axis unit, increasing. forward / reverse: correction for an approach in the + / -
    direction, deviation unit (for `uni` they are common ∓ backlash/2). common: the one table of
    `uni` mode ((forward + reverse)/2 otherwise), deviation unit. backlash: B̄ = mean reversal,
    deviation unit (uni mode with both directions measured), else None. inverse_minus_simple:
    per direction (+1, -1) the inverse-interpolated correction minus the simple -e, deviation unit.
    smoothing: how the means became the table's errors, per direction (+1, -1), or under 0 for
    the one table of `uni` mode.
    """

    kind: str
    targets: np.ndarray
    forward: np.ndarray
    reverse: np.ndarray
    common: np.ndarray
    mode: str
    reason: str
    backlash: float | None
    inverse_minus_simple: dict[int, np.ndarray]
    method: str = "inverse"
    smoothing: dict[int, Smoothing] = field(default_factory=dict)

    @property
    def max_inverse_minus_simple(self) -> float:
        """Largest |inverse - simple| over both directions, deviation unit."""
        return float(max(np.max(np.abs(v)) for v in self.inverse_minus_simple.values()))


def interp_extended(x: np.ndarray | float, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """Linear interpolation of (xp, fp) at x, extended linearly beyond the first and last
    interval (np.interp would hold the end values). xp increasing, at least 2 points. Returns
    an array (length 1 for a scalar x)."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    out = np.interp(x, xp, fp)
    low, high = x < xp[0], x > xp[-1]
    out[low] = fp[0] + (x[low] - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0])
    out[high] = fp[-1] + (x[high] - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
    return out


def inverse_corrections(targets: np.ndarray, errors: np.ndarray, unit_factor: float) -> np.ndarray:
    """Corrections (deviation unit) that put the actual position on each target (the 2024 motion-planning patent).

    The measured actual positions a_i = P_i + e_i * unit_factor (axis unit) form the grid of
    the mapping command -> actual. The command that lands on target P_k is found by linear
    interpolation of the inverse mapping (actual -> command) at P_k, extended linearly beyond
    the end intervals; the correction is (command - P_k) / unit_factor. The simple method gives
    -e_k; the two differ by about e_k times the slope of the error.
    """
    actual = targets + errors * unit_factor
    steps = np.diff(actual)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise InputError(f"the measured positions do not increase between targets {targets[i]:g} and "
                         f"{targets[i + 1]:g}: the errors are larger than the target spacing")
    command = interp_extended(targets, actual, targets)
    return (command - targets) / unit_factor


def choose_mode(requested: str, reversals: np.ndarray | None, scatter: np.ndarray | None,
                k: float = 2.0, unit: str = "µm") -> tuple[str, str]:
    """The mode to use and why (the reason names `unit`, the deviation unit: µm or arcsec).

    reversals: B_i = x̄↑_i - x̄↓_i per target (deviation unit), None with one direction only.
    scatter: every s↑_i and s↓_i (deviation unit), None when there is one run only.

    `auto` picks `bi` when the reversal varies along the axis by more than the noise: when
    max B_i - min B_i exceeds the repeatability of a single approach, 2k·s_pooled (4 s_pooled
    for ISO 230-2:2014), s_pooled = sqrt(mean of all s²). A constant backlash then leaves a
    residual larger than the scatter every point shows anyway. Without s (one run) `auto` picks
    `bi`, which keeps every measured difference between the directions.
    """
    if requested not in MODES:
        raise InputError(f"--mode: unknown mode '{requested}' (use {', '.join(MODES)})")
    if reversals is None:
        if requested == "bi":
            raise InputError("--mode bi needs both directions; the table has one")
        return "uni", "measured in one direction only: one table, no backlash value"
    variation = float(np.max(reversals) - np.min(reversals))
    if requested != "auto":
        return requested, f"requested (reversal varies by {variation:.3f} {unit} along the axis)"
    if scatter is None:
        return "bi", "one run only: no scatter to judge the reversal's variation; bidirectional"
    pooled = float(np.sqrt(np.mean(np.square(scatter))))
    limit = 2 * k * pooled
    if variation > limit:
        return "bi", (f"the reversal varies by {variation:.3f} {unit} along the axis, more than the "
                      f"repeatability {2 * k:g}·s = {limit:.3f} {unit}: bidirectional")
    return "uni", (f"the reversal varies by {variation:.3f} {unit} along the axis, within the repeatability "
                   f"{2 * k:g}·s = {limit:.3f} {unit}: one table plus backlash B̄")


def corrections(table: PointTable, mode: str = "auto", method: str = "inverse",
                smooth: str = "auto") -> Corrections:
    """The corrections at the measured targets of `table` (see `Corrections`).

    mode: uni, bi or auto (`choose_mode`). method: `inverse` (the 2024 motion-planning patent, default) or `simple`
    (c = -e at each target). smooth: `auto` (default, `smooth_means`) or `none` (the raw means).
    """
    if method not in ("inverse", "simple"):
        raise InputError(f"unknown correction method '{method}' (use inverse or simple)")
    if smooth not in SMOOTHING:
        raise InputError(f"unknown smoothing '{smooth}' (use {' or '.join(SMOOTHING)})")
    ev = evaluate(table)
    rows = ev.targets
    if len(rows) < 2:
        raise InputError(f"{table.source}: a compensation table needs at least 2 targets")
    targets = np.array([r.target for r in rows])
    up = [r.mean_up for r in rows]
    down = [r.mean_down for r in rows]
    both = None not in up and None not in down
    reversals = np.array([r.B for r in rows]) if both else None
    sds = [s for r in rows for s in (r.s_up, r.s_down) if s is not None]
    scatter = np.array(sds) if ev.runs > 1 and sds else None
    chosen, reason = choose_mode(mode, reversals, scatter, unit=unit_label(table.deviation_unit))
    factor = AXIS_UNIT_PER_DEVIATION_UNIT[table.kind]
    within = {d: scatter_within_runs(table.run[table.direction == d], table.target[table.direction == d],
                                     table.deviation[table.direction == d]) for d in table.directions}
    n_up = np.array([max(r.n_up, 1) for r in rows], dtype=float)
    n_down = np.array([max(r.n_down, 1) for r in rows], dtype=float)

    def solve(errors: np.ndarray, var_weights: np.ndarray,
              s2: tuple[float, int] | None) -> tuple[np.ndarray, np.ndarray, Smoothing]:
        smoothed = smooth_means(targets, errors, var_weights, s2, smooth)
        inverse = inverse_corrections(targets, smoothed.values, factor)
        return (inverse if method == "inverse" else -smoothed.values), inverse + smoothed.values, smoothed

    if reversals is None:  # one direction measured
        d = 1 if None not in up else -1
        common, diff, sm = solve(np.array(up if d > 0 else down, dtype=float), 1 / (n_up if d > 0 else n_down),
                                within.get(d))
        return Corrections(table.kind, targets, common, common, common, "uni", reason, None, {d: diff}, method,
                           {d: sm})
    up_e, down_e = np.array(up, dtype=float), np.array(down, dtype=float)
    if chosen == "uni":
        backlash = float(np.mean(reversals))
        common, diff, sm = solve((up_e + down_e) / 2, (1 / n_up + 1 / n_down) / 4, pool(within[1], within[-1]))
        return Corrections(table.kind, targets, common - backlash / 2, common + backlash / 2, common,
                           "uni", reason, backlash, {1: diff, -1: diff}, method, {0: sm})
    forward, diff_up, sm_up = solve(up_e, 1 / n_up, within[1])
    reverse, diff_down, sm_down = solve(down_e, 1 / n_down, within[-1])
    return Corrections(table.kind, targets, forward, reverse, (forward + reverse) / 2, "bi", reason, None,
                       {1: diff_up, -1: diff_down}, method, {1: sm_up, -1: sm_down})

"""The predicted result of a compensation table: the measured points as they would be with the
table applied, evaluated to ISO 230-2, next to the floor the repeatability allows.

Model (deviation unit: µm or arcsec; positions in the axis unit): per direction d the axis's
error at a commanded position x is ē_d(x), the linear interpolation of the measured means
x̄_d (extended linearly beyond the ends, as the inverse interpolation assumes), plus the
point's own scatter x_ij - x̄_d,i. The controller commands
C = P + c_d(P)·f to reach target P (c_d: the table's correction, f: axis unit per deviation
unit), so the predicted deviation is

    x'_ij = (x_ij - x̄_d,i) + ē_d(C) + c_d(P).

The scatter of every target is kept, so s↑_i, s↓_i are unchanged. Floor: with every mean
deviation at 0, ISO 230-2 gives A = max(2s) - min(-2s) = 4·s_max, s_max the largest s↑_i or
s↓_i (2k·s_max for coverage factor k); no table can do better (reference.md §5), and
A >= 4·s_max holds for any means.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from campaign.compensation.corrections import interp_extended
from campaign.compensation.grid import ControllerTable
from campaign.iso230 import Evaluation, evaluate
from campaign.pointtable import PointTable


@dataclass(frozen=True)
class Prediction:
    """accuracy_before / accuracy_after: ISO 230-2 A (bidirectional, or the one measured
    direction's), deviation unit. floor: 4·s_max, deviation unit (None with one run).
    after: the predicted point table; evaluation: its evaluation."""

    accuracy_before: float | None
    accuracy_after: float | None
    floor: float | None
    after: PointTable
    evaluation: Evaluation


def _accuracy(ev: Evaluation) -> float | None:
    s = ev.summary
    return s["A"] if s["A"] is not None else (s["A_up"] if s["A_up"] is not None else s["A_down"])


def predict(table: PointTable, ctable: ControllerTable) -> Prediction:
    """Apply `ctable` to the measured points of `table` (see the module text)."""
    before = evaluate(table)
    f = ctable.unit_factor
    deviation = np.empty(len(table))
    for d in table.directions:
        suffix = "up" if d > 0 else "down"
        targets = np.array([r.target for r in before.targets])
        means = np.array([getattr(r, f"mean_{suffix}") for r in before.targets])
        pick = table.direction == d
        for i in np.flatnonzero(pick):
            target = table.target[i]
            mean_here = means[np.searchsorted(targets, target)]
            correction = ctable.correction(float(target), d)
            command = target + correction * f
            error_at_command = float(interp_extended(command, targets, means)[0])
            deviation[i] = table.deviation[i] - mean_here + error_at_command + correction
    after = replace(table, deviation=deviation, source=f"{table.source} (predicted)")
    ev = evaluate(after)
    sds = [s for r in before.targets for s in (r.s_up, r.s_down) if s is not None]
    floor = 2 * before.standard.k * max(sds) if before.runs > 1 and sds else None
    return Prediction(_accuracy(before), _accuracy(ev), floor, after, ev)

"""Two campaigns of an axis side by side: their mean deviation curves (ISO 230-2's per-target
means, campaign/iso230.py, from the points the store holds) and the difference, with its
uncertainty.

Per target the bidirectional mean x̄ = (x̄↑ + x̄↓)/2 (or the one direction measured), its standard
uncertainty from the runs' scatter, u(x̄) = ½·√(s↑²/n↑ + s↓²/n↓) (s/√n for one direction), and
each campaign's instrument and environment terms for E (its budget's terms other than the
statistics: an upper bound, since they are stated for the whole travel). The difference second − first has
U = 2·√(u_A² + u_B² + u_inst,A² + u_inst,B²) (k = 2); it is beyond its uncertainty where
|second − first| > U. Only the targets both campaigns measured are compared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from campaign.history.axis import RANDOM_TERMS
from campaign.iso230 import Evaluation, TargetResult, evaluate
from campaign.pointtable import PointTable
from protocols.units import unit_label


def table_of(row: dict[str, Any], points: list[tuple[int, int, float, float, float | None]]) -> PointTable:
    """The point table of a stored campaign."""
    run, direction, target, deviation, _ = (np.array(c) for c in zip(*points)) if points else ([], [], [], [], [])
    return PointTable(kind=row["axis_kind"], run=np.asarray(run, dtype=int), direction=np.asarray(direction, dtype=int),
                      target=np.asarray(target, dtype=float), deviation=np.asarray(deviation, dtype=float),
                      source=row["label"])


def instrument_u(budget: dict[str, Any]) -> float:
    """A campaign's instrument and environment terms for E, standard, deviation unit."""
    return math.sqrt(sum(float(t["u"]) ** 2 for t in budget.get("terms") or []
                         if "E" in t.get("applies_to", ()) and not str(t.get("name", "")).startswith(RANDOM_TERMS)))


def _mean(t: TargetResult) -> tuple[float | None, float | None]:
    """(x̄, u(x̄)) of one target: both directions when measured, else the one there is."""
    parts = [(m, s, n) for m, s, n in ((t.mean_up, t.s_up, t.n_up), (t.mean_down, t.s_down, t.n_down)) if m is not None]
    if not parts:
        return None, None
    mean = sum(m for m, _, _ in parts) / len(parts)
    if any(s is None for _, s, _ in parts):
        return mean, None
    return mean, math.sqrt(sum((s or 0.0) ** 2 / n for _, s, n in parts)) / len(parts)


@dataclass
class Comparison:
    first: dict[str, Any]
    second: dict[str, Any]
    unit: str
    position_unit: str
    rows: list[dict[str, Any]]
    only_one: int
    evaluations: tuple[Evaluation, Evaluation]

    @property
    def beyond(self) -> list[dict[str, Any]]:
        return [r for r in self.rows if r["U"] is not None and abs(r["difference"]) > r["U"]]

    def sentence(self) -> str:
        known = [r for r in self.rows if r["U"] is not None]
        if not self.rows:
            return "the two campaigns have no target in common: nothing to compare"
        if not known:
            return "the difference has no stated uncertainty (a campaign of one run): it cannot be judged"
        worst = max(self.rows, key=lambda r: abs(r["difference"]))
        u = "n/a" if worst["U"] is None else f"{worst['U']:.2f}"
        return (f"the mean deviation differs beyond its uncertainty at {len(self.beyond)} of {len(self.rows)} "
                f"targets; the largest difference is {worst['difference']:+.2f} ± {u} {unit_label(self.unit)} at "
                f"{worst['target']:g} {self.position_unit}")

    def other_axis(self) -> str | None:
        """Why the two are not one axis seen twice, when they are not: they name other machines or axes
        (the difference then compares two axes, not one over time)."""
        a, b = self.first, self.second
        if (a["machine"], a["axis"]) == (b["machine"], b["axis"]):
            return None
        return (f"campaign {a['id']} measured machine '{a['machine']}' axis '{a['axis']}', campaign {b['id']} machine "
                f"'{b['machine']}' axis '{b['axis']}': this compares two axes, not one axis over time")

    def as_json(self) -> dict[str, Any]:
        def who(row: dict[str, Any]) -> dict[str, Any]:
            return {"id": row["id"], "label": row["label"], "date": None if row["measured_utc"] is None
                    else row["measured_utc"].date().isoformat(), "location": row["location"]}

        return {"first": who(self.first), "second": who(self.second), "unit": self.unit,
                **({"other_axis": other} if (other := self.other_axis()) else {}),
                "position_unit": self.position_unit, "targets": self.rows, "targets_not_in_both": self.only_one,
                "beyond_uncertainty": len(self.beyond), "sentence": self.sentence(),
                "uncertainty": "U (k = 2) of the difference: the runs' scatter of both means and both campaigns' "
                               "instrument and environment terms for E (an upper bound)"}


def compare(first: dict[str, Any], first_points: list, second: dict[str, Any], second_points: list) -> Comparison:
    """Compare two stored campaigns, the first and the second (rows of Store.find, points of Store.points): second − first."""
    ev_a, ev_b = evaluate(table_of(first, first_points)), evaluate(table_of(second, second_points))
    inst = math.hypot(instrument_u(first["uncertainty"]), instrument_u(second["uncertainty"]))
    by_target = {round(t.target, 6): t for t in ev_b.targets}
    rows, common = [], 0
    for t in ev_a.targets:
        other = by_target.get(round(t.target, 6))
        if other is None:
            continue
        common += 1
        (ma, ua), (mb, ub) = _mean(t), _mean(other)
        if ma is None or mb is None:
            continue
        u = None if ua is None or ub is None else 2.0 * math.sqrt(ua ** 2 + ub ** 2 + inst ** 2)
        rows.append({"target": t.target, "first": round(ma, 4), "second": round(mb, 4),
                     "difference": round(mb - ma, 4), "U": None if u is None else round(u, 4),
                     "first_up": t.mean_up, "first_down": t.mean_down, "second_up": other.mean_up,
                     "second_down": other.mean_down})
    only_one = len(ev_a.targets) + len(ev_b.targets) - 2 * common
    return Comparison(first, second, ev_a.unit, ev_a.position_unit, rows, only_one, (ev_a, ev_b))

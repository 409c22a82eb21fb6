"""The history of one axis as the store holds it: which campaigns count for its trend (and why
the others do not), their A, E, B, R with U, and the trend (campaign/history/trend.py).

Counted: the campaigns of the machine and axis that are re-checks of it (an acceptance test, or a
verification after a compensation, which enters as a known step: the compensation changed the
axis), completed with every planned point, dated, in the unit of the latest. Left out, each with
its reason: a follow-up or a diagnostic (listed, never trended: not a re-check), a converted table
(a copy read by `axiscal convert`), stopped, incomplete or undated campaigns, another unit. A
measurement recorded twice (a campaign and a copy of its table: the same fingerprint) counts once.
Each parameter takes the campaigns that give it with its U and its uncertainty between re-checks.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field
from typing import Any

from campaign.history.trend import ChangePoint, Crossing, Fit, Observation, analyse, crossing
from campaign.specs import JUDGED_PURPOSES

TRENDED = ("A", "E", "B", "R")
RANDOM_TERMS = ("statistics", "reading resolution")
"""Budget terms that differ from campaign to campaign (campaign/uncertainty.py); the others (the
instrument, the air, the temperature) are common to an axis's campaigns measured the same way."""


def u_random(budget: dict[str, Any], parameter: str) -> float | None:
    """The random part of a campaign's uncertainty of `parameter` (standard, deviation unit): its
    budget's statistics and resolution terms; None when the budget lists no terms."""
    terms = budget.get("terms") or []
    parts = [float(t["u"]) for t in terms if parameter in t.get("applies_to", ())
             and str(t.get("name", "")).startswith(RANDOM_TERMS)]
    return math.sqrt(sum(u * u for u in parts)) if parts else None


def is_known_step(row: dict[str, Any]) -> bool:
    """A verification after a compensation: the axis was changed on purpose just before it."""
    return row.get("purpose") == "verification" or bool(row["with_compensation"])


def why_left_out(row: dict[str, Any], unit: str) -> str:
    """Why a campaign does not count for the trend ("" when it counts)."""
    if row["source"] == "converted":
        return ("a converted table (read by axiscal convert): a copy in another format, not a campaign of its own "
                "(axiscal history import FILE records it as a measurement)")
    purpose = str(row.get("purpose") or "acceptance")
    if purpose not in JUDGED_PURPOSES:
        of = f" of {row['follows']}" if row.get("follows") else ""
        return f"a {purpose}{of}, not a re-check of the axis ([campaign] purpose = \"{purpose}\"): listed, never trended"
    if row["source"] == "directory" and row["status"] != "completed":
        done = f"{row['points']} of {row['points_planned']} points" if row["points_planned"] else f"{row['points']} points"
        if row["status"] == "running":  # no stop record: its process was killed, or still measures
            return f"not finished ({done}; no stop recorded: killed, or still running; `axiscal resume` continues it)"
        return f"{row['status']} campaign ({done}; `axiscal resume` continues it)"
    if row["points_planned"] and row["points"] < row["points_planned"]:
        return f"incomplete: {row['points']} of {row['points_planned']} points"
    if row["measured_utc"] is None:
        return "undated"
    if row["unit"] != unit:
        return f"in {row['unit']}, the axis's latest campaigns in {unit}"
    return ""


@dataclass
class AxisTrend:
    machine: str
    axis: str
    unit: str
    counted: list[dict[str, Any]]
    left_out: list[tuple[dict[str, Any], str]]
    fits: dict[str, Fit] = field(default_factory=dict)
    jumps: list[ChangePoint] = field(default_factory=list)
    crossing: Crossing | None = None
    tolerance: float | None = None
    known_steps: list[dict[str, Any]] = field(default_factory=list)
    """The verifications after a compensation counted: a known step before each."""

    def step_sentences(self) -> list[str]:
        return [f"compensation verified by {r['label']} on {_day(r['measured_utc'])}: a known step in every "
                "parameter's line" for r in self.known_steps]

    def as_json(self) -> dict[str, Any]:
        def campaign(row: dict[str, Any]) -> dict[str, Any]:
            out = {"id": row["id"], "date": _day(row["measured_utc"]), "label": row["label"],
                   "command": row["command"], "purpose": row.get("purpose", "acceptance"),
                   "known_step": is_known_step(row), "verdict": row["verdict"], "location": row["location"]}
            for p in TRENDED:
                value, u = row["results"].get((p, "both"), (None, None))
                out[p], out[f"U_{p}"] = value, u
                out[f"u_recheck_{p}"] = row.get("recheck", {}).get(p)
            return out

        return {"machine": self.machine, "axis": self.axis, "unit": self.unit,
                "campaigns": [campaign(r) for r in self.counted],
                "left_out": [{"id": r["id"], "label": r["label"], "date": _day(r["measured_utc"]), "reason": why}
                             for r, why in self.left_out],
                "drift": {p: f.as_json(self.unit) for p, f in self.fits.items()},
                "change_points": [j.as_json(self.unit) for j in self.jumps],
                "known_steps": [{"id": r["id"], "label": r["label"], "date": _day(r["measured_utc"]),
                                 "sentence": sentence} for r, sentence in zip(self.known_steps, self.step_sentences())],
                "crossing": None if self.crossing is None else self.crossing.as_json(self.unit)}


def _day(when: dt.datetime | None) -> str | None:
    return None if when is None else when.date().isoformat()


def axis_trend(rows: list[dict[str, Any]], machine: str, axis: str, tolerance: float | None = None,
               parameters: tuple[str, ...] = TRENDED) -> AxisTrend:
    """The trend of one axis from its store rows (Store.campaigns(machine, axis)). `tolerance`:
    on A, instead of the latest campaign's recorded one. `parameters`: those to trend (the plant
    needs A, and B, whose jumps step A's line)."""
    dated = [r for r in rows if r["measured_utc"] is not None]
    unit = (dated or rows)[-1]["unit"] if rows else "um"
    counted: list[dict[str, Any]] = []
    left_out: list[tuple[dict[str, Any], str]] = []
    seen: dict[str, str] = {}
    for row in rows:
        why = why_left_out(row, unit)
        if not why and row["fingerprint"] in seen:
            why = f"the same measurement as {seen[row['fingerprint']]} (a copy of its table)"
        if why:
            left_out.append((row, why))
            continue
        seen[row["fingerprint"]] = row["label"]
        counted.append(row)
    series: dict[str, list[Observation]] = {}
    for p in parameters:
        series[p] = []
        for row in counted:
            value, u = row["results"].get((p, "both"), (None, None))
            if value is not None and u is not None:
                between = row.get("recheck", {}).get(p) or u_random(row.get("uncertainty") or {}, p)
                series[p].append(Observation(row["measured_utc"], row["label"], float(value), float(u), between))
    trend = AxisTrend(machine, axis, unit, counted, left_out)
    trend.known_steps = [r for i, r in enumerate(counted) if i > 0 and is_known_step(r)]
    trend.fits, trend.jumps = analyse(series, [r["measured_utc"] for r in trend.known_steps])
    if tolerance is None and counted:
        tolerance = counted[-1]["tolerances"].get("A")
    trend.tolerance = tolerance
    trend.crossing = crossing(trend.fits["A"], tolerance)
    return trend

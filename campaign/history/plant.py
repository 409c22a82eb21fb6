"""The plant at a glance (`axiscal history plant`): one row per machine and axis, from every
campaign the store holds: the last campaign's A ± U and verdict, the drift of A per year with its
uncertainty, when A + U is predicted to reach the tolerance, and when the next re-check is due;
sorted by urgency (axes already beyond their tolerance first, then by the due date).

**When a re-check is due.** The earliest date of the crossing's 95 % interval (where the fit's
upper band plus the last campaign's U reaches the tolerance: campaign/history/trend.py), less a
margin (`margin_days`: time to plan the re-check), and never later than the last campaign plus the
longest interval the plant allows between re-checks (`max_interval_days`). An axis whose crossing
is not predictable (no significant upward drift, too few campaigns, no tolerance) is due at that
longest interval, and says why; an axis whose last campaign is already beyond its tolerance is
due at once (its due date is that campaign's); an axis with no campaign that counts for a trend
(only follow-ups, say) is due at once.

Dates are UTC days; A and U in the deviation unit (µm, arcsec).
"""

from __future__ import annotations

import datetime as dt
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

from campaign.history.axis import AxisTrend, axis_trend

MAX_INTERVAL_DAYS = 365
"""The longest interval between two re-checks of an axis, days (a plant's rule; --max-interval)."""
MARGIN_DAYS = 30
"""How long before the predicted crossing a re-check is due, days (--margin)."""
STATES = ("out", "overdue", "due soon", "ok", "no trend")
"""An axis's state, most urgent first: beyond its tolerance; past its due date; due within the
margin; fine; no campaign that counts."""


@dataclass
class AxisGlance:
    """One axis of the plant. `due`: the day its next re-check is due; `why`: how that day was
    found; `state`: one of STATES."""

    trend: AxisTrend
    due: dt.date
    why: str
    state: str

    @property
    def last(self) -> dict[str, Any] | None:
        return self.trend.counted[-1] if self.trend.counted else None

    def a_and_u(self) -> tuple[float | None, float | None]:
        if self.last is None:
            return None, None
        value, u = self.last["results"].get(("A", "both"), (None, None))
        return value, u

    def as_json(self) -> dict[str, Any]:
        a, u = self.a_and_u()
        fit = self.trend.fits.get("A")
        crossing = self.trend.crossing
        last = self.last
        return {"machine": self.trend.machine, "axis": self.trend.axis, "unit": self.trend.unit, "state": self.state,
                "due": self.due.isoformat(), "due_because": self.why,
                "campaigns": len(self.trend.counted), "left_out": len(self.trend.left_out),
                "last": None if last is None else {
                    "id": last["id"], "label": last["label"], "date": last["measured_utc"].date().isoformat(),
                    "A": a, "U_A": u, "verdict": last["verdict"], "purpose": last.get("purpose", "acceptance")},
                "tolerance": self.trend.tolerance,
                "drift_A": None if fit is None else fit.as_json(self.trend.unit),
                "crossing": None if crossing is None else crossing.as_json(self.trend.unit),
                "series": [{"date": r["measured_utc"].date().isoformat(),
                            "A": r["results"].get(("A", "both"), (None, None))[0],
                            "U": r["results"].get(("A", "both"), (None, None))[1]} for r in self.trend.counted]}


def glance(trend: AxisTrend, today: dt.date, max_interval_days: int = MAX_INTERVAL_DAYS,
           margin_days: int = MARGIN_DAYS) -> AxisGlance:
    """One axis's row (see the module's docstring)."""
    if not trend.counted:
        return AxisGlance(trend, today, "no campaign that counts for a trend: measure the axis", "no trend")
    last_day = trend.counted[-1]["measured_utc"].date()
    cap = last_day + dt.timedelta(days=max_interval_days)
    crossing = trend.crossing
    if crossing is not None and crossing.state == "already":
        return AxisGlance(trend, last_day, f"A + U is beyond the tolerance since {last_day.isoformat()}", "out")
    if crossing is not None and crossing.state == "predicted" and crossing.earliest is not None:
        early = crossing.earliest.date() - dt.timedelta(days=margin_days)
        if early < cap:
            due, why = early, (f"{margin_days} days before the earliest predicted crossing "
                               f"({crossing.earliest.date().isoformat()}, 95 %)")
        else:
            due, why = cap, f"{max_interval_days} days after the last campaign (the crossing is later)"
    else:
        reason = crossing.reason if crossing is not None else "no crossing"
        due, why = cap, f"{max_interval_days} days after the last campaign ({reason})"
    if due < today:
        state = "overdue"
    elif due <= today + dt.timedelta(days=margin_days):
        state = "due soon"
    else:
        state = "ok"
    return AxisGlance(trend, due, why, state)


def plant(rows: list[dict[str, Any]], today: dt.date, max_interval_days: int = MAX_INTERVAL_DAYS,
          margin_days: int = MARGIN_DAYS) -> list[AxisGlance]:
    """Every axis of the store's rows (Store.campaigns(summary=True) is enough), most urgent first."""
    by_axis: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        by_axis[(row["machine"], row["axis"])].append(row)
    glances = [glance(axis_trend(axis_rows, machine, axis, parameters=("A", "B")), today, max_interval_days, margin_days)
               for (machine, axis), axis_rows in by_axis.items()]
    glances.sort(key=lambda g: (g.state != "out", g.due, g.trend.machine, g.trend.axis))
    return glances

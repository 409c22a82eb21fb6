"""The one verdict on a campaign, used by `guide`, `analyze`, `report` and `verify`: pass, fail or
not judged, with the reasons.

Decision rule (ISO 14253-1, the default of ISO 230-2 acceptance): a parameter passes when its value
plus the expanded measurement uncertainty U is within the tolerance T (A + U ≤ T), fails when its
value minus U is beyond it (A − U > T); in between the measurement cannot decide. Every configured
tolerance is judged this way: on A always, on E, B and R when the config sets them. The axis fails
when one parameter fails (a proven nonconformity), passes when every one passes, and is not judged
otherwise. A table measured in one direction only is judged on its unidirectional values, named
as such (A↑, not A).

Not judged, with the reason, when:
- the campaign is not an acceptance test ([campaign] purpose: a follow-up or a diagnostic);
- the campaign is incomplete: points missing against its plan, fewer runs than planned, or (for a
  table without a plan) targets and directions not measured the same number of times;
- a direction lacks data where the campaign measured both;
- no tolerance is given;
- the uncertainty budget misses a term it needs;
- the rule cannot decide.

Outliers are listed with the verdict, never removed: the verdict is on every reading.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from campaign.iso230 import Evaluation
from campaign.outliers import Outliers
from campaign.pointtable import PointTable
from campaign.specs import JUDGED_PURPOSES
from campaign.uncertainty import Budget
from protocols.units import counted, unit_label

PASS, FAIL, NOT_JUDGED = "pass", "fail", "not judged"

RULE = "ISO 14253-1: pass when value + U ≤ tolerance, fail when value − U > tolerance, otherwise not judged"

NAMES = {"A": "accuracy A", "E": "systematic deviation E", "B": "reversal value B", "R": "repeatability R"}


@dataclass(frozen=True)
class Planned:
    """What the campaign set out to measure: points and runs (from its recorded plan)."""

    points: int
    runs: int


@dataclass(frozen=True)
class Verdict:
    """verdict: pass, fail or not judged; reasons: one sentence each, with units; checks: per
    judged parameter (value, U, tolerance, result)."""

    verdict: str
    reasons: tuple[str, ...]
    checks: tuple[dict, ...] = ()
    rule: str = RULE
    notes: tuple[str, ...] = field(default=())

    @property
    def word(self) -> str:
        """PASS, FAIL or NOT JUDGED: how people read it."""
        return self.verdict.upper()

    def as_json(self) -> dict:
        return {"verdict": self.verdict, "reasons": list(self.reasons), "rule": self.rule,
                "checks": list(self.checks), "notes": list(self.notes)}


def completeness(table: PointTable, plan: Planned | None) -> list[str]:
    """Why the table is not the whole campaign (empty when it is)."""
    problems = []
    runs = sorted({int(r) for r in table.run})
    if plan is not None:
        if len(table) < plan.points:
            problems.append(f"{plan.points - len(table)} of {plan.points} planned points are missing")
        if len(runs) < plan.runs:
            problems.append(f"{len(runs)} of {plan.runs} planned runs measured")
        return problems
    counts: dict[tuple[float, int], int] = {}
    for t, d in zip(table.target.tolist(), table.direction.tolist()):
        counts[(t, d)] = counts.get((t, d), 0) + 1
    directions = {d for _, d in counts}
    targets = {t for t, _ in counts}
    expected = len(targets) * len(directions) * len(runs)
    if len(table) < expected:
        problems.append(f"{expected - len(table)} of {expected} points missing ({len(targets)} targets × "
                        f"{len(directions)} direction(s) × {counted(len(runs), 'run')})")
    return problems


def purpose_reason(purpose: str, follows: str = "") -> str | None:
    """Why a campaign of this `purpose` ([campaign] purpose) gets no pass/fail; None when it is judged."""
    if purpose in JUDGED_PURPOSES:
        return None
    of = f" of {follows}" if follows else ""
    return f"not an acceptance test: a {purpose}{of} ([campaign] purpose = \"{purpose}\")"


def judge(table: PointTable, ev: Evaluation, tolerances: dict[str, float], uncertainty: Budget,
          outliers: Outliers | None = None, plan: Planned | None = None, purpose: str = "acceptance",
          follows: str = "") -> Verdict:
    """The verdict on `ev` (the evaluation of `table`). tolerances: parameter (A, E, B, R) -> T in
    the deviation unit; 0 or absent: not set. plan: what the campaign planned, when known. purpose,
    follows: the campaign's [campaign] purpose and follows; a follow-up or a diagnostic is not judged."""
    unit = unit_label(ev.unit)
    reasons: list[str] = []
    notes: list[str] = []
    if (not_acceptance := purpose_reason(purpose, follows)) is not None:
        reasons.append(not_acceptance)
    if outliers is not None and outliers.found:
        notes.append(f"{len(outliers.found)} outlier(s) at {100 * outliers.alpha:g} % significance, "
                     "included in the result (see outliers)")
    incomplete = completeness(table, plan)
    reasons += [f"incomplete campaign: {p}" for p in incomplete]
    both = {int(d) for d in table.direction} == {1, -1}
    if both and ev.summary.get("A") is None and ev.runs >= 2:
        reasons.append("a direction lacks data at some targets: the bidirectional A cannot be computed")
    set_tolerances = {k: v for k, v in tolerances.items() if v}
    if "A" not in set_tolerances:
        reasons.append("no tolerance on A is given (campaign.tolerance or --tolerance)")
    reasons += [f"uncertainty budget incomplete: {m}" for m in uncertainty.missing]
    checks = []
    for key, tol in set_tolerances.items():
        value, name = _value(ev, key, both)
        u = uncertainty.expanded.get(key)
        if value is None:
            reasons.append(f"{name} is unavailable")
            continue
        result = NOT_JUDGED if u is None else PASS if value + u <= tol else FAIL if value - u > tol else NOT_JUDGED
        checks.append({"parameter": key, "name": name, "value": round(value, 4),
                       "U": None if u is None else round(u, 4), "tolerance": tol,
                       "unit": ev.unit, "result": result})
    if reasons:  # the campaign itself does not allow a verdict: no parameter is judged on it either
        reasons += _undecided(checks, unit)
        checks = [{**c, "result": NOT_JUDGED} for c in checks]
        return Verdict(NOT_JUDGED, tuple(reasons), tuple(checks), notes=tuple(notes))
    failed = [c for c in checks if c["result"] == FAIL]
    if failed:  # one parameter proven out of tolerance fails the axis, whatever the others
        why = tuple(f"{c['name']} = {c['value']:.2f} {unit}: minus U = {c['U']:.2f} {unit} it is still "
                    f"above the tolerance {c['tolerance']:g} {unit}" for c in failed)
        return Verdict(FAIL, why, tuple(checks), notes=tuple(notes + _undecided(checks, unit)))
    if undecided := _undecided(checks, unit):
        return Verdict(NOT_JUDGED, tuple(undecided), tuple(checks), notes=tuple(notes))
    why = tuple(f"{c['name']} = {c['value']:.2f} {unit}: plus U = {c['U']:.2f} {unit} it is within the "
                f"tolerance {c['tolerance']:g} {unit}" for c in checks)
    return Verdict(PASS, why, tuple(checks), notes=tuple(notes))


def _undecided(checks: list[dict], unit: str) -> list[str]:
    """One sentence per parameter the decision rule cannot decide."""
    return [f"{c['name']} = {c['value']:.2f} {unit} has no stated uncertainty (one run: no scatter)"
            if c["U"] is None else
            f"{c['name']} = {c['value']:.2f} {unit} is within its uncertainty U = {c['U']:.2f} {unit} of the "
            f"tolerance {c['tolerance']:g} {unit}: the measurement cannot decide"
            for c in checks if c["result"] == NOT_JUDGED]


def _value(ev: Evaluation, key: str, both: bool) -> tuple[float | None, str]:
    """The parameter and its name; for a table measured in one direction only, the unidirectional
    one, named as such (A↑ is not the bidirectional A)."""
    if both or key == "B":
        return ev.summary.get(key), NAMES[key]
    for suffix, arrow, sign in (("up", "↑", "+"), ("down", "↓", "−")):
        if ev.summary.get(f"{key}_{suffix}") is not None:
            return (ev.summary[f"{key}_{suffix}"],
                    f"unidirectional {NAMES[key]}{arrow} (only the {sign} direction was measured)")
    return None, NAMES[key]

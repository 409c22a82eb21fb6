"""Evaluation of positioning accuracy and repeatability: ISO 230-2 and VDI/DGQ 3441.

Notation of ISO 230-2:2014 (reference.md §2): x_ij = measured - target at target i, run j; `_up`
is the + direction (↑), `_down` the - direction (↓). All results are in the deviation unit of the
point table (µm for a linear axis, arcsec for a rotary axis). A value that cannot be computed
from the data (one direction only, one run only) is None, never a made-up number.

The coverage factor k is 2 for ISO 230-2:2014 (±2s, R = 4s) and 3 for ISO 230-2:1988 (±3s, R = 6s).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from campaign.errors import InputError
from campaign.pointtable import PointTable


@dataclass(frozen=True)
class Standard:
    """An evaluation standard. k: coverage factor on s (2 or 3). vdi: also compute VDI/DGQ 3441."""

    key: str
    title: str
    k: float
    vdi: bool = False


STANDARDS = {
    "iso230-2:2014": Standard("iso230-2:2014", "ISO 230-2:2014", 2.0),
    "iso230-2:1988": Standard("iso230-2:1988", "ISO 230-2:1988 (±3s)", 3.0),
    "vdi3441": Standard("vdi3441", "VDI/DGQ 3441", 2.0, vdi=True),
}

_ALIASES = {
    "iso": "iso230-2:2014", "iso2302": "iso230-2:2014", "iso23022014": "iso230-2:2014",
    "iso23022006": "iso230-2:2014", "gbt174212": "iso230-2:2014", "gbt17421": "iso230-2:2014",
    "jisb61902": "iso230-2:2014", "iso23021988": "iso230-2:1988", "iso1988": "iso230-2:1988",
    "vdi3441": "vdi3441", "vdidgq3441": "vdi3441", "vdi": "vdi3441",
}


def find_standard(name: str) -> Standard:
    """Look up a standard by name, accepting aliases such as 'GB/T 17421.2' and 'JIS B 6190-2'."""
    folded = re.sub(r"[^a-z0-9]", "", name.lower())
    key = _ALIASES.get(folded)
    if key is None:
        known = "ISO230-2:2014 (aliases GB/T17421.2, JIS B 6190-2), ISO230-2:1988, VDI3441"
        raise InputError(f"--standard: unknown standard '{name}' (known: {known})")
    return STANDARDS[key]


@dataclass
class TargetResult:
    """Per-target statistics, deviation unit. None where the data do not allow a value."""

    target: float
    n_up: int
    n_down: int
    mean_up: float | None
    mean_down: float | None
    s_up: float | None
    s_down: float | None
    R_up: float | None
    R_down: float | None
    B: float | None
    R: float | None
    mean: float | None

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class Evaluation:
    """The result of one evaluation: `summary` maps parameter name -> value (or None)."""

    standard: Standard
    unit: str
    position_unit: str
    runs: int
    targets: list[TargetResult]
    summary: dict[str, float | None]
    warnings: list[str] = field(default_factory=list)

    def as_json(self) -> dict:
        out: dict = dict(self.summary)
        out.update(standard=self.standard.title, unit=self.unit, position_unit=self.position_unit,
                   runs=self.runs, targets=[t.as_dict() for t in self.targets], warnings=self.warnings)
        return out


def _stats(values: np.ndarray) -> tuple[int, float | None, float | None]:
    """(n, mean, s with n-1) of one target and direction; None where undefined."""
    n = len(values)
    if n == 0:
        return 0, None, None
    mean = float(np.mean(values))
    s = float(np.std(values, ddof=1)) if n >= 2 else None
    return n, mean, s


def _known(values: list[float | None]) -> list[float] | None:
    """The values when every one is known, else None."""
    known = [v for v in values if v is not None]
    return known if len(known) == len(values) else None


def _span(high: list[float | None], low: list[float | None]) -> float | None:
    hi, lo = _known(high), _known(low)
    if not hi or lo is None:
        return None
    return float(max(hi) - min(lo))


def _max(values: list[float | None]) -> float | None:
    known = _known(values)
    return float(max(known)) if known else None


def _per_target(table: PointTable, k: float) -> list[TargetResult]:
    results = []
    for t in np.unique(table.target):
        at = table.target == t
        n_up, m_up, s_up = _stats(table.deviation[at & (table.direction > 0)])
        n_dn, m_dn, s_dn = _stats(table.deviation[at & (table.direction < 0)])
        r_up = 2 * k * s_up if s_up is not None else None
        r_dn = 2 * k * s_dn if s_dn is not None else None
        b = r = mean = None
        if m_up is not None and m_dn is not None:
            b = m_up - m_dn
            mean = (m_up + m_dn) / 2
            if s_up is not None and s_dn is not None:
                r = max(k * s_up + k * s_dn + abs(b), 2 * k * s_up, 2 * k * s_dn)  # R↑, R↓
        results.append(TargetResult(float(t), n_up, n_dn, m_up, m_dn, s_up, s_dn, r_up, r_dn, b, r, mean))
    return results


def _direction_summary(rows: list[TargetResult], suffix: str, k: float) -> dict[str, float | None]:
    means = _known([getattr(r, f"mean_{suffix}") for r in rows])
    sds: list[float | None] = [getattr(r, f"s_{suffix}") for r in rows]
    if means is None:
        return {f"A_{suffix}": None, f"E_{suffix}": None, f"R_{suffix}": None}
    high = [m + k * s if s is not None else None for m, s in zip(means, sds)]
    low = [m - k * s if s is not None else None for m, s in zip(means, sds)]
    return {
        f"A_{suffix}": _span(high, low),
        f"E_{suffix}": float(max(means) - min(means)),
        f"R_{suffix}": _max([getattr(r, f"R_{suffix}") for r in rows]),
    }


def _bidirectional_summary(rows: list[TargetResult], k: float) -> dict[str, float | None]:
    none: dict[str, float | None] = dict.fromkeys(("A", "E", "M", "B", "B_mean", "R"))
    means = _known([r.mean_up for r in rows] + [r.mean_down for r in rows])
    reversals = _known([r.B for r in rows])
    bi_means = _known([r.mean for r in rows])
    if means is None or reversals is None or bi_means is None:
        return none
    sds = [r.s_up for r in rows] + [r.s_down for r in rows]
    high = [m + k * s if s is not None else None for m, s in zip(means, sds)]
    low = [m - k * s if s is not None else None for m, s in zip(means, sds)]
    return {
        "A": _span(high, low),
        "E": float(max(means) - min(means)),
        "M": float(max(bi_means) - min(bi_means)),
        "B": float(max(abs(b) for b in reversals)),
        "B_mean": float(np.mean(reversals)),
        "R": _max([r.R for r in rows]),
    }


def _vdi_summary(rows: list[TargetResult]) -> dict[str, float | None]:
    """VDI/DGQ 3441 (reference.md §2, unverified against the standard's text): per target the mean
    over both directions, the reversal U = |B| and the scatter Ps = 6 s, with s the mean of the two
    directions' s. With one direction only, U = 0 and that direction's mean and s are used."""
    centre: list[float] = []
    spread: list[float] = []
    scatter: list[float | None] = []
    for r in rows:
        pairs = [(m, s) for m, s in ((r.mean_up, r.s_up), (r.mean_down, r.s_down)) if m is not None]
        centre.append(float(np.mean([m for m, _ in pairs])))
        spread.append(abs(r.B) if r.B is not None else 0.0)
        sds = _known([s for _, s in pairs])
        scatter.append(6 * float(np.mean(sds)) if sds is not None else None)
    out: dict[str, float | None] = {"Pa": float(max(centre) - min(centre)), "U_max": float(max(spread))}
    out["Ps_max"] = _max(scatter)
    known = _known(scatter)
    if not known:
        out["P"] = None
    else:
        out["P"] = float(max(c + u / 2 + p / 2 for c, u, p in zip(centre, spread, known))
                         - min(c - u / 2 - p / 2 for c, u, p in zip(centre, spread, known)))
    return out


def evaluate(table: PointTable, standard: Standard = STANDARDS["iso230-2:2014"]) -> Evaluation:
    """Evaluate a point table to `standard`. Never raises for a table that `read_points` accepted."""
    k = standard.k
    rows = _per_target(table, k)
    summary: dict[str, float | None] = {}
    summary.update(_bidirectional_summary(rows, k))
    for suffix in ("up", "down"):
        summary.update(_direction_summary(rows, suffix, k))
    if standard.vdi:
        summary.update(_vdi_summary(rows))
    runs = len(np.unique(table.run))
    warnings = []
    if runs < 5:
        warnings.append(f"{runs} run(s); ISO 230-2 asks for 5")
    if runs == 1:
        warnings.append("one run only: repeatability (R) and accuracy (A) are unavailable")
    if len(rows) < 5:
        warnings.append(f"{len(rows)} target(s); ISO 230-2 asks for at least 5")
    if len(table.directions) == 1:
        which = "+" if table.directions[0] > 0 else "-"
        warnings.append(f"measured in the {which} direction only: bidirectional parameters are unavailable")
    return Evaluation(standard, table.deviation_unit, table.position_unit, runs, rows, summary, warnings)

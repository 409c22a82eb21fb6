"""Outliers in a point table: one reading far from the others at its target (a beam glitch, a
bump), found by a test that uses the whole campaign's scatter.

Every target and direction is a group. Within a group the deviations scatter about their mean;
the scatter is assumed the same in every group (ISO 230-2's s_i differ only by chance), so it is
pooled over the campaign. Each point is tested by its studentised deleted residual:

    e_k   = x_k - x̄_g                       (its residual about its group's mean, n_g points)
    s²_(k) = (SSE - e_k² · n_g/(n_g - 1)) / (N - G - 1)
    t_k   = e_k / (s_(k) · √((n_g - 1)/n_g))

with SSE the sum of all squared residuals, N points and G groups: the residual measured against
the scatter of every other point, so that the glitch itself does not inflate the yardstick.
Without outliers, t_k follows Student's t with N - G - 1 degrees of freedom. A point is an
outlier when |t_k| exceeds the two-sided critical value at significance ALPHA for the whole
campaign (Bonferroni: ALPHA / N per point). Groups of one point cannot be tested. The deleted
scatter is never taken below the rounding of the readings' own step (`_resolution_variance`).

Outliers are reported, never removed: ISO 230-2 counts every reading. `Outliers.s_with` and
`s_without` give the pooled scatter with and without them, so a reader sees what one reading
does to R and A. Deviations in µm (arcsec for a rotary axis).

One pass finds the worst point of a group reliably; two glitches in one group of five can mask
each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from campaign.pointtable import PointTable

ALPHA = 0.01
"""Significance of the test for the whole campaign (the chance that a campaign without outliers
shows one)."""


@dataclass(frozen=True)
class Outlier:
    """One flagged reading: run, direction (+1/-1), target (axis unit), deviation (µm or arcsec),
    score |t| and the critical value it exceeds."""

    run: int
    direction: int
    target: float
    deviation: float
    score: float
    critical: float

    def as_dict(self) -> dict:
        return {"run": self.run, "direction": "+" if self.direction > 0 else "-", "target": self.target,
                "deviation": self.deviation, "score": round(self.score, 2), "critical": round(self.critical, 2)}


@dataclass(frozen=True)
class Outliers:
    """The test's result. s_with / s_without: pooled scatter within the groups (√(SSE/(N - G)))
    with every point and without the outliers, deviation unit; None when it cannot be computed."""

    found: tuple[Outlier, ...]
    alpha: float
    critical: float | None
    s_with: float | None
    s_without: float | None
    tested: int

    def mask(self, table: PointTable) -> np.ndarray:
        """True for the rows of `table` that are outliers."""
        keys = {(o.run, o.direction, o.target) for o in self.found}
        return np.array([(int(r), int(d), float(t)) in keys
                         for r, d, t in zip(table.run, table.direction, table.target)], dtype=bool)


def _groups(table: PointTable) -> np.ndarray:
    """A group number per row: one per (target, direction)."""
    keys = list(zip(table.target.tolist(), table.direction.tolist()))
    index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    return np.array([index[k] for k in keys], dtype=int)


def _pooled_s(deviation: np.ndarray, group: np.ndarray) -> float | None:
    n_groups = len(np.unique(group))
    if len(deviation) - n_groups < 1:
        return None
    means = np.bincount(group, deviation) / np.bincount(group)
    sse = float(np.sum((deviation - means[group]) ** 2))
    return math.sqrt(sse / (len(deviation) - n_groups))


def _resolution_variance(deviation: np.ndarray, group: np.ndarray) -> float:
    """The variance of rounding to the step the readings come in (q²/12): q is the smallest nonzero
    difference between two readings of one group. A reading is not judged against a scatter below
    it: readings that repeat exactly (an instrument of coarse resolution, 0.1/0.1 µm) show none, and
    a group differing by one step (0.2/0.3 µm) was flagged at a score of 7e163. Continuous readings
    make q tiny, and the floor changes nothing; 1e-300 when no two differ."""
    order = np.lexsort((deviation, group))  # by group, then by reading: neighbours within a group
    same = group[order][1:] == group[order][:-1]
    steps = np.diff(deviation[order])[same]
    positive = steps[steps > 0]
    return float(np.min(positive)) ** 2 / 12 if len(positive) else 1e-300


def find_outliers(table: PointTable, alpha: float = ALPHA) -> Outliers:
    """Test every reading of `table` (see the module docstring)."""
    from scipy.special import stdtrit  # Student's t quantile; scipy.stats costs a second more to import

    x = np.asarray(table.deviation, dtype=float)
    group = _groups(table)
    counts = np.bincount(group)
    n_g = counts[group]
    testable = n_g >= 2
    dof = len(x) - len(counts) - 1
    s_with = _pooled_s(x, group)
    if dof < 1 or not testable.any():
        return Outliers((), alpha, None, s_with, s_with, 0)
    means = np.bincount(group, x) / counts
    e = x - means[group]
    sse = float(np.sum(e**2))
    scale = np.where(testable, n_g / np.maximum(n_g - 1, 1), 0.0)
    deleted = np.maximum((sse - e**2 * scale) / dof, _resolution_variance(x, group))
    t = np.where(testable, np.abs(e) / np.sqrt(deleted / np.where(testable, scale, 1.0)), 0.0)
    tested = int(testable.sum())
    critical = float(stdtrit(dof, 1 - alpha / (2 * tested)))
    found = tuple(Outlier(int(table.run[i]), int(table.direction[i]), float(table.target[i]), float(x[i]),
                          float(t[i]), critical)
                  for i in np.argsort(-t) if t[i] > critical)
    keep = np.ones(len(x), dtype=bool)
    for o in found:
        keep &= ~((table.run == o.run) & (table.direction == o.direction) & (table.target == o.target))
    s_without = _pooled_s(x[keep], _groups_subset(group, keep)) if found else s_with
    return Outliers(found, alpha, critical, s_with, s_without, tested)


def _groups_subset(group: np.ndarray, keep: np.ndarray) -> np.ndarray:
    _, renumbered = np.unique(group[keep], return_inverse=True)
    return renumbered

"""Smoothing the mean deviations before they become a compensation table.

Each mean deviation x̄_i carries the measurement's own scatter, s/√n_i. A table built from the raw
means writes that scatter into the controller, and the verification campaign then measures it a
second time on top of its own. Where the means lie on a smooth curve within their scatter, a
curve fitted through them is closer to the axis's true error than the means themselves.

The rule (`smooth_means`): fit polynomials (Legendre basis over the targets' range, weighted by
1/var(x̄_i)) of degree 1, 2, … up to m-3 for m targets, and keep the lowest degree whose
residuals are consistent with the scatter: F = χ²/ν against the pooled variance s² (F
distribution with ν = m-d-1 and the pooled s's degrees of freedom), accepted when its p value is
at least `level` (5 %). If no degree passes, the means are kept unchanged: a sharp feature, such
as seed 000's vertical axis between 0 and 30 mm, is larger than the scatter and is then followed
target by target. Degree 1 is the lowest: a scale error (a line) is always expected on a screw.

The fitted curve is used at the targets only; the controller interpolates linearly between them,
as it does between raw means. All values in the deviation unit (µm or arcsec); positions in the
axis unit (mm or degree).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

SMOOTHING = ("auto", "none")
LEVEL = 0.05
"""Significance level of the test that keeps a polynomial: 5 %."""


@dataclass(frozen=True)
class Smoothing:
    """The values that go into the table and how they were chosen.

    values: per target, deviation unit. degree: the polynomial kept, None when the raw means
    are kept. p_value: of the kept degree's test (None without a fit). max_change: largest
    |values - raw mean|, deviation unit. reason: one line for the operator.
    """

    values: np.ndarray
    degree: int | None
    p_value: float | None
    max_change: float
    reason: str


def pooled_variance(sds: list[float], counts: list[int]) -> tuple[float, int] | None:
    """The pooled variance s² (deviation unit²) of the per-target standard deviations `sds`,
    each from `counts` readings, and its degrees of freedom. None when there is no scatter."""
    dof = sum(n - 1 for n in counts)
    if dof <= 0:
        return None
    return sum((n - 1) * s * s for s, n in zip(sds, counts, strict=True)) / dof, dof


def smooth_means(targets: np.ndarray, means: np.ndarray, var_weights: np.ndarray,
                 pooled: tuple[float, int] | None, mode: str = "auto", level: float = LEVEL) -> Smoothing:
    """The smoothed means (see the module text).

    targets: axis unit, increasing. means: x̄_i, deviation unit. var_weights: var(x̄_i) / s² per
    target (1/n_i for one direction's mean, (1/n↑ + 1/n↓)/4 for the mean of both). pooled: (s²,
    degrees of freedom) from `pooled_variance`, None without scatter. mode: `auto` or `none`.
    """
    means = np.asarray(means, dtype=float)
    m = len(means)
    if mode == "none":
        return Smoothing(means, None, None, 0.0, "not smoothed (--smooth none): the raw means")
    if pooled is None or pooled[0] <= 0:
        return Smoothing(means, None, None, 0.0, "not smoothed: one run, no scatter to judge a fit by")
    if m < 4:
        return Smoothing(means, None, None, 0.0, f"not smoothed: {m} targets leave no room to test a fit")
    s2, dof_s = pooled
    span = targets[-1] - targets[0]
    u = 2 * (targets - targets[0]) / span - 1
    weights = 1 / np.sqrt(var_weights)
    for degree in range(1, m - 2):
        basis = np.polynomial.legendre.legvander(u, degree)
        coef, *_ = np.linalg.lstsq(basis * weights[:, None], means * weights, rcond=None)
        fitted = basis @ coef
        nu = m - degree - 1
        f_value = float(np.sum(((means - fitted) * weights) ** 2) / s2 / nu)
        p = float(stats.f.sf(f_value, nu, dof_s))
        if p >= level:
            change = float(np.max(np.abs(fitted - means)))
            return Smoothing(fitted, degree, p, change,
                             f"polynomial of degree {degree} (p = {p:.2f} against the scatter), "
                             f"moves the means by at most {change:.3f}")
    return Smoothing(means, None, None, 0.0, f"not smoothed: no polynomial up to degree {m - 3} fits "
                                             f"within the scatter, the raw means are kept")

"""Smoothing the mean deviations before they become a compensation table.

Each mean deviation x̄_i carries the measurement's own scatter, s/√n_i. A table built from the raw
means writes that scatter into the controller, and the verification campaign then measures it a
second time on top of its own. Where the means lie on a smooth curve within their scatter, a
curve fitted through them is closer to the axis's true error than the means themselves.

The scatter (`scatter_within_runs`): per direction, the variance of the readings about a two-way
additive model, target mean + run offset. A run-wide offset (drift between runs) moves every
mean alike, and a fitted curve follows it; it is not part of the target-to-target scatter of the
means, so it is left out of s². (ISO 230-2's s_i includes it; that s is still the one used for
the floor and the evaluation.)

The rule (`smooth_means`): fit polynomials (Legendre basis over the targets' range, weighted by
1/var(x̄_i)) of degree 1, 2, … up to m-3 for m targets. Take the lowest degree whose residuals
pass the overall test, F = χ²/ν against s² (F distribution with ν = m-d-1 and the degrees of
freedom of s²), p ≥ `LEVEL` (5 %). Keep it if it also passes the local test: no target's
studentised residual r_i / √(var(x̄_i)·(1-h_ii)) exceeds the two-sided t quantile at 5 %/m
(Bonferroni), since the overall test averages a feature at one target over all of them. If the
local test fails, or no degree passes, the raw means are kept and a sharp feature (Li et al. 2022's
vertical axis between 0 and 30 mm) is followed target by target. Degree 1 is the lowest: a
scale error (a line) is always expected on a screw.

What it costs: a feature close to the tests' resolution is sometimes smoothed away. The worst
case is a bump at one target of 1.5-2 s with 5 runs (3.4-4.5 s/√n) on 11 targets: it is
detected in 41-66 % of campaigns, and on average the table then misses the axis by 0.48-0.49 s
RMS instead of the raw means' 0.45 s (bench/smoothing.py). Smaller bumps gain from the smoothing, larger ones are
detected. Where such features are expected, use `--smooth none` or more targets (`axiscal
refine`).

The fitted curve is used at the targets only; the controller interpolates linearly between them,
as it does between raw means. All values in the deviation unit (µm or arcsec); positions in the
axis unit (mm or degree).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SMOOTHING = ("auto", "none")
LEVEL = 0.05
"""Significance level of both tests that keep a polynomial: 5 %."""


@dataclass(frozen=True)
class Smoothing:
    """The values that go into the table and how they were chosen.

    values: per target, deviation unit. degree: the polynomial kept, None when the raw means
    are kept. max_change: largest |values - raw mean|, deviation unit. reason: one line for the
    operator (no numbers with a unit; the caller prints max_change with its unit).
    """

    values: np.ndarray
    degree: int | None
    max_change: float
    reason: str


def _raw(means: np.ndarray, reason: str) -> Smoothing:
    return Smoothing(means, None, 0.0, f"not smoothed: {reason}")


def scatter_within_runs(run: np.ndarray, target: np.ndarray, deviation: np.ndarray) -> tuple[float, int] | None:
    """Variance s² (deviation unit²) of one direction's readings about target mean + run offset,
    and its degrees of freedom N - m - R + 1 (N readings, m targets, R runs). None when that
    leaves no degree of freedom or no scatter. Fitted by alternating group means, which
    handles missing points without a dense design matrix."""
    _, t = np.unique(target, return_inverse=True)
    _, r = np.unique(run, return_inverse=True)
    m, runs = t.max() + 1, r.max() + 1
    dof = len(deviation) - m - runs + 1
    if dof <= 0:
        return None
    x = np.asarray(deviation, dtype=float)
    n_t, n_r = np.bincount(t, minlength=m), np.bincount(r, minlength=runs)
    offset = np.zeros(runs)
    for _ in range(200):
        mean = np.bincount(t, x - offset[r], minlength=m) / n_t
        new = np.bincount(r, x - mean[t], minlength=runs) / n_r
        new -= new.mean()
        done = np.max(np.abs(new - offset)) <= 1e-12 * (1 + np.max(np.abs(x)))
        offset = new
        if done:
            break
    s2 = float(np.sum((x - mean[t] - offset[r]) ** 2) / dof)
    return (s2, dof) if s2 > 0 else None


def pool(*scatters: tuple[float, int] | None) -> tuple[float, int] | None:
    """s² pooled over several (s², dof) by their degrees of freedom; None entries are skipped."""
    known = [s for s in scatters if s is not None]
    dof = sum(d for _, d in known)
    return (sum(s2 * d for s2, d in known) / dof, dof) if dof else None


def smooth_means(targets: np.ndarray, means: np.ndarray, var_weights: np.ndarray,
                 scatter: tuple[float, int] | None, mode: str = "auto") -> Smoothing:
    """The smoothed means (see the module text).

    targets: axis unit, increasing. means: x̄_i, deviation unit. var_weights: var(x̄_i) / s² per
    target (1/n_i for one direction's mean, (1/n↑ + 1/n↓)/4 for the mean of both). scatter: (s²,
    degrees of freedom), from `scatter_within_runs` or `pool`; None without scatter. mode: `auto`
    or `none`.
    """
    means = np.asarray(means, dtype=float)
    m = len(means)
    if mode == "none":
        return Smoothing(means, None, 0.0, "not smoothed (--smooth none): the raw means")
    if scatter is None:
        return _raw(means, "the readings show no scatter to judge a fit by (one run, or identical readings)")
    if m < 4:
        return _raw(means, f"{m} targets leave no room to test a fit")
    from scipy import stats

    s2, dof_s = scatter
    u = 2 * (targets - targets[0]) / (targets[-1] - targets[0]) - 1
    weights = 1 / np.sqrt(var_weights)
    y = means * weights  # in units of √(var(x̄_i)/s²), so every residual has variance s²
    for degree in range(1, m - 2):
        q, _ = np.linalg.qr(np.polynomial.legendre.legvander(u, degree) * weights[:, None])
        fitted = q @ (q.T @ y)
        residual = y - fitted
        nu = m - degree - 1
        p = float(stats.f.sf(np.sum(residual ** 2) / s2 / nu, nu, dof_s))
        if p < LEVEL:
            continue
        leverage = np.sum(q ** 2, axis=1)
        worst = float(np.max(np.abs(residual) / np.sqrt(s2 * np.clip(1 - leverage, 1e-12, None))))
        t_limit = float(stats.t.isf(LEVEL / (2 * m), dof_s))
        if worst > t_limit:
            return _raw(means, f"degree {degree} fits overall (p = {p:.2f}) but leaves a target {worst:.1f} "
                               f"standard errors off (> {t_limit:.1f}): a local feature, the raw means are kept")
        values = fitted / weights
        return Smoothing(values, degree, float(np.max(np.abs(values - means))),
                         f"polynomial of degree {degree} (p = {p:.2f}; studentised residuals "
                         f"≤ {worst:.1f}, limit {t_limit:.1f})")
    return _raw(means, f"no polynomial up to degree {m - 3} fits within the scatter, the raw means are kept")

"""How much a campaign's A, E, B and R would scatter if the same, unchanged axis were measured
again: the uncertainty that weighs a campaign in the trend (campaign/history/trend.py).

The uncertainty budget's statistics term (campaign/uncertainty.py) is built for one campaign's
statement and takes the largest s_i of all targets; between re-checks that is 1.9 to 2.4 times the
real scatter of A (issue 30). Here the campaign's own data say it instead: each target and
direction keeps its own mean x̄ (ISO 230-2), the runs scatter with the campaign's pooled standard
deviation s_p (all targets and directions together, √(Σ(n_i − 1)·s_i² / Σ(n_i − 1))), and
`DRAWS` re-checks are drawn from them (each run of each target and direction x̄ + s_p·z, z normal;
the same number of runs as measured), evaluated with ISO 230-2's formulas (A from x̄ ± k·s, E from
the means, B the largest |x̄↑ − x̄↓|, R the largest R_i). The standard deviation of each parameter
over the draws is its re-check uncertainty, standard, in the deviation unit. The draws are seeded,
so the same points always give the same numbers.

Why the pooled s and not each target's own: A takes the largest x̄ + k·s, and each s_i is itself
uncertain (about 35 % with 5 runs); drawn from their own s_i, the targets whose s_i came out large
drive A and the draws overstate its scatter (1.3 to 1.6 times on the demo axis, against the
scatter of A over 60 simulated re-checks; with s_p, 1.0 to 1.1 times). Where the campaigns really
scatter more than this (a target noisier than the others, the set-up changing between re-checks),
the trend's Birge scaling takes over.

It needs every target measured in both directions with at least two runs each; otherwise there is
none and the trend falls back to the budget's random terms.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

DRAWS = 400
"""Re-checks drawn per campaign (the relative precision of a standard deviation over 400 draws is
about 1/√800, 3.5 %)."""
SEED = 230_2
"""The draws' seed: the same points give the same uncertainty."""


def recheck_u(run: ArrayLike, direction: ArrayLike, target: ArrayLike, deviation: ArrayLike,
              k: float = 2.0) -> dict[str, float]:
    """{parameter: standard uncertainty between re-checks} for A, E, B and R of one campaign's
    point table (see the module's docstring); {} when the table cannot say it. `k`: the standard's
    coverage factor in A and R (2 for ISO 230-2:2014, 3 for 1988)."""
    d = np.asarray(deviation, dtype=float)
    if len(d) == 0:
        return {}
    direction_ = np.asarray(direction, dtype=int)
    targets, t_index = np.unique(np.round(np.asarray(target, dtype=float), 9), return_inverse=True)
    up = (direction_ > 0).astype(int)
    group = t_index * 2 + up  # (target, direction): 2i down, 2i+1 up
    n_groups = 2 * len(targets)
    counts = np.bincount(group, minlength=n_groups)
    if np.any(counts < 2):
        return {}
    mean = np.bincount(group, weights=d, minlength=n_groups) / counts
    s = np.sqrt(np.bincount(group, weights=(d - mean[group]) ** 2, minlength=n_groups) / (counts - 1))
    pooled = float(np.sqrt(np.sum((counts - 1) * s ** 2) / np.sum(counts - 1)))
    rng = np.random.default_rng(SEED)
    draws = mean[group] + pooled * rng.standard_normal((DRAWS, len(d)))
    one_hot = np.zeros((len(d), n_groups))
    one_hot[np.arange(len(d)), group] = 1.0
    m = draws @ one_hot / counts
    var = (draws ** 2 @ one_hot - counts * m ** 2) / (counts - 1)
    sd = np.sqrt(np.clip(var, 0.0, None))
    m_dn, m_up, s_dn, s_up = m[:, 0::2], m[:, 1::2], sd[:, 0::2], sd[:, 1::2]
    high = np.maximum(m_up + k * s_up, m_dn + k * s_dn).max(axis=1)
    low = np.minimum(m_up - k * s_up, m_dn - k * s_dn).min(axis=1)
    means = np.concatenate([m_up, m_dn], axis=1)
    b = m_up - m_dn
    r = np.maximum.reduce([k * s_up + k * s_dn + np.abs(b), 2 * k * s_up, 2 * k * s_dn]).max(axis=1)
    values = {"A": high - low, "E": means.max(axis=1) - means.min(axis=1), "B": np.abs(b).max(axis=1), "R": r}
    return {p: float(np.std(v, ddof=1)) for p, v in values.items()}


def k_of(standard: str) -> float:
    """The coverage factor in A and R of a standard as the store names it ("ISO 230-2:1988": 3)."""
    return 3.0 if "1988" in standard else 2.0

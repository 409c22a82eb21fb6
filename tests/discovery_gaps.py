"""Whether the gap a discovery leaves on a drawn machine (tests/discovery_draws.py) is one a local term
could hold (issue 34: "gap after within 1.3 × the noise wherever a local term can hold it"): the truth's
out-of-vocabulary deviation, the gap ratio were it fitted beside the final model (the oracle), and
whether the targets show it so that a term predicting a left-out target can hold it. Used by
tests/test_discovery_held.py and bench/discovery_gaps.py.

Units: mm, µm, s.
"""

from __future__ import annotations

import numpy as np

from campaign.discovery.data import CampaignData
from campaign.discovery.fit import design, fixed_deviation, weighted
from campaign.discovery.result import Discovery
from campaign.model import EFFECTS, effect_um
from tests.discovery_draws import Truth


def out_of_vocabulary_um(truth: Truth, x: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The truth's out-of-vocabulary deviation at each row (µm)."""
    total = np.zeros(len(x))
    for name, p in truth.model.items():
        if EFFECTS[name].simulator_only or name == "linear_drift":
            params = {**EFFECTS[name].defaults, **p}
            values = effect_um(name, params, x[:, None], d[:, None], t, np.full(t.shape, 2.0))
            total += np.nanmean(np.where(np.isnan(t), np.nan, values), axis=1)
    return total


def oracle_ratio(data: CampaignData, result: Discovery, column: np.ndarray) -> float:
    """The gap ratio of the final model with the true out-of-vocabulary shape beside it."""
    terms = result.final.terms
    a, _ = design(data, terms)
    a = np.column_stack([a, column])
    y = data.y - fixed_deviation(data, terms)
    beta = np.linalg.lstsq(weighted(data, a), weighted(data, y), rcond=None)[0]
    rms = float(np.sqrt(np.mean((y - a @ beta) ** 2)))
    return rms / max(result.noise_um, 1e-9)


def holdable(truth: Truth, data: CampaignData, column: np.ndarray) -> str:
    """Whether a local term could hold the error: a step; or every region that some target sees
    above the noise seen there by two targets or more (one target's reading is held by no term that
    predicts a left-out target); a wave over part of the travel shorter than twice the target
    spacing is aliased at the targets (its values there jump from target to target), unless its values
    there follow a slow alias (slow_alias: a local term can then hold them as it holds a bump)."""
    xs, where = np.unique(np.round(data.x, 6), return_inverse=True)
    at = np.bincount(where, column) / np.bincount(where)
    if truth.shape == "step":
        return f"step (targets above the noise: {int(np.sum(np.abs(at) > truth.noise_um))})"
    spacing = float(np.median(np.diff(xs)))
    if truth.shape == "partial_wave" and truth.model["partial_wave"]["period_mm"] < 2 * spacing:
        period = truth.model["partial_wave"]["period_mm"]
        slow = slow_alias(xs, at, truth.noise_um)
        if slow is None:
            return f"no (a wave of {period:.3g} mm at targets {spacing:.3g} mm apart: aliased)"
        return (f"yes (a wave of {period:.3g} mm at targets {spacing:.3g} mm apart, seen as a slow alias: "
                f"{slow[0]} targets above the noise, each predicted by its neighbours to {slow[1]:.2f} of its value)")
    if truth.shape == "linear_growth":
        return "yes (a drift in time)"
    counts = []
    for centre, half in truth.regions:
        near = np.abs(xs - centre) <= half + spacing
        counts.append(int(np.sum(near & (np.abs(at) > truth.noise_um))))
    seen = [c for c in counts if c > 0]
    ok = bool(seen) and all(c >= 2 for c in seen)
    return f"{'yes' if ok else 'no'} (targets above the noise per region: {counts})"


def slow_alias(xs: np.ndarray, at: np.ndarray, noise_um: float) -> tuple[int, float] | None:
    """Whether a wave sampled below twice its period at the targets `xs` (its values `at`, µm) is seen
    there as a slow alias that a local term could hold: two targets or more above the noise, and each
    of them predicted from its two neighbours (interpolated) better than by nothing (the RMS of what
    the interpolation misses below that of the values). The count and that ratio; None when not."""
    inner = at[1:-1]
    between = np.array([np.interp(xs[i], [xs[i - 1], xs[i + 1]], [at[i - 1], at[i + 1]])
                        for i in range(1, len(xs) - 1)])
    seen = np.abs(inner) > noise_um
    if int(np.sum(seen)) < 2:
        return None
    ratio = float(np.sqrt(np.mean((inner - between)[seen] ** 2) / np.mean(inner[seen] ** 2)))
    return (int(np.sum(seen)), ratio) if ratio < 1.0 else None

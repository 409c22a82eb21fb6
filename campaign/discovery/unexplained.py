"""Unexplained local errors (issue 34 items 2 and 3): a local term over each region the locator found
(campaign.discovery.locate), whose shape follows the data (a spline over the region:
campaign.discovery.effects.region_basis), in both directions or in the one that shows it; any number
of regions, bumps of any shape, steps with their rise. A vocabulary effect is then named only when it
explains the campaign better than these terms do (campaign.discovery.search.discover compares the
routes: the BIC of the final model with every region's place counted as searched, and the
leave-one-target-out cross-validation); otherwise the region stays what it is, an unexplained local
error, located, in the model so that the gap shrinks, and said as such.

Units: positions mm (deg), deviations µm (arcsec), times s (or point order).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from campaign.discovery.cv import GrowingFit, cv_rms_um
from campaign.discovery.data import CampaignData
from campaign.discovery.effects import region_basis_of
from campaign.discovery.fit import (
    Blocks,
    Fit,
    Term,
    bic,
    design,
    f_test_p,
    fixed_deviation,
    linear_fit,
    solve_normal,
    weighted,
)
from campaign.discovery.local import STEPPED_SHARE, LocalError, look_elsewhere, passes
from campaign.discovery.locate import Located, Region

REGION_SHARE = 0.5
"""A region wider than this share of the travel is the vocabulary's to explain (a bow, a scale, a
reversal), not a local error."""
MAX_PIECES = 6
"""The most spline pieces of one region's term (one per two targets in it, at least one)."""
SIDES = {"both": "", "+": "_plus", "-": "_minus"}


def candidate_regions(data: CampaignData, located: Located | None) -> list[Region]:
    """The located regions along the axis a local term may hold: not a reversal over the travel, not
    wider than REGION_SHARE of it, not one target's odd reading (a local error there, or an aliased
    period: a term over it and its neighbours would fit either)."""
    if located is None:
        return []
    travel = float(np.ptp(data.x)) or 1.0
    return [r for r in located.along if r.direction != "opposite" and r.end - r.start <= REGION_SHARE * travel
            and not r.one_target]


def region_term(data: CampaignData, region: Region, index: int) -> Term | None:
    """The local term over `region`, widened by one target spacing either side (the error begins where
    the curve is still inside its band); its level goes on after the region only where the locator
    saw a step or a slope change (otherwise it returns to zero: a bump of any shape); None when fewer
    than two targets lie in it."""
    targets = data.targets_mm
    spacing = float(np.median(np.diff(targets))) if len(targets) > 1 else 1.0
    start = max(float(targets[0]), region.start - spacing)
    end = min(float(targets[-1]), region.end + spacing)
    inside = int(np.sum((targets >= start) & (targets <= end)))
    if inside < 2 or end <= start:
        return None
    step = region.shape in ("step", "slope change")
    pieces = int(np.clip(inside // 2, 1 if step else 2, MAX_PIECES))
    name = "local_region" + SIDES.get(region.direction, "") + (f"#{index}" if index > 1 else "")
    at_end = end >= float(targets[-1])  # nothing is measured beyond the travel: no side to close there
    open_end, open_start = step or at_end, start <= float(targets[0])
    both = not SIDES.get(region.direction, "")  # local_region, in both directions: the offset's level
    return Term(name, {}, False, {"start_mm": start, "end_mm": end, "pieces": float(pieces),
                                  "open_end": float(open_end), "open_start": float(open_start),
                                  "offset_level": float(both and open_end and open_start)})


def is_region(term: Term) -> bool:
    return term.name.startswith("local_region")


def region_terms(data: CampaignData, fit: Fit, located: Located | None) -> list[Term]:
    """Local terms over the located regions beside `fit`'s model, each kept only when it passes the tests
    every local term passes (BIC and F-test with the search's look-elsewhere factor, leave-one-target-out
    CV), the largest region first."""
    kept: list[Term] = []
    current = fit
    regions = sorted(candidate_regions(data, located), key=lambda r: -abs(r.peak_um))
    growing = GrowingFit.start(data, fit, data.target_index) if regions else None
    for region in regions:
        term = region_term(data, region, len(kept) + 1)
        if term is None:
            continue
        if growing is not None:  # a dense table: each term tried beside the model without refitting it
            rss, n_params, cv_um, grown = growing.trial(term)
            before = replace(current, rss=growing.rss, n_params=growing.n_params)
            if passes(data, before, replace(current, rss=rss, n_params=n_params), (growing.cv_um, cv_um)):
                kept.append(term)
                growing.add(grown)
            continue
        trial = linear_fit(data, [*current.terms, term])
        if passes(data, current, trial):
            kept.append(term)
            current = trial
    return kept


def describe_region(data: CampaignData, fit: Fit, name: str, without: Fit) -> LocalError:
    """The LocalError of the region term `name` in `fit`: its peak (and its 1-σ error from the
    coefficients' covariance), its place, whether it changes with time (an F-test of its fitted shape
    growing linearly in time), the tests against `without`."""
    i = next(k for k, t in enumerate(fit.terms) if t.name == name)
    term, coefs = fit.terms[i], fit.coefs[i]
    params = fit.params()[name]
    shape = term.shape
    blocks = Blocks(data, fit.terms)  # the design's blocks and normal matrix: no n × p design (dense tables)
    n, p = len(data), blocks.width
    gram = blocks.gram()
    cov = np.linalg.pinv(gram) * fit.rss / max(n - p, 1)
    mine = blocks.slice_of(fit.terms, i)
    block = cov[mine, mine]
    at = np.array([params["peak_at_mm"]])
    b = region_basis_of(at, shape)[0]
    peak_error = float(math.sqrt(max(float(b @ block @ b), 0.0)))
    stepped = abs(params["level_after_um"]) >= STEPPED_SHARE * abs(params["peak_um"])
    where, between = params["peak_at_mm"], None
    if stepped:  # between the neighbouring targets over which the fitted term changes most (not finer)
        between = steepest_between(data.targets_mm, shape, coefs)
        where = (between[0] + between[1]) / 2 if between is not None else where
    direction = {"local_region_plus": "+", "local_region_minus": "-"}.get(name.split("#")[0], "both")
    shown = {"amplitude_um": params["peak_um"], "centre_mm": where, "width_mm": shape["end_mm"] - shape["start_mm"],
             "start_mm": shape["start_mm"], "end_mm": shape["end_mm"], "level_after_um": params["level_after_um"]}
    # does it change with time? its fitted shape growing linearly in time, beside the model
    tm = np.nanmean(data.t, axis=1)
    span = float(np.ptp(tm)) or 1.0
    fitted = term.columns(data) @ coefs
    growth = fitted * (tm - tm.mean()) / span
    base = fixed_deviation(data, fit.terms)
    w = weighted(data, weighted(data, np.ones(n)))
    cross = blocks.t_times(growth)  # the normal equations of [A, growth] on weighted rows
    normal = np.block([[gram, cross[:, None]], [cross[None, :], np.array([[float(growth @ (w * growth))]])]])
    beta = solve_normal(normal, np.append(blocks.t_times(data.y - base), float(growth @ (w * (data.y - base)))))
    prediction = base + blocks.times(beta[:-1]) + growth * beta[-1]
    rss = float(np.sum(weighted(data, data.y - prediction) ** 2))
    grown = Fit(fit.terms, fit.coefs, fit.offset_um, prediction, rss, fit.n_params + 1, fit.offsets_um)
    time_p = f_test_p(fit, grown, n)
    change_cov = np.linalg.pinv(normal) * rss / max(n - p - 1, 1)
    # beta[-1] is a share of the fitted shape (growth = fitted × time share): in µm at the peak
    change_um = float(beta[-1]) * params["peak_um"]
    change_error_um = float(math.sqrt(max(change_cov[-1, -1], 0.0))) * abs(params["peak_um"])
    errors = {"amplitude_um": peak_error}
    if direction in ("+", "-"):  # what the other direction shows there: the same spline fitted for it
        other = "local_region_" + ("minus" if direction == "+" else "plus") + "#0"
        beside = linear_fit(data, [*fit.terms, Term(other, {}, False, dict(shape))])
        other_blocks = Blocks(data, beside.terms)
        ocov = np.linalg.pinv(other_blocks.gram()) * beside.rss / max(len(data) - other_blocks.width, 1)
        j = len(beside.terms) - 1
        theirs = other_blocks.slice_of(beside.terms, j)
        shown["other_um"] = float(b @ beside.coefs[j])
        errors["other_um"] = float(math.sqrt(max(float(b @ ocov[theirs, theirs] @ b), 0.0)))
    k = len(data)
    factor = look_elsewhere(data)
    return LocalError(term, shown, errors, direction, time_p, change_um,
                      explained_pct=100 * (1 - fit.rss / without.rss) if without.rss > 0 else 0.0,
                      delta_bic=bic(fit, k) - bic(without, k) + 2 * math.log(factor),
                      p_value=min(1.0, f_test_p(without, fit, k) * factor),
                      cv_before_um=cv_rms_um(data, without.terms, data.target_index),
                      cv_after_um=cv_rms_um(data, fit.terms, data.target_index),
                      gap_without_um=without.rms_um(data.y),
                      time_change_error_um=change_error_um,
                      position_unit=data.position_unit, deviation_unit=data.deviation_unit, kind="region",
                      between_mm=between)


def steepest_between(targets: np.ndarray, shape: dict[str, float], coefs: np.ndarray) -> tuple[float, float] | None:
    """The two neighbouring targets, from the last before the region to the first after it, between which
    the region term (its spline `coefs`) changes most: where its step lies, as finely as the targets
    say (the spline between them is not measured); None when fewer than two targets lie there."""
    lo = np.searchsorted(targets, shape["start_mm"], side="right") - 1
    hi = np.searchsorted(targets, shape["end_mm"], side="left") + 1
    at = targets[max(lo, 0):min(hi, len(targets))]
    if len(at) < 2:
        return None
    values = region_basis_of(at, shape) @ coefs
    k = int(np.argmax(np.abs(np.diff(values))))
    return float(at[k]), float(at[k + 1])



SECTIONS = 3
"""A screw lead's periodic error is looked at in this many sections of the travel (equal numbers of
targets)."""
SECTION_SIGMAS = 3.0
"""A wave whose amplitude differs between two sections by more than this many standard errors of the
difference, the smaller under half the larger, is in part of the travel only."""


def wave_over_part(data: CampaignData, fit: Fit, name: str = "periodic_lead") -> str | None:
    """Is the periodic term `name` of `fit` a wave over part of the travel only (not a screw lead,
    whose error repeats on every turn)? Its sine and cosine fitted per section of the travel
    (SECTIONS) beside the rest of the model: why, in words, when the amplitudes differ (SECTION_SIGMAS)
    and the smaller is under half the larger; None otherwise."""
    i = next((k for k, t in enumerate(fit.terms) if t.name == name), None)
    if i is None or fit.terms[i].fixed:
        return None
    term = fit.terms[i]
    targets = data.targets_mm
    if len(targets) < 3 * SECTIONS:
        return None
    edges = np.quantile(targets, np.linspace(0, 1, SECTIONS + 1))
    section = np.clip(np.searchsorted(edges, data.x, side="right") - 1, 0, SECTIONS - 1)
    cols = term.columns(data)
    split = np.column_stack([cols * (section == k)[:, None] for k in range(SECTIONS)])
    others = [t for t in fit.terms if t is not term]
    a, _ = design(data, others)
    base = fixed_deviation(data, others)
    full = weighted(data, np.column_stack([a, split]))
    y = weighted(data, data.y - base)
    beta = np.linalg.lstsq(full, y, rcond=None)[0]
    rss = float(np.sum((y - full @ beta) ** 2))
    n, p = full.shape
    cov = np.linalg.pinv(full.T @ full) * rss / max(n - p, 1)
    width = cols.shape[1]
    amps, errs = [], []
    for k in range(SECTIONS):
        j = a.shape[1] + width * k
        c = beta[j:j + width]
        amp = float(np.hypot(*c)) if width == 2 else float(abs(c[0]))
        g = c / amp if amp > 0 else np.ones(width) / math.sqrt(width)
        amps.append(amp)
        errs.append(float(math.sqrt(max(float(g @ cov[j:j + width, j:j + width] @ g), 0.0))))
    hi, lo = int(np.argmax(amps)), int(np.argmin(amps))
    if amps[lo] < 0.5 * amps[hi] and amps[hi] - amps[lo] > SECTION_SIGMAS * math.hypot(errs[hi], errs[lo]):
        said = ", ".join(f"{a:.2g} ± {e:.2g}" for a, e in zip(amps, errs))
        return (f"a wave over part of the travel only (amplitude by {SECTIONS} sections: {said} "
                f"{data.deviation_unit}): a screw lead repeats on every turn")
    return None

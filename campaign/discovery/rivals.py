"""What else the data leave room for beside what was said: a bump said with its other shape, a step, when
that fits as well (shape_rivals); a rival of a named effect its data do not exclude
(rivals_not_excluded); local errors that fit as well as an unresolved effect, said as its rivals
(add_local_rivals, rivals_from_routes); and the comparison they rest on (fits_as_well: a
leave-one-target-out mean square above the other's by at most RIVAL_SE standard errors of the
targets' paired differences, or a lower BIC).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from campaign.discovery.cv import cv_group_errors, cv_rms_um
from campaign.discovery.data import CampaignData
from campaign.discovery.effects import FORMS, HELD_PREFIX, PERIOD_KEY, SIZE_SIGMAS, fixed_shape
from campaign.discovery.fit import Fit, Term, bic, f_test_p, linear_fit, refine, standard_errors
from campaign.discovery.local import TARGET, LocalError, describe, is_local, other_shape, passes, term_index
from campaign.discovery.naming import ALPHA, BIC_MARGIN, gate_failures
from campaign.discovery.records import LocalRival, NotExcluded
from campaign.discovery.result import Candidate, Discovery, note_once, period_unresolved, periodic_in
from campaign.discovery.unexplained import is_region
from campaign.discovery.vocabulary import how_to_tell_pairs


def unnamed_forms(data: CampaignData, vocabulary: Discovery) -> Iterator[tuple[Candidate, Term]]:
    """Each effect the vocabulary search tried and did not name (not a period), as one form to hold beside
    the grid: its shape fixed (skipped when it has a shape to search, a time constant)."""
    for cand in [c for c in vocabulary.remaining if c.name not in PERIOD_KEY]:
        shape = fixed_shape(cand.name, data, {})
        if all(key in shape for key in FORMS[cand.name].shape):
            yield cand, Term(cand.name, {}, False, shape)


OTHER_SHAPE = {"bump": "step", "step": "bump"}


def shape_rivals(data: CampaignData, result: Discovery) -> None:
    """For each bump or step of the final model (in both directions), the best local error of the other
    shape in its place: beside the rest of the model, and beside it with each effect of fixed shape that
    is not in the model put in (unnamed_forms; a bow takes a step's level beyond it and leaves a bump).
    When one passes the tests of a local error there (the look-elsewhere factor of the grid in one
    direction: its shapes, widths and targets, not the three directions), lies where this one does (their regions overlap),
    the effect put in passes beside it (passes_beside) and it fits as well (as_good: its leave-one-target-out CV within RIVAL_SE of the final model's;
    or a lower BIC), it is this error's `shape_rival`: which shape it is, the campaign does not say (a
    2.8 µm step rising over 140 mm at 187 mm beside a 1.4 µm bow, 17 golden targets, noise 0.8 µm, was said
    as a bump at 270 mm, width 117 mm, with no bow; the step and bow have a BIC 4.7 higher and a CV 0.736
    against 0.733 µm, bench seed 11, draw 24296). Its effect beside it is said, not named. The
    follow-up measures over both (regions_to_measure)."""
    final = result.final
    in_model = {t.name.removeprefix(HELD_PREFIX) for t in final.terms}
    forms = [term for _, term in unnamed_forms(data, result) if term.name not in in_model]
    for at, local in enumerate(result.local_errors):
        if local.kind not in OTHER_SHAPE or "_by_direction" in local.term.name:
            continue
        others = [t for t in final.terms if t.name != local.term.name]
        for beside in [None, *forms]:
            without = linear_fit(data, others + ([beside] if beside is not None else []))
            rival = other_shape(data, without, OTHER_SHAPE[local.kind], term_index(local.term))
            if rival is None or not passes(data, without, rival):  # its grid searched both directions alone
                continue
            found = describe(data, rival, rival.terms[-1].name, explained_pct=0.0, delta_bic=0.0, p_value=1.0,
                             cv_before_um=0.0, cv_after_um=0.0)
            (low, high), (a, b) = found.region_mm, local.region_mm
            if high < a or b < low or beyond_the_campaign(data, result.start, rival):
                continue
            if beside is not None and not passes_beside(data, rival, beside.name):
                continue  # the effect adds nothing beside it: the rival is the one without it
            if not fits_as_well(data, rival, final):
                continue
            said = found.sentence() + (f", with {beside.name} beside it, named only with this shape"
                                       if beside is not None else "")
            rival_of = LocalRival(said, (round(low, 1), round(high, 1)), found.between_mm)
            result.local_errors[at] = replace(local, shape_rival=rival_of)
            note_once(result.notes, f"{local.sentence()}: not told from {said}, which predicts left-out targets as "
                                "well or explains the campaign better by BIC")
            break


RIVAL_NOT_EXCLUDED_SHARE = 0.5
"""A rival beside a named effect is said not excluded when twice its standard error reaches this
share of the named effect's size: the data leave room for both at sizes that matter."""


def rivals_not_excluded(data: CampaignData, result: Discovery) -> None:
    """For each named effect, each of its rivals (its `rivals`, those with no shape to search and a size
    in the same unit) that is neither named nor unresolved is fitted beside the final model, the named
    effects' shapes refitted with it (a settling's time constant grows to hold a backlash beside it):
    when its size plus 2σ reaches RIVAL_NOT_EXCLUDED_SHARE of the named effect's size, the data do not
    exclude it (the search did not name it): said (`not_excluded`, a note) with how to tell and, for
    a named effect with a time constant, the waits that would show it fade (from the time constant
    refitted beside the rival). Backlash and settling together fit as settling alone with a long time
    constant (a reviewer's 1.8 µm backlash and 2 µm settling, τ 1 s, came out as settling, τ 4.2 s,
    and nothing said backlash might be there too)."""
    unresolved = {name for u in result.unresolved for name in u.effects}
    pairs = how_to_tell_pairs()
    for named in result.added:
        size_key = next(iter(FORMS[named].sizes), None)
        if size_key is None or named not in result.params():
            continue
        size = abs(result.params()[named].get(size_key, math.nan))
        for rival in sorted(n for pair in pairs if named in pair for n in pair if n != named):
            if (rival in result.added or rival in unresolved or rival not in FORMS or FORMS[rival].shape
                    or FORMS[rival].fixed_shape is not None):
                continue
            rival_size = next(iter(FORMS[rival].sizes), None)
            if rival_size is None or rival_size.rsplit("_", 1)[-1] != size_key.rsplit("_", 1)[-1]:
                continue  # sizes in other units (a slope beside a reversal) do not compare
            # the named effect's own shape refitted beside the rival, the others' held (a period's
            # refinement on a dense profile costs seconds and is not what the rival changes)
            beside = refine(data, [t if t.name == named else replace(t, held={**t.held, **t.shape})
                                   for t in result.final.terms] + [Term(rival)])
            errors = standard_errors(data, beside)
            value = beside.params().get(rival, {}).get(rival_size, math.nan)
            error = errors.get(rival, {}).get(rival_size, math.nan)
            if not (math.isfinite(value) and math.isfinite(error) and math.isfinite(size)):
                continue
            if abs(value) + SIZE_SIGMAS * error >= RIVAL_NOT_EXCLUDED_SHARE * size:
                tau = beside.params()[named].get(TIME_CONSTANT)
                tau_error = errors.get(named, {}).get(TIME_CONSTANT, math.nan)
                waits = 3 * (tau + SIZE_SIGMAS * tau_error) if tau is not None and math.isfinite(tau_error) else None
                how = pairs[frozenset({named, rival})] + ("" if waits is None or tau is None else (
                    f" (beside it {named}'s time constant is {tau:.2g} ± {tau_error:.2g} s: waits up to about "
                    f"{waits:.2g} s, three times its upper bound, show what fades and what stays)"))
                result.not_excluded.append(NotExcluded(rival, named, rival_size, value, error, how, size, waits))
                note_once(result.notes, f"{rival} beside {named} is not excluded by this data: {rival_size} = "
                                    f"{value:.3g} ± {error:.2g} beside it, {named}'s shape refitted (up to "
                                    f"{abs(value) + SIZE_SIGMAS * error:.2g} against {named}'s {size_key} {size:.3g}); "
                                    f"{named}'s values may hold part of it. To tell: {how}")


TIME_CONSTANT = "tau_s"
"""The shape parameter that is a time constant in every effect that has one (effects.SHAPE_KEYS)."""


def rivals_from_routes(data: CampaignData, vocabulary: Discovery, routes: list[Discovery], held: Fit) -> bool:
    """A route with local errors and no period left unresolved that fits as well as the vocabulary with
    its unresolved period held (`held`; as_good, or a lower BIC, as in rivals_beside_hidden) may still
    lose the choice of routes, its places charged for their search: its local errors are then the period's
    rivals, said with what it names beside them (a 3.1 µm step at 169 mm rising over 73 mm beside a bow and
    a backlash, 11 golden targets, bench seed 97 draw 8358: the period held 58 % of the residual, and
    nothing was said of the step that three routes found). The route of the lowest BIC of those; whether
    there was one."""
    n = len(data)
    fitting = [r for r in routes[1:] if r.local_errors and not period_unresolved(r.unresolved)
               and fits_as_well(data, r.final, held)]
    if not fitting:
        return False
    route = min(fitting, key=lambda r: bic(r.final, n))
    return bool(add_local_rivals(vocabulary, route.local_errors, beside=[a for a in route.added
                                                                        if a not in vocabulary.added]))


RIVAL_SE = 1.0
"""A model predicts left-out targets as well as another when it is worse by at most this many standard errors
of the paired difference of their targets' errors (as_good)."""


def fits_as_well(data: CampaignData, fit: Fit, other: Fit) -> bool:
    """A rival's test: `fit` predicts left-out targets as well as `other` (as_good), or explains the
    campaign better by BIC, neither charged for its search."""
    return as_good(data, fit, other) or bic(fit, len(data)) < bic(other, len(data))


def as_good(data: CampaignData, fit: Fit, other: Fit) -> bool:
    """Does `fit` predict left-out targets as well as `other`: its leave-one-target-out mean square (shapes
    held, cv_group_errors: linear in the rows on a dense table) above the other's by at most RIVAL_SE
    standard errors of the targets' paired differences?"""
    groups = data.target_index
    total, se = paired_difference(data, cv_group_errors(data, fit.terms, groups),
                                  cv_group_errors(data, other.terms, groups))
    return total <= RIVAL_SE * se


def paired_difference(data: CampaignData, mine: np.ndarray, theirs: np.ndarray) -> tuple[float, float]:
    """Two models' CV compared fold by fold (each fold's sum of squared left-out residuals,
    cv_searched_errors or cv_group_errors): the difference of their mean squares (mine less theirs, µm²) and its standard
    error from the spread of the folds' shares of it (0 with one fold)."""
    diff = (mine - theirs) / max(len(data), 1)
    se = float(np.std(diff, ddof=1) * math.sqrt(len(diff))) if len(diff) > 1 else 0.0
    return float(diff.sum()), se


def add_local_rivals(result: Discovery, found: list[LocalError], beside: list[str] | None = None) -> list[LocalError]:
    """The unresolved period's group gets the local errors that would fit as well as rivals
    (`local_rivals`: sentence and region, mm): what the campaign shows there is either (`beside`: the
    effects named with them, said in the sentence). One target's
    departure never is: it is what a period seen at few targets shows at every target (beside_period).
    A rival already said in the same region is said again with `beside` when that is given. The local
    errors made rivals."""
    at = next((i for i, u in enumerate(result.unresolved) if periodic_in(u.effects)), None)
    found = [local for local in found if local.kind != TARGET]
    if at is None or not found:
        return []
    entry = result.unresolved[at]
    rivals = list(entry.local_rivals)
    for local in found:
        lo, hi = (round(v, 1) for v in local.region_mm)
        rival = LocalRival(local.sentence() + (f", with {' and '.join(beside)} beside it" if beside else ""),
                           (lo, hi), local.between_mm)
        same = [i for i, r in enumerate(rivals) if r.region_mm == (lo, hi)]
        if not same:
            rivals.append(rival)
        elif beside:  # the same local error, now with what is named beside it
            rivals[same[0]] = rival
    said = ", ".join(f"{r.region_mm[0]:g}–{r.region_mm[1]:g} {result_unit(found)}" for r in rivals)
    how = entry.how_to_tell
    if "denser targets over" not in how:
        how = f"{how}; or a local error at {said}: denser targets over it tell a wave from a local error"
    result.unresolved[at] = replace(entry, local_rivals=tuple(rivals), how_to_tell=how)
    return found


def result_unit(found: list[LocalError]) -> str:
    return found[0].position_unit if found else "mm"


LOCAL_LARGEST = 2.0
"""A local term is kept only while its size is at most this many times the largest deviation of the
campaign from the starting model (larger, it only cancels another term)."""


def beyond_the_campaign(data: CampaignData, start: Fit, fit: Fit) -> bool:
    """Is a local term of `fit` (bump, step or region: its amplitude or peak in that fit) larger than
    LOCAL_LARGEST times anything the campaign shows (its largest deviation from the starting model
    `start`)? Then it only cancels another term (a drawn bump was held by a step of +1.6 µm and one of
    -39 µm between the same two targets): not physical."""
    limit = LOCAL_LARGEST * float(np.max(np.abs(data.y - start.prediction)))
    params = fit.params()
    return any(abs(params[t.name].get(key, 0.0)) > limit for t in fit.terms if is_local(t) or is_region(t)
               for key in ("amplitude_um", "plus_um", "minus_um", "peak_um"))


def passes_beside(data: CampaignData, fit: Fit, name: str) -> bool:
    """Does the effect `name`, put in `fit` beside the local errors rather than searched for, pass the
    tests of a named effect against `fit` without it: BIC (by BIC_MARGIN), the F-test and
    leave-one-target-out CV, and its gates (gate_failures)? Not the F-test outside the local errors'
    regions (outside_p) that an effect named beside them passes: such a model is a rival of an unresolved
    period, said as a whole, not named (a 0.9 µm bow beside a 2.7 µm step on 11 targets, noise 0.5 µm:
    p 4e-11 beside it, 0.004 outside it, bench seed 71, draw 16251)."""
    n = len(data)
    without = linear_fit(data, [t for t in fit.terms if t.name != name])
    if not (bic(fit, n) - bic(without, n) < -BIC_MARGIN and f_test_p(without, fit, n) < ALPHA):
        return False
    if gate_failures(data, fit, name):
        return False
    return cv_rms_um(data, fit.terms, data.target_index) < cv_rms_um(data, without.terms, data.target_index)

"""Local terms against the vocabulary, after the route is chosen: a named effect is replaced by terms
over the located regions when these predict left-out targets better by REPLACE_SE standard errors
(unnamed_beside_regions: it only soaked up a local error); what the final model leaves along the axis,
located again, is held by local terms that pass the tests of a local term, round after round while one
is added (hold_what_is_left); a region term fitted in one direction whose other direction shows it
too is fitted in both when that predicts left-out targets better (both_directions).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from campaign.discovery.cv import cv_rms_um, cv_searched_errors, shapes_held
from campaign.discovery.data import CampaignData
from campaign.discovery.effects import HELD_PREFIX
from campaign.discovery.fit import Fit, Term, linear_fit
from campaign.discovery.held import after_final, held_said
from campaign.discovery.local import MAX_REGIONS as MAX_LOCALS
from campaign.discovery.local import (
    SIDES,
    TARGET,
    LocalError,
    describe,
    find_local,
    gap_um,
    is_local,
    passes,
    refit_local,
    shapes_refined,
    term_index,
    term_kind,
)
from campaign.discovery.locate import Located, locate
from campaign.discovery.records import Held, LocalRival, Unresolved
from campaign.discovery.result import Discovery, Step, note_once, period_candidate, period_unresolved
from campaign.discovery.rivals import add_local_rivals, beyond_the_campaign, paired_difference, result_unit
from campaign.discovery.unexplained import (
    candidate_regions,
    describe_region,
    is_region,
    region_term,
    region_terms,
)


def described_in(data: CampaignData, fit: Fit, local: LocalError) -> LocalError:
    """A bump or step found earlier (its tests as found), described from `fit`: its size and place as
    `fit` has them beside the terms added after it."""
    return describe(data, fit, local.term.name, explained_pct=local.explained_pct, delta_bic=local.delta_bic,
                    p_value=local.p_value, cv_before_um=local.cv_before_um, cv_after_um=local.cv_after_um,
                    gap_without_um=local.gap_without_um)


def unnamed_beside_regions(data: CampaignData, result: Discovery) -> Discovery:
    """Issue 34 item 2 (a): each named effect must predict left-out targets better than a general local
    term over the regions it explains. For each, the final model without it is located again
    (campaign.discovery.locate), local terms whose shape follows the data are fitted over the regions
    found (campaign.discovery.unexplained, each passing its tests); when that model's
    leave-one-target-out CV is not above the named one's, and it still wins with its regions located again
    in each fold (by REPLACE_SE standard errors when it has more parameters: regions_compared), the effect is not
    named and the regions stay in the model as unexplained local errors (a note says so), in place of the effect and of any
    bump or step term beside it. Beside an unresolved period the regions may be that period seen at few
    targets: they are then also listed as its rivals (add_local_rivals)."""
    periodic = period_unresolved(result.unresolved)
    # beside an unresolved period both sides are compared with its best candidate in (a stand-in, not
    # named): otherwise the regions would be credited with the period's residual
    period = period_candidate(result.remaining)
    if periodic and period is None:
        return result
    beside = [t for t in period.fitted.terms if t.name == period.name] if periodic and period else []
    changed = False
    for step in list(result.steps):
        name = step.effect
        if name not in {t.name for t in result.final.terms}:
            continue
        # without it, and without the fixed-shape local terms (a bump or a step it may stand beside)
        without = linear_fit(data, [t for t in result.final.terms if t.name != name
                                    and not t.name.startswith("local_error")] + beside)
        index = 1 + sum(1 for t in result.final.terms if t.name.startswith("local_region"))
        terms = [replace(t, name=t.name.split("#")[0] + (f"#{index + k}" if index + k > 1 else ""))
                 for k, t in enumerate(region_terms(data, without, locate(data, data.y - without.prediction)))]
        named_cv = cv_rms_um(data, [*result.final.terms, *beside], data.target_index)
        if not all(within_targets(data, t) for t in terms):
            terms = []  # a region that reaches the end of the travel may be the effect's own slope or bow
        if terms:
            local = linear_fit(data, [t for t in without.terms if t not in beside] + terms)
            local_cv = cv_rms_um(data, [*local.terms, *beside], data.target_index)
        else:
            local, local_cv = result.final, math.inf
        fixed, found = (None, []) if beside else bumps_and_steps_without(data, result, name)
        if (fixed is not None and (fixed_cv := cv_rms_um(data, fixed.terms, data.target_index)) <= min(named_cv,
                                                                                                         local_cv)
                and not needed_beside(data, fixed, next(t for t in result.final.terms if t.name == name), fixed_cv)):
            searched = searched_comparison(data, fixed, result.final)
            if searched.bumps_win:
                result.steps.remove(step)
                result.final, result.local_errors, changed = fixed, found, True
                note_once(result.notes, f"{name} is not named: local terms (bumps, steps) in its place predict left-out "
                                    f"targets as well (CV {fixed_cv:.3f} against {named_cv:.3f} {data.deviation_unit})")
                continue
            hold_beside_local_rivals(data, result, step, found, searched)
            changed = True
            continue
        if local_cv > named_cv and beside:
            # the regions may stand for the unresolved period too: is the effect still needed beside them?
            regions, terms = needed_beside_regions(data, result.final, name, index)
            if regions is None:
                continue
            local, local_cv = regions, cv_rms_um(data, regions.terms, data.target_index)
        elif local_cv > named_cv:
            continue
        elif not (against := regions_compared(data, local, result.final, without.terms, beside, index)).bumps_win:
            simpler = parameters(result.final) < parameters(local)
            note_once(result.notes, f"{name} stays named: local terms over the regions it explains, located again "
                                f"without the targets each fold leaves out, do not predict them better (CV "
                                f"{against.bumps_cv:.3f} against {against.effect_cv:.3f} {data.deviation_unit}"
                                + (f"; with more parameters they must win by {REPLACE_SE:g} standard errors, "
                                   f"{against.margin_cv:.2g} {data.deviation_unit}" if simpler else "")
                                + f"); with the places located on every target {local_cv:.3f} against {named_cv:.3f}")
            continue
        result.steps.remove(step)
        result.final, changed = local, True
        result.local_errors = [e for e in result.local_errors if e.term.name in {t.name for t in local.terms}] + [
            describe_region(data, local, t.name, linear_fit(data, [u for u in local.terms if u.name != t.name]))
            for t in terms]
        note_once(result.notes, f"{name} is not named: local terms over the regions it explains predict left-out targets "
                            f"as well (CV {local_cv:.3f} against {named_cv:.3f} {data.deviation_unit}); they stay in "
                            "the model as unexplained local errors")
    if changed and periodic:
        add_local_rivals(result, result.local_errors)
    if changed:
        after_final(data, result)
    return result


LEFT_ROUNDS = 3
"""How many times what the final model leaves is located again and held by region terms."""


def hold_what_is_left(data: CampaignData, result: Discovery) -> Discovery:
    """Issue 34 item 2: what the final model still leaves beyond the noise, located again
    (campaign.discovery.locate), is held by local terms whose shape follows the data over each region
    (campaign.discovery.unexplained.region_terms: any number of regions, bumps of any shape, steps
    with their rise, one direction or both), each only when it passes the tests every local term
    passes beside the rest (BIC and F-test with the search's look-elsewhere factor,
    leave-one-target-out CV); nothing is named for them. Beside an unresolved period they are also
    listed as its rivals (the period seen at few targets would fit there too: add_local_rivals).
    Repeated (LEFT_ROUNDS) while a round adds a term: a region hidden beside a larger one shows once
    that one is held."""
    before = result.final
    result = both_directions(data, result)
    # beside an unresolved period each term must also pass beside the period's best candidate (a
    # stand-in, not named): what it holds is then more than that period seen at few targets
    period = period_candidate(result.remaining)
    beside = ([t for t in period.fitted.terms if t.name == period.name]
              if period is not None and period_unresolved(result.unresolved) else [])
    final, found = result.final, list[LocalError]()
    if not beside:  # a bump, a step or one target's departure the earlier routes did not keep
        taken = {term_index(t) for t in final.terms if is_local(t)}
        final, found = more_locals(data, final, result.start, taken)
    added = [described_in(data, final, e) for e in found]  # as the fit they end in has them
    for _ in range(LEFT_ROUNDS):
        index = 1 + sum(1 for t in final.terms if t.name.startswith("local_region"))
        terms = held_regions(data, final, locate(data, data.y - final.prediction), index, beside)
        if not terms:
            break
        final = linear_fit(data, [*final.terms, *terms])
        added += [describe_region(data, final, t.name, linear_fit(data, [u for u in final.terms if u.name != t.name]))
                  for t in terms]
    if not added and final is before:
        return result
    result.final = final
    names = {t.name for t in final.terms}
    result.local_errors = [e for e in result.local_errors if e.term.name in names and e not in added] + added
    if added and period_unresolved(result.unresolved):
        add_local_rivals(result, added)
    after_final(data, result)
    if added:
        note_once(result.notes, f"what the model left beyond the noise is held by {len(added)} local term"
                            f"{'s' if len(added) > 1 else ''} over the regions located there (not named)",
              "what the model left beyond the noise is held")
    return result


def both_directions(data: CampaignData, result: Discovery) -> Discovery:
    """A region term fitted in one direction whose other direction shows it too (the same spline fitted
    there at 3σ or more: LocalError.other_um) is fitted in both when that predicts left-out targets
    better (leave-one-target-out CV): the locator may call a region one-sided where one direction's
    curve alone left its band."""
    for local in list(result.local_errors):
        if local.kind != "region" or local.directions not in ("+", "-"):
            continue
        other, error = local.params.get("other_um", 0.0), local.errors.get("other_um", math.inf)
        if not abs(other) >= 3 * error:
            continue
        term = local.term
        both = replace(term, name=term.name.replace("_plus", "").replace("_minus", ""))
        if both.name in {t.name for t in result.final.terms}:
            continue
        trial = linear_fit(data, [both if t.name == term.name else t for t in result.final.terms])
        if cv_rms_um(data, trial.terms, data.target_index) >= cv_rms_um(data, result.final.terms, data.target_index):
            continue
        without = linear_fit(data, [t for t in trial.terms if t.name != both.name])
        again = describe_region(data, trial, both.name, without)
        result.final = trial
        result.local_errors = [again if e is local else e for e in result.local_errors]
        note_once(result.notes, f"{local.sentence()}: fitted in both directions, which predicts left-out targets better")
    return result


def held_regions(data: CampaignData, fit: Fit, located: Located, index: int,
                 beside: list[Term] | None = None) -> list[Term]:
    """Region terms over the located regions beside `fit` (the largest first, each beside the ones
    kept before it), named from `index` on; each region's flexibility (its spline's pieces, from
    region_term's down to one) the one whose leave-one-target-out CV is lowest, kept only when it
    passes the tests every local term passes (campaign.discovery.local.passes), beside `fit` and,
    when given, beside `fit` with the `beside` terms (an unresolved period's best candidate) too. A
    spline with about as many pieces as targets in it fits them but cannot predict one left out:
    fewer pieces can."""
    kept: list[Term] = []
    current = fit
    regions = sorted(candidate_regions(data, located), key=lambda r: -abs(r.peak_um))
    for region in regions:
        term = region_term(data, region, index + len(kept))
        if term is None:
            continue
        least = 1 if term.shape["open_end"] > 0 or term.shape["open_start"] > 0 else 2
        tried = []
        for pieces in range(int(term.shape["pieces"]), least - 1, -1):
            trial_term = replace(term, shape={**term.shape, "pieces": float(pieces)})
            trial = linear_fit(data, [*current.terms, trial_term])
            tried.append((cv_rms_um(data, trial.terms, data.target_index), pieces, trial))
        cv_um, _, trial = min(tried, key=lambda c: (c[0], c[1]))
        if not passes(data, current, trial, (cv_rms_um(data, current.terms, data.target_index), cv_um)):
            continue
        if beside and not passes(data, linear_fit(data, [*current.terms, *beside]),
                                 linear_fit(data, [*trial.terms, *beside])):
            continue
        kept.append(trial.terms[-1])
        current = trial
    return kept


def within_targets(data: CampaignData, term: Term) -> bool:
    """Does the local term `term` (a bump from one width below its centre to one above, a step over its
    rise, a region from its start to its end) lie between the outer targets? One that reaches past
    them is seen on one side only: the data cannot tell it from a slope or a bow rising to the end of
    the travel, which the vocabulary holds; it may not take a named effect's place."""
    first, last = float(np.min(data.x)), float(np.max(data.x))
    shape = term.shape
    if "start_mm" in shape and "end_mm" in shape:
        lo, hi = shape["start_mm"], shape["end_mm"]
    elif "from_mm" in shape:  # a departure at one target (or two neighbours), never at the outer two
        lo, hi = shape["centre_mm"], shape.get("last_mm", shape["centre_mm"])
    else:
        reach = shape["width_mm"] if "step" not in term.name else shape["width_mm"] / 2
        lo, hi = shape["centre_mm"] - reach, shape["centre_mm"] + reach
    return bool(lo > first and hi < last)


def hold_beside_local_rivals(data: CampaignData, result: Discovery, step: Step, found: list[LocalError],
                             searched: Searched) -> None:
    """The named effect of `step` cannot be told from the local terms `found` in its place: they predict
    left-out targets as well with their places chosen on all the targets, not better with them refined
    again in each fold (`searched`). It is not named (issue 34 item 2 a) and not replaced: it holds what
    it explains in the final model (HELD_PREFIX, said in `held`), and an unresolved group lists as its
    rivals the local errors that are not in the model already, which denser targets over them tell
    apart (the follow-up measures there)."""
    name = step.effect
    result.steps.remove(step)
    without = linear_fit(data, [t for t in result.final.terms if t.name != name])
    result.final = linear_fit(data, [replace(t, name=HELD_PREFIX + name) if t.name == name else t
                                     for t in result.final.terms])
    kept = {e.term.name for e in result.local_errors}
    new = [e for e in found if e.term.name not in kept] or found
    rivals = tuple(LocalRival(e.sentence(), (round(e.region_mm[0], 1), round(e.region_mm[1], 1)), e.between_mm)
                   for e in new)
    places = " and ".join(f"{r.region_mm[0]:g}–{r.region_mm[1]:g} {result_unit(new)}" for r in rivals)
    dev = data.deviation_unit
    result.unresolved.append(Unresolved(
        (name,), f"local terms in {name}'s place predict left-out targets as well with their places chosen on all "
                 f"the targets, but not better with them refined again without each target (CV {searched.bumps_cv:.3f} "
                 f"against {searched.effect_cv:.3f} {dev}; {REPLACE_SE:g} standard errors {searched.margin_cv:.3f} {dev}): the "
                 f"campaign cannot tell {name} from local errors there",
        f"denser targets over {places} tell {name} from a local error there", local_rivals=rivals))
    held = HELD_PREFIX + name
    result.held.append(Held(name, (name,), held_said(data, result.final, held, (name,), places),
                            result.final.params()[held], gap_um(data, data.y - without.prediction)))
    note_once(result.notes, f"{name} is not named: local terms in its place ({'; '.join(e.sentence() for e in new)}) "
                        "would fit about as well; it holds what it explains in the model, and which of them it is "
                        "stays unresolved")


@dataclass(frozen=True)
class Searched:
    """Bump and step terms in a named effect's place against it, each fold refining their places again
    (searched_comparison): whether they win, both sides' CV RMS and the margin they had to win by, in
    the deviation unit (the margin as the RMS change it amounts to)."""

    bumps_win: bool
    bumps_cv: float
    effect_cv: float
    margin_cv: float


SEARCHED_FOLDS = 25
"""At most this many folds for a CV whose folds refine places again (cv_searched_errors): more targets
are left out in this many contiguous blocks, so a dense table costs as few refinements as a sparse one."""


def searched_comparison(data: CampaignData, fixed: Fit, named: Fit) -> Searched:
    """Do the bumps and steps of `fixed`, found in a named effect's place, predict left-out targets
    better than the `named` model when each fold refines their centres and widths again
    (cv_searched_errors)? With places chosen on all the targets they beat an effect of fixed shape that
    fits as well. When they have more parameters, they must win by more than REPLACE_SE standard errors
    of the paired difference of the folds' errors (when cross-validation cannot tell two models apart, the
    simpler is kept, and the local terms stay its rivals): a 0.66 µm bump stood in for a machine's 0.3 µm bow
    at CV 0.503 against 0.521 µm, 0.516 against 0.521 µm refined in each fold (a null draw, seed 16489)."""
    return margin_comparison(data, fixed, named, shapes_refined, shapes_refined)


REPLACE_SE = 2.0
"""Local terms with more parameters replace a named effect only when their CV beats it by this many
standard errors of the paired difference of the folds' errors; within it the effect is held beside them
as rivals (unresolved). With one standard error (the one-standard-error rule of model choice) a null
machine's 0.9 µm bow on 21 golden targets was replaced by a step rising over 75 mm (CV 0.612 against
0.637 µm, a standard error 0.025 µm: bench seed 131, draw 16621); a replacement is a claim that the
effect is not there, so it asks for a difference of about 95 % confidence. The draws bench over eight
seeds: that null held as a rival, one more bump located (seed 23), nothing else changed; two fresh
seeds (181, 199): no total changed."""


Refined = Callable[[CampaignData, list[Term]], list[Term]]
"""The terms a CV fold fits (cv_searched_errors): from the terms fitted on all the data and the fold's rows."""


def margin_comparison(data: CampaignData, local: Fit, named: Fit, local_refined: Refined,
                      named_refined: Refined) -> Searched:
    """Local terms (`local`) against the `named` model by the CV whose folds (at most SEARCHED_FOLDS
    blocks of targets) get their terms from `local_refined` and `named_refined`; with more parameters than
    the named model, the local terms win only by more than REPLACE_SE standard errors of the paired
    difference of the folds' errors."""
    targets = data.target_index
    count = int(targets.max()) + 1 if len(targets) else 0
    groups = targets if count <= SEARCHED_FOLDS else (targets * SEARCHED_FOLDS) // count
    with_local = cv_searched_errors(data, local.terms, groups, local_refined)
    with_effect = cv_searched_errors(data, named.terms, groups, named_refined)
    n = max(len(data), 1)
    total, se = paired_difference(data, with_local, with_effect)
    simpler = parameters(named) < parameters(local)
    margin = REPLACE_SE * se if simpler else 0.0
    effect_ms = float(with_effect.sum()) / n
    return Searched(total < -margin if simpler else total <= 0.0, math.sqrt(float(with_local.sum()) / n),
                    math.sqrt(effect_ms), math.sqrt(effect_ms) - math.sqrt(max(effect_ms - margin, 0.0)))


def regions_compared(data: CampaignData, local: Fit, named: Fit, without: list[Term], beside: list[Term],
                     index: int) -> Searched:
    """Region terms in a named effect's place (`local`) against the `named` model, each fold locating its
    regions again beside `without` (the named model less the effect), both sides with the terms `beside`
    (an unresolved period's stand-in) as their leave-one-target-out CVs have them."""
    if beside:
        local, named = linear_fit(data, [*local.terms, *beside]), linear_fit(data, [*named.terms, *beside])
    return margin_comparison(data, local, named, regions_located_again(without, index), shapes_held)


def regions_located_again(beside: list[Term], index: int) -> Refined:
    """A fold's region terms located again on its own rows beside the terms `beside` (their shapes held),
    numbered from `index` and dropped when one reaches past the outer targets (as unnamed_beside_regions
    numbers and drops them): the regions' places were chosen on all the targets, so with them held the
    left-out target is predicted too well."""

    def refined(fold: CampaignData, terms: list[Term]) -> list[Term]:
        without = linear_fit(fold, beside)
        found = region_terms(fold, without, locate(fold, fold.y - without.prediction))
        if not all(within_targets(fold, t) for t in found):
            found = []
        return [*beside, *(replace(t, name=t.name.split("#")[0] + (f"#{index + k}" if index + k > 1 else ""))
                           for k, t in enumerate(found))]

    return refined


def parameters(fit: Fit) -> int:
    """A fit's parameters with each local term's searched centre and width counted (a departure at one
    target: its place once; a region term: its start and end, which the locator chose; Fit.n_params
    counts the vocabulary's searched shapes only)."""
    return fit.n_params + sum(1 if term_kind(t) == TARGET else len(t.shape) for t in fit.terms if is_local(t)) + sum(
        2 for t in fit.terms if is_region(t))


def needed_beside_regions(data: CampaignData, final: Fit, name: str, index: int) -> tuple[Fit | None, list[Term]]:
    """Beside an unresolved period: region terms located beside `final` without `name` (and without any
    period), and the fit of them without `name` when `name` added to them does not predict left-out
    targets better (None when it does, or when no region term passes its tests)."""
    without = linear_fit(data, [t for t in final.terms if t.name != name and not t.name.startswith("local_error")])
    terms = [replace(t, name=t.name.split("#")[0] + (f"#{index + k}" if index + k > 1 else ""))
             for k, t in enumerate(region_terms(data, without, locate(data, data.y - without.prediction)))]
    if not terms or not all(within_targets(data, t) for t in terms):
        return None, []
    regions = linear_fit(data, [*without.terms, *terms])
    named = linear_fit(data, [*regions.terms, next(t for t in final.terms if t.name == name)])
    if cv_rms_um(data, named.terms, data.target_index) < cv_rms_um(data, regions.terms, data.target_index):
        return None, []
    return regions, terms


def needed_beside(data: CampaignData, fit: Fit, term: Term, cv_um: float) -> bool:
    """Is the named effect's `term` still needed beside the bumps and steps of `fit` (found in its
    place; `cv_um` their CV): does it pass a local term's tests there (BIC and F-test with the local
    search's look-elsewhere factor without its sides, as before the grid looked in one direction
    alone, CV)? Bumps searched anew beside the rest improve the CV whether
    the effect is there or not: the effect goes only when they hold what it held (a 1 µm backlash went
    beside a wave's bumps, which held the wave and not the reversal)."""
    with_it = linear_fit(data, [*fit.terms, term])
    return passes(data, fit, with_it, (cv_um, cv_rms_um(data, with_it.terms, data.target_index)))


def more_locals(data: CampaignData, fit: Fit, start: Fit, taken: set[int]) -> tuple[Fit, list[LocalError]]:
    """Local errors looked for beside `fit` one after the other (find_local), at the indices not `taken`,
    up to MAX_LOCALS on the axis in all: each kept while it lies within the targets (within_targets) and no
    local term of the fit grows beyond what the campaign shows from `start` (beyond_the_campaign). The
    fit with them, and them as found (each tested beside the fit before it)."""
    free = [k for k in range(1, MAX_LOCALS + 1) if k not in taken][:MAX_LOCALS - len(taken)]
    found: list[LocalError] = []
    for index in free:
        more = find_local(data, fit, index)
        if more is None or not within_targets(data, more.term):
            break
        trial = linear_fit(data, [*fit.terms, more.term])
        if beyond_the_campaign(data, start, trial):
            break
        fit = trial
        found.append(more)
    return fit, found


def bumps_and_steps_without(data: CampaignData, result: Discovery, name: str) -> tuple[Fit | None, list[LocalError]]:
    """The final model without the named effect `name`, its bump and step terms refitted in its place
    and more looked for beside them (campaign.discovery.local, up to MAX_REGIONS in all), each kept
    only while it passes its tests beside the rest: the fit and its local errors; None when no local
    term is left (the comparison is then with the region terms alone)."""
    fit = linear_fit(data, [t for t in result.final.terms if t.name != name])
    kept: list[LocalError] = []
    for local in result.local_errors:
        if local.kind == "region" or local.term.name not in {t.name for t in fit.terms}:
            continue
        fit, refined = refit_local(data, fit, local)
        kept.append(refined)
    fit, more = more_locals(data, fit, result.start, {term_index(e.term) for e in kept})
    kept += more
    for local in list(kept):
        without = linear_fit(data, [t for t in fit.terms if t.name != local.term.name])
        if not passes(data, without, fit, sides=len(SIDES)):
            kept.remove(local)
            fit = without
    if not kept:
        return None, []
    return fit, [described_in(data, fit, e) for e in kept] + [
        e for e in result.local_errors if e.kind == "region" and e.term.name in {t.name for t in fit.terms}]

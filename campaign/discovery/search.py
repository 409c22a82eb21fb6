"""Discovery's entry point, discover: routes through the vocabulary and local errors, the one that explains
the campaign best kept (route_score), then tested against its rivals and what it leaves (issue 34).

The routes: the vocabulary alone (campaign.discovery.vocabulary.search_vocabulary); the vocabulary
again beside local errors (campaign.discovery.local) found beside what it named, beside it with each
named effect left out in turn, and with each effect it did not name put in (with_locals); region
terms over the regions located before naming (campaign.discovery.unexplained), then the vocabulary
beside them (with_regions). A vocabulary effect is thus named only when it explains the campaign
better than local terms over the regions located. After the choice: campaign.discovery.unnamed,
.held and .rivals; then the locator on what the final model leaves (campaign.discovery.locate).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np

from campaign.discovery.cv import cv_rms_um
from campaign.discovery.data import CampaignData, keep_rows
from campaign.discovery.effects import HELD_PREFIX, PERIOD_KEY, SIZE_SIGMAS
from campaign.discovery.fit import Fit, Term, bic, drop_collinear, f_test_p, full_columns, linear_fit
from campaign.discovery.held import (
    beside_unresolved_period,
    held_fit,
    hold_unresolved,
    model_prediction,
    places,
    with_local_terms,
)
from campaign.discovery.local import (
    SIDES,
    TARGET,
    LocalError,
    find_locals,
    is_local,
    look_elsewhere,
    passes,
    refit_local,
    term_kind,
)
from campaign.discovery.locate import Located, beside_period, locate
from campaign.discovery.naming import ALPHA, BIC_MARGIN
from campaign.discovery.periodogram import independent_periods
from campaign.discovery.result import Discovery, note_once, period_unresolved
from campaign.discovery.rivals import (
    add_local_rivals,
    beyond_the_campaign,
    fits_as_well,
    passes_beside,
    rivals_from_routes,
    rivals_not_excluded,
    shape_rivals,
    unnamed_forms,
)
from campaign.discovery.unexplained import (
    REGION_SHARE,
    candidate_regions,
    describe_region,
    is_region,
    region_terms,
)
from campaign.discovery.unnamed import hold_what_is_left, unnamed_beside_regions
from campaign.discovery.vocabulary import by_table, may_soak, noise_measured, search_vocabulary
from campaign.model import ErrorModel


def discover(data: CampaignData, model: ErrorModel, given: dict[str, set[str]],
             stage: Callable[[str], None] | None = None) -> Discovery:
    """Run discovery on a campaign from a starting model (`given`: the parameters the user gave
    per effect; the others are fitted). Routes, the one that explains the campaign best
    (route_score) kept: the vocabulary alone; the vocabulary, then errors outside it located
    beside what it named (campaign.discovery.local), beside it with each effect it named left out in
    turn (locals_beside_all_but), and with each effect it did not name put in (locals_beside_unnamed);
    errors outside it located first, beside the starting model, then the vocabulary beside them; region terms over the located regions, then the
    vocabulary beside them (with_regions); and, when those regions let the vocabulary name more, bumps and
    steps located beside that vocabulary, then the vocabulary beside them. A vocabulary effect is thus named only when
    it explains the campaign better than local terms over the regions located: an effect that merely
    soaked up a local error (a bow, a short period, a reversal) is not named. A bump or step of the
    route kept is said with the other shape when that fits as well (shape_rivals). `stage` is told, in a
    few words, each stage as it begins (the command line shows it while a dense table takes seconds)."""
    said = stage or (lambda _: None)
    said("searching the vocabulary")
    vocabulary = search_vocabulary(data, model, given)
    periodic = period_unresolved(vocabulary.unresolved)
    soakers = [n for n in reversed(vocabulary.added) if may_soak(n)]
    beside = locals_beside(data, vocabulary.final, soakers)
    held_vocabulary = None  # the vocabulary's model with its unresolved groups held, once computed
    if not beside:
        held_vocabulary = held_fit(data, vocabulary) or vocabulary.final
        if held_vocabulary is not vocabulary.final:
            # beside a reversal its unresolved rivals hold alike: left in, it hides the local error from the
            # grid, and a named effect may hold it beside the reversal
            beside = locals_beside(data, held_vocabulary, soakers)
    first = find_locals(data, vocabulary.start) if vocabulary.added else []
    routes = [vocabulary]
    hidden = ((found, False) for found in locals_beside_unnamed(data, vocabulary, beside, periodic))
    own = ((found, True) for found in itertools.chain((beside, first), locals_beside_all_but(data, vocabulary)))
    tried: list[tuple[list[LocalError], bool]] = []
    said("looking for local errors beside what it named")
    for found, rivals_said in itertools.chain(own, hidden):
        if found and not any(_same_places(found, r.local_errors) for r in routes[1:]) and not any(
                was == rivals_said and _same_found(found, earlier) for earlier, was in tried):
            tried.append((found, rivals_said))
            said(f"route {len(tried)}: the vocabulary again beside local errors in {places(found)} place(s)")
            route = with_locals(data, model, given, vocabulary, found, periodic, rivals_said=rivals_said)
            if route is not None:
                routes.append(route)
    if periodic:
        rivals_beside_hidden(data, model, given, vocabulary, routes)
    said("locating where the campaign departs from the starting model")
    start_located = locate(data, data.y - vocabulary.start.prediction)
    said("local terms over the regions located, and the vocabulary beside them")
    regions = with_regions(data, model, given, vocabulary, start_located, periodic)
    if regions is not None and (cv_rms_um(data, regions.final.terms, data.target_index)
                                < cv_rms_um(data, vocabulary.final.terms, data.target_index)):
        routes.append(regions)  # unexplained local errors, only when they also predict left-out targets better
        if set(regions.added) - set(vocabulary.added):
            # what the regions let the vocabulary name (a bow a step hid) may in turn show the step: bumps
            # and steps looked for beside that vocabulary alone, the regions left out
            named = held_fit(data, regions) or regions.final
            found = find_locals(data, linear_fit(data, [t for t in named.terms if not is_region(t)]))
            if found and not any(_same_places(found, r.local_errors) for r in routes[1:]):
                route = with_locals(data, model, given, vocabulary, found, periodic)
                if route is not None:
                    routes.append(route)
    said(f"choosing between {len(routes)} routes")
    scores = [route_score(data, r, held_vocabulary if r is vocabulary and not periodic else None) for r in routes]
    best = min(range(len(routes)), key=lambda i: scores[i] + (0.0 if i == 0 else BIC_MARGIN))
    if best == 0 and (closer := [i for i in range(1, len(routes)) if scores[i] < scores[0]]):
        # BIC favours local terms, by less than its margin: undecided, so the leave-one-target-out CV decides
        cvs = {i: cv_rms_um(data, routes[i].final.terms, data.target_index) for i in [0, *closer]}
        best = min(cvs, key=lambda i: cvs[i])
    if best and routes[0].added:
        dropped = [name for name in routes[0].added if name not in routes[best].added]
        for name in dropped:
            note_once(routes[best].notes, f"{name} explained part of the residual before the local errors were located; "
                                      "beside them it is not significant: not named (it soaked up a local error)")
    said("testing what the route kept against its rivals")
    result = unnamed_beside_regions(data, routes[best])
    result = hold_what_is_left(data, result)
    result = hold_unresolved(data, result, periods=False)
    result = beside_unresolved_period(data, result)
    result = hold_unresolved(data, result, periods=True)
    rivals_not_excluded(data, result)
    shape_rivals(data, result)
    said("locating what the final model leaves")
    result.located_before = start_located if result.start is vocabulary.start else locate(
        data, data.y - result.start.prediction)
    result.located_after = locate(data, data.y - model_prediction(data, result.final))
    result.tables = by_table(data, data.y - result.final.prediction)
    if period_unresolved(result.unresolved):
        # single targets' departures over the travel are the unresolved period seen at few targets: said there
        for located in (result.located_before, result.located_after):
            located.regions[:] = beside_period(located.regions, float(np.ptp(data.x)) or 1.0)
    result.noise_measured = noise_measured(data)
    return result


def locals_beside_all_but(data: CampaignData, vocabulary: Discovery) -> Iterator[list[LocalError]]:
    """The local errors found beside the vocabulary's model with each effect it named left out in turn
    (not the starting model's): a named effect may hold part of a local error well enough to hide it
    from the grid and leave another shape in its place (a 2.5 µm step rising over 77 mm at 259 mm, 17
    golden targets: beside the backlash and a bow it was said as a bump at 334 mm, and the bow named;
    beside the backlash alone the grid finds the step, and then nothing names the bow, bench seed 157,
    draw 8604). Only those that hold what the effect held: the model without it and with them has a BIC
    below the vocabulary's (otherwise the route could only name the effect again beside them, which the
    local errors found beside the whole vocabulary stand for; on a dense table of 100,000 rows a period
    and a bow left out gave bumps that held neither, and their two routes took 11 s)."""
    started = {t.name for t in vocabulary.start.terms}
    n = len(data)
    for name in vocabulary.added:
        if name in started:
            continue
        others = [t for t in vocabulary.final.terms if t.name != name]
        found = find_locals(data, linear_fit(data, others))
        if found and bic(linear_fit(data, [*others, *(e.term for e in found)]), n) < bic(vocabulary.final, n):
            yield found


def locals_beside_unnamed(data: CampaignData, vocabulary: Discovery, beside: list[LocalError], periodic: bool
                          ) -> Iterator[list[LocalError]]:
    """The local errors found beside the vocabulary's model with each effect it did not name put in
    (unnamed_forms): a local error may hide an effect, which then hides the error's shape (a 2.9 µm step
    rising over 16 mm at 424 mm beside a 1.2 µm bow, 17 golden targets: beside the backlash alone the grid
    finds a bump at 484 mm, width 94 mm, and beside it the bow is not significant; beside the backlash and
    the bow it finds the step, BIC 20 lower, bench seed 131, draw 8578). Kept only when they hold more
    than the local errors found beside the vocabulary (`beside`): the model with the effect and them has
    a BIC below the vocabulary's with those and below the vocabulary's alone. The route then searches the
    vocabulary again beside them (with_locals), which names the effect only if it passes there. Tried
    only for an effect whose candidate lowered the BIC by BIC_MARGIN in the search (the candidate as the
    search fitted it: beside the best period candidate when a period is unresolved, so that there the
    period's share counts too) and that is not in the model already (a stand-in): on the dense bench's
    table none is, and each grid there takes 0.4 s. The test is not of the effect beside the
    vocabulary's model: an effect a local error hides may explain nothing beside that model (a bow beside
    a 2.6 µm step at 219 mm and an unresolved period, 11 golden targets, bench seed 23, draw 8284: BIC 2
    higher with the bow alone; with the bow put in the grid finds the step, and the route names the bow
    and resolves the period). Beside a period the vocabulary leaves unresolved (`periodic`), only local
    errors in one place (places): several places that take the period's place with the effect are the
    period seen at few targets (a 1 µm, 10 mm lead on 11 targets beside a bow and a 3 µm bump 150 mm wide:
    with the bow put in, three steps of −6.5, −2.8 and +2.1 µm held the bump and the lead's readings, and
    no period was said); and when the period stays unresolved beside them they are not said as its rivals
    here (rivals_beside_hidden says them, with what is named beside them)."""
    n = len(data)
    own = bic(vocabulary.final, n)
    bar = min(own, bic(linear_fit(data, [*vocabulary.final.terms, *(e.term for e in beside)]), n)) if beside else own
    in_model = {t.name.removeprefix(HELD_PREFIX) for t in vocabulary.final.terms}
    for cand, term in unnamed_forms(data, vocabulary):
        if cand.name in in_model or cand.fit is None or bic(cand.fit, n) >= own - BIC_MARGIN:
            continue
        with_term = linear_fit(data, [*vocabulary.final.terms, term])
        found = find_locals(data, with_term)
        if periodic and places(found) > 1:
            continue
        if found and bic(linear_fit(data, [*with_term.terms, *(e.term for e in found)]), n) < bar:
            yield found


def locals_beside(data: CampaignData, fit: Fit, soakers: list[str]) -> list[LocalError]:
    """The local errors found beside `fit` (campaign.discovery.local.find_locals), or, when none is, beside
    `fit` without each named effect of `soakers` in turn (a short period or a reversal may have soaked up
    most of it): the first found."""
    found = find_locals(data, fit)
    for name in soakers if not found else ():
        found = find_locals(data, linear_fit(data, [t for t in fit.terms if t.name != name]))
        if found:
            break
    return found


def _same_places(a: list[LocalError], b: list[LocalError]) -> bool:
    """The same local errors in the same places (a departure at one target and at it and the next are not)."""
    return len(a) == len(b) and all(x.kind == y.kind and x.params.get("last_mm") == y.params.get("last_mm")
                                    and abs(x.params["centre_mm"] - y.params["centre_mm"]) < 1e-6 for x, y in zip(a, b))


SAME_FOUND = 1e-4
"""Two local errors found by different routes are the same start for with_locals when their kinds and
targets agree and their centres and widths differ by at most this share of the width (a route
found again beside another effect left out, to rounding of its refinement: its with_locals would
refine it to the same result, at the cost of a vocabulary search)."""


def _same_found(a: list[LocalError], b: list[LocalError]) -> bool:
    """The same local errors found, each's centre and width within SAME_FOUND of its width."""
    def near(x: LocalError, y: LocalError) -> bool:
        width = max(x.params.get("width_mm", 0.0), y.params.get("width_mm", 0.0))
        return (x.kind == y.kind and x.directions == y.directions and x.params.get("last_mm") == y.params.get("last_mm")
                and abs(x.params["centre_mm"] - y.params["centre_mm"]) <= SAME_FOUND * width
                and abs(x.params.get("width_mm", 0.0) - y.params.get("width_mm", 0.0)) <= SAME_FOUND * width)
    return len(a) == len(b) and all(near(x, y) for x, y in zip(a, b))


def route_score(data: CampaignData, result: Discovery, held: Fit | None = None) -> float:
    """How well a route explains the campaign: the BIC of its final model (with what its unresolved
    groups show held, as the route chosen will hold it: held_fit; `held`, that model when already
    computed), each local term's centre
    and width counted with its search's look-elsewhere factor (the grid's with its sides, a region
    term's without), a searched period with its own."""
    n = len(data)
    final = held or held_fit(data, result, periods=True) or result.final  # routes compared with their groups held
    score = bic(final, n)
    score += sum((1 if e.kind == TARGET else 2) * math.log(n)  # a target's place is one choice, not two shapes
                 + 2 * math.log(look_elsewhere(data, 1 if e.kind == "region" else len(SIDES)))
                 for e in result.local_errors)
    if any(t.name.removeprefix(HELD_PREFIX) in PERIOD_KEY and t.searched for t in final.terms):
        score += 2 * math.log(independent_periods(data))
    return score


def rivals_beside_hidden(data: CampaignData, model: ErrorModel, given: dict[str, set[str]], vocabulary: Discovery,
                         routes: list[Discovery]) -> None:
    """Beside a period the vocabulary leaves unresolved, a local error may hide an effect as well as the
    period may stand in for it: a step's rise bends the residual, so beside the vocabulary alone the
    grid finds one wide bump, and only beside a bow the step (a 3.5 µm step on 11 golden targets beside
    a 1.1 µm bow, bench seed 199, draw 541: the period held 51 % of the residual, and nothing was said
    of the step). For each effect the search did not name (not a period, and with no shape to search),
    local errors are looked for beside the vocabulary with it. When the vocabulary searched again beside
    them leaves no period unresolved (with_locals), or, when that search takes the period first, the
    effect put in beside them passes the tests of a named effect there (with_locals' `beside`), and
    that model fits as well as the vocabulary with the period held by its best candidate (as_good: its
    leave-one-target-out CV within RIVAL_SE, the period held in every fold, which favours it; or a lower
    BIC, neither side charged for its search: the period's candidates, the local errors' places), its
    local errors become the period's rivals, said with what is named beside them. The route is not
    chosen by this (its place and shape count against it in route_score): the follow-up measures
    densely over the rivals, which tells them apart. A route already found that fits as well comes
    first (rivals_from_routes)."""
    held = held_fit(data, vocabulary, periods=True)
    if held is None:
        return
    if rivals_from_routes(data, vocabulary, routes, held):
        return  # a route already found says them, with what it names beside them
    for _, term in unnamed_forms(data, vocabulary):
        name = term.name
        found = find_locals(data, linear_fit(data, [*vocabulary.final.terms, term]))
        if not found or any(_same_places(found, r.local_errors) for r in routes[1:]):
            continue
        route = with_locals(data, model, given, vocabulary, found, periodic=False)
        forced = route is None or period_unresolved(route.unresolved)
        if forced:  # the search took the period first: the effect put in beside them, kept if it passes there
            route = with_locals(data, model, given, vocabulary, found, periodic=False, beside=term)
        if route is None or period_unresolved(route.unresolved) or not fits_as_well(data, route.final, held):
            continue
        named = [n for n in route.added if n not in vocabulary.added] + ([name] if forced else [])
        add_local_rivals(vocabulary, route.local_errors, beside=named)
        return  # one such model is what the follow-up needs to look for


def with_locals(data: CampaignData, model: ErrorModel, given: dict[str, set[str]], vocabulary: Discovery,
                found: list[LocalError], periodic: bool, beside: Term | None = None, rivals_said: bool = True
                ) -> Discovery | None:
    """The vocabulary searched again with the local errors `found` in the model, what its unresolved
    groups show held (hold_unresolved), then each local term refitted beside what is named and held; a
    local term that no longer passes its tests beside the
    rest is left out. None when none is left, or when an unresolved period stays beside them (the
    local error may be that period seen at few targets: said in a note). `beside`: an effect in the
    model from the start with them (not searched for: the search may take a period first), kept only
    when it passes the tests of a named effect beside the rest (passes_beside); None when it does not.
    `rivals_said`: False for local errors found with an effect the vocabulary did not name put in
    (locals_beside_unnamed): beside an unresolved period they become its rivals only through
    rivals_beside_hidden, which says what is named beside them."""
    extra = [local.term for local in found] + ([beside] if beside is not None else [])
    again = search_vocabulary(data, model, given, extra)
    left_out: dict[str, float] = {}  # effects named only beside the local terms that do not show outside them
    while failing := {n: p for n in again.added if n not in vocabulary.added
                      and (p := outside_p(data, again.final, n, found)) >= ALPHA}:
        left_out.update(failing)  # searched again without them, so that what is named is fitted without them
        again = search_vocabulary(data, model, given, extra, frozenset(left_out))
    for name, p in left_out.items():
        note_once(again.notes, f"{name} explained part of the residual beside the local errors, but not on the targets "
                           f"outside their regions (F-test p = {p:.2g} there): not named (it held what the local "
                           "terms leave of an error they describe in part)")
    if periodic and period_unresolved(again.unresolved):
        if rivals_said and (rivals := add_local_rivals(vocabulary, found)):
            note_once(vocabulary.notes, f"{rivals[0].sentence()} would fit too, but the unresolved periodic error is "
                                    "still there beside it: it may be that error seen at few targets, so it is not added")
        return None
    # the local terms are tested beside what an unresolved group holds, which the route then keeps (and
    # route_score, and hold_unresolved after the route is chosen, find held already)
    again = hold_unresolved(data, again, periods=False)
    final, kept = again.final, []
    for local in found:
        final, refined = refit_local(data, final, local)
        kept.append(refined)
    for local in list(kept):
        without = linear_fit(data, [t for t in final.terms if t.name != local.term.name])
        small = abs(local.size_um) < SIZE_SIGMAS * local.errors.get(local.size_key, 0.0)
        if not passes(data, without, final, sides=len(SIDES)) or small or beyond_the_campaign(data, vocabulary.start,
                                                                                          final):
            kept.remove(local)
            final = without
    if not kept or (beside is not None and not passes_beside(data, final, beside.name)):
        return None
    return with_local_terms(data, again, vocabulary, final, kept)


OUTSIDE_MIN_ROWS = 10
"""The fewest rows outside the local errors' regions, beyond the parameters, that outside_p tests on."""


OUTSIDE_MORE_TARGETS = 3
"""The fewest targets outside the local errors' regions beyond the tested effect's own columns (a bow's two)
that outside_p tests on: on fewer positions its columns are near the others' (a drawn 2 µm bow on 21
targets: p 1.0 on two targets, 0.0056 on four, 2e-13 on eight)."""


def outside_p(data: CampaignData, fit: Fit, name: str, found: list[LocalError]) -> float:
    """The F-test p of the effect `name` of `fit` on the rows outside the regions of the local errors
    `found`, the other effects of `fit` fitted with it there, and its steps (a step's level goes on past
    its rise); what its bumps and departures hold there (a bump's tails) is taken off the readings as
    `fit` has it. 0 (it shows) when too few rows or targets lie outside to tell, or when the other terms
    span its columns there.

    An effect along the travel that the vocabulary named only beside local terms must show outside them
    too: otherwise it holds what they leave of an error they describe in part (a wave of 9.9 mm over
    261-416 mm on 17 uniform targets, said as two steps and two targets' departure, left a 0.4 µm wave of
    81 mm that a screw lead took, p 0.64 outside)."""
    inside = np.zeros(len(data), dtype=bool)
    for local in found:
        low, high = local.region_mm
        inside |= (data.x >= low) & (data.x <= high)
    kept = [t for t in fit.terms if not is_region(t) and (not is_local(t) or term_kind(t) == "step")]
    held = sum((full_columns(data, t) @ fit.coefs[i] for i, t in enumerate(fit.terms) if t not in kept),
               np.zeros(len(data)))  # the bumps' and departures' part, as fitted
    outside = replace(keep_rows(data, ~inside), y=(data.y - held)[~inside])
    effect = next(t for t in kept if t.name == name)
    own = full_columns(outside, effect).shape[1]
    if (len(outside) < OUTSIDE_MIN_ROWS + len(kept) + 2
            or len(np.unique(np.round(outside.x, 6))) < own + OUTSIDE_MORE_TARGETS
            or not any(drop_collinear(outside, [t for t in kept if t is not effect], effect).keep or ())):
        return 0.0
    return f_test_p(linear_fit(outside, [t for t in kept if t is not effect]), linear_fit(outside, kept), len(outside))


def with_regions(data: CampaignData, model: ErrorModel, given: dict[str, set[str]], vocabulary: Discovery,
                 located: Located, periodic: bool) -> Discovery | None:
    """The route of unexplained local errors (campaign.discovery.unexplained): a local term whose shape
    follows the data over each region the locator found beside the starting model (each kept only
    when it passes the tests), the vocabulary searched beside them, then each term tested again beside
    what is named. None when none is left, or when a period stays unresolved beside them (the
    regions may be that period seen at few targets: with_locals makes them its rivals), or when the
    regions together cover most of the travel (`over_the_travel`)."""
    if over_the_travel(data, located):
        return None
    terms = region_terms(data, vocabulary.start, located)
    if not terms:
        return None
    again = search_vocabulary(data, model, given, terms)
    if period_unresolved(again.unresolved):
        return None  # a region may be the unresolved period seen at few targets (as for with_locals)
    final, kept = again.final, []
    for term in terms:
        without = linear_fit(data, [t for t in final.terms if t.name != term.name])
        if passes(data, without, final) and not beyond_the_campaign(data, vocabulary.start, final):
            kept.append(term)
        else:
            final = without
    if not kept:
        return None
    found = [describe_region(data, final, term.name, linear_fit(data, [t for t in final.terms if t.name != term.name]))
             for term in kept]
    return with_local_terms(data, again, vocabulary, final, found)


def over_the_travel(data: CampaignData, located: Located) -> bool:
    """Whether the located regions a local term may hold are a row of lobes over the travel: more than
    LOBES regions, together covering more than REGION_SHARE of the travel (the length of their union).
    The residual then departs from the starting model over most of the axis in many places, a structure
    over the travel (a screw lead seen lobe by lobe on a dense table), which is the vocabulary's to
    explain, as one region that wide is (candidate_regions), not a set of local errors. (A few regions,
    however wide together, may each be one: a zone, and the starting model bent around it on either
    side.) Each lobe tried as a local term, and the vocabulary searched again beside them all, cost
    most of a dense table's discovery."""
    regions = candidate_regions(data, located)
    if len(regions) <= LOBES:
        return False
    covered, reach = 0.0, -math.inf
    for start, end in sorted((r.start, r.end) for r in regions):
        covered += max(0.0, end - max(start, reach))
        reach = max(reach, end)
    return covered > REGION_SHARE * (float(np.ptp(data.x)) or 1.0)


LOBES = 10
"""More located regions than this over most of the travel are a row of lobes (over_the_travel): an
axis's local errors are a few (a step, a worn zone or two, each seen at most in both directions and with
the starting model bent beside it); a 10 mm lead over 600 mm shows up to 120 lobes."""

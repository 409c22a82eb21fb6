"""The vocabulary's search (search_vocabulary): find where the simulated and the measured campaign
disagree, name the effect the model is missing, add it, refit, and repeat until what is left is noise
(issue 4, reference §5). campaign.discovery.search.discover runs it as one of its routes.

1. Fit the current model (campaign.discovery.fit) and simulate the campaign with it; the
   residual is measured - simulated (µm). An offset is always fitted (the laser datum is arbitrary).
2. Summarise where they disagree: by position, by direction, by run.
3. Rank every effect not in the model by how much of the residual it explains, penalised for
   its parameters (the BIC change).
4. Accept the best-ranked one that passes all of: BIC lower by more than BIC_MARGIN; a nested
   F-test with p < ALPHA (times the number of independent periods searched, for a periodic
   error); and a lower cross-validated RMS (leave one run out for time effects, one target out
   for spatial ones). Then refit every shape parameter and go back to 1.
5. An effect whose columns the model already spans is not named: it is reported as confounded.
6. Without a time column, time is the point order (time constants in points), and it says so.

`environment` (the slope that follows the air and material log) is a candidate only when the
table has an air or material column that varies. It and thermal_drift can both explain a
run-to-run slope change: when both are plausible at a step, a note says which one was chosen and
why (the log's fit against the exponential's, and the pivot: air about the laser datum x = 0,
screw growth about its fixed bearing).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from campaign.discovery.data import CampaignData, keep_rows
from campaign.discovery.effects import (
    FORMS,
    LASER_DATUM_MM,
    PERIOD_KEY,
    PERIOD_RANGE_MM,
    SHAPE_KEYS,
    environment_logs,
    even_spacing,
    fixed_shape,
    period_limits,
)
from campaign.discovery.fit import (
    Fit,
    Term,
    bic,
    drop_collinear,
    f_test_p,
    linear_fit,
    refine,
    shape_bounds,
    standard_errors,
)
from campaign.discovery.local import gap_um, point_weights
from campaign.discovery.naming import (
    ALPHA,
    NESTED_IN,
    RIVAL_MARGIN,
    gate_failures,
    how_to_tell_pairs,
    period_spread_mm,
    prefer_simpler,
    try_candidate,
)
from campaign.discovery.records import Aliased, Choice, StandIn, StartingEffect, TableGap, Unresolved
from campaign.discovery.result import STAND_IN_RIVALS, Candidate, Discovery, Step, note_once
from campaign.effects import RegistryView, effect
from campaign.effects.base import stop_waits
from campaign.errors import InputError
from campaign.model import DEFAULTS, EFFECT_PARAMS, ErrorModel

MAX_STEPS = len(FORMS)


DWELL_SPREAD = 0.05
"""Relative spread of the wait since arrival below which settling is not looked for."""


VARIED_WAIT_POINTS = 8
"""Points whose wait departs from the typical one by more than DWELL_SPREAD that it takes to tell
settling (two parameters, one per wait) from a constant reversal: one short capture in a
fixed-dwell campaign does not."""


NEEDS: RegistryView[str] = RegistryView(lambda e: e.needs)
"""Effect -> what a campaign must have for it to be looked for (each effect's `needs`: a varying
wait, a varying air or material log, two runs or more)."""


def start_terms(model: ErrorModel, given: dict[str, set[str]], data: CampaignData,
                notes: list[str]) -> list[Term]:
    """Terms for the starting model: an effect with all parameters given is fixed; otherwise its
    shape parameters given are held and the rest is fitted."""
    terms = []
    for name, params in model.effects.items():
        if name == "noise":
            continue
        keys = given.get(name, set())
        fixed = set(EFFECT_PARAMS[name]) <= keys
        if NEEDS.get(name) == "wait" and data.w is None:
            note_once(notes, f"the model's {name} is left out: without a capture_wait_s column the wait since "
                         "arrival is unknown (the captures are taken as settled)")
            continue
        if name not in FORMS:  # an effect the simulator has and discovery does not (local_defect)
            defaults = DEFAULTS.get(name, {})
            missing = sorted(set(EFFECT_PARAMS[name]) - keys - set(defaults))
            if missing:
                raise InputError(f"the starting model's effects.{name} is not one discovery can fit (it is not in "
                                 f"its vocabulary): give all its parameters to hold it ({', '.join(missing)} missing)")
            terms.append(Term(name, {**defaults, **params}, True, {}))
            continue
        held = {k: v for k, v in params.items() if fixed or k in SHAPE_KEYS}
        shape = {**fixed_shape(name, data, held), **{k: held[k] for k in FORMS[name].shape if k in held}}
        for key in FORMS[name].shape:
            if key not in shape:
                shape[key] = default_shape(name, key, data)
        terms.append(Term(name, held, fixed, shape))
    return terms


def default_shape(name: str, key: str, data: CampaignData) -> float:
    """A starting shape parameter for an effect in the starting model: the middle of its grid."""
    if PERIOD_KEY.get(name) == key:
        return 10.0
    grid = FORMS[name].grid(data, {})
    return grid[len(grid) // 2][key]


def disagreement(data: CampaignData, residual: np.ndarray) -> dict:
    """Where the residual (µm) lives: per target the mean; per direction the mean; per run the mean
    and the slope (µm/m); RMS values µm."""
    targets, where = np.unique(np.round(data.x, 6), return_inverse=True)
    by_target = list(np.bincount(where, residual) / np.bincount(where))
    by_run = {}
    for r in np.unique(data.run):
        pick = data.run == r
        slope = np.polyfit(data.x[pick] * 1e-3, residual[pick], 1)[0] if np.ptp(data.x[pick]) > 0 else 0.0
        by_run[int(r)] = {"mean_um": round(float(residual[pick].mean()), 4), "slope_ppm": round(float(slope), 4)}
    by_dir = {("+" if d > 0 else "-"): round(float(residual[data.d == d].mean()), 4) for d in (1, -1)
              if np.any(data.d == d)}
    out = {"by_position_rms_um": round(float(np.sqrt(np.mean(np.square(by_target)))), 4),
           "by_target_um": dict(zip([f"{t:g}" for t in targets.tolist()], np.round(by_target, 4).tolist())),
           "by_direction_um": by_dir, "by_run": by_run}
    if data.campaigns > 1:
        out["by_campaign_um"] = [round(float(residual[data.campaign_index == c].mean()), 4)
                                 for c in range(data.campaigns)]
    return out


def _repeat_groups(data: CampaignData) -> tuple[np.ndarray, np.ndarray]:
    """Each row's (campaign, target, direction) group, and each group's number of rows."""
    keys = (data.campaign_index * (data.target_index.max() + 1) + data.target_index) * 2 + (data.d > 0)
    _, group = np.unique(keys, return_inverse=True)
    return group, np.bincount(group)


def noise_measured(data: CampaignData) -> bool:
    """Whether the campaign repeats any target in a direction: without, pooled_scatter_um has no
    run-to-run scatter to pool and falls back to the residual itself (the noise is not measured)."""
    return bool(np.any(_repeat_groups(data)[1] > 1))


def pooled_scatter_um(data: CampaignData, residual: np.ndarray) -> float:
    """Run-to-run scatter of the residual, pooled over (campaign, target, direction) groups, µm
    (the residual's RMS when nothing is repeated: noise_measured is then False). Each group weighed
    as the fit weighs its points (gap_um), so that the gap and the noise compare like with like."""
    group, count = _repeat_groups(data)
    w = point_weights(data)
    mean = np.bincount(group, w * residual) / np.bincount(group, w)
    ss = float(np.sum(w * (residual - mean[group]) ** 2))
    dof = float(np.sum((np.bincount(group, w) / count) * (count - 1)))
    return float(np.sqrt(ss / dof)) if dof > 0 else gap_um(data, residual)


def by_table(data: CampaignData, residual: np.ndarray) -> list[TableGap]:
    """Per table fitted together (campaign index order): its gap (RMS of the residual on its points)
    and its run-to-run noise, µm, each as if it were alone (unweighted); empty for one table."""
    if data.campaigns < 2:
        return []
    out = []
    for c in range(data.campaigns):
        keep = data.campaign_index == c
        out.append(TableGap(float(np.sqrt(np.mean(residual[keep] ** 2))),
                            pooled_scatter_um(keep_rows(data, keep), residual[keep])))
    return out


def candidate_names(data: CampaignData, terms: list[Term], notes: list[str],
                    aliased: list[Aliased] | None = None) -> list[str]:
    """Effects not in the model that this data can show; notes say why others are not tried, and
    `aliased` gets the periodic effects the plan's even spacing keeps from being looked for."""
    present = {t.name for t in terms}
    names = [n for n in FORMS if n not in present]
    for name in [n for n in names if NEEDS.get(n) == "wait"]:
        if data.w is None:
            names.remove(name)
            note_once(notes, f"{name} is not looked for: the table has no capture_wait_s column, and at a "
                         f"constant wait {name} looks exactly like backlash")
        elif not waits_vary(data):
            names.remove(name)
            note_once(notes, f"{name} is confounded with backlash: the dwell does not vary, so {name} "
                         "is not looked for (vary the dwell to separate them)")
    low, high = period_limits(data)
    for name in [n for n in names if n in PERIOD_KEY]:
        if low < high:
            if even_spacing(data) is not None and low > PERIOD_RANGE_MM[0]:
                note_once(notes, f"{name} is looked for at periods from {low:.4g} to {high:.4g} {data.position_unit}: "
                             "the targets are evenly spaced, so shorter periods alias onto longer ones")
            continue
        names.remove(name)
        spacing = even_spacing(data)
        if aliased is not None and spacing is not None and all(a.effect != name for a in aliased):
            aliased.append(Aliased(name, spacing, 2 * spacing, data.position_unit))
        note_once(notes, f"{name} is not looked for: the targets are evenly spaced {spacing:.4g} "
                     f"{data.position_unit} apart, so a period shorter than twice that ({2 * (spacing or 0):.4g} "
                     f"{data.position_unit}) aliases into a smooth bow or vanishes, and the screw leads looked for "
                     f"end at {high:.4g} {data.position_unit} (plan with offsets = \"golden\" or \"random\", or "
                     "targets closer together)")
    for name in [n for n in names if NEEDS.get(n) == "log"]:
        if not environment_logs(data):
            names.remove(name)
            note_once(notes, f"{name} is not looked for: the table has no air or material log that varies "
                         "(air_temp_c, air_pressure_hpa, humidity_pct, material_temp_c)")
    for name in [n for n in names if NEEDS.get(n) == "runs"]:
        if len(np.unique(data.run)) < 2:
            names.remove(name)
            note_once(notes, f"{name} is not looked for: one run cannot show a run-to-run change")
    return names


def waits_vary(data: CampaignData) -> bool:
    """Does the wait since arrival before each capture vary enough to tell settling from a
    constant reversal: at least VARIED_WAIT_POINTS points whose wait departs from the median wait by
    DWELL_SPREAD of it or more? False when it is not recorded."""
    waits = stop_waits(data)
    if not len(waits):
        return False
    typical = max(float(np.median(waits)), 1e-9)
    return int(np.sum(np.abs(waits - typical) >= DWELL_SPREAD * typical)) >= VARIED_WAIT_POINTS


def may_soak(name: str) -> bool:
    """Whether a local error may hide behind the named effect `name` (its module's may_soak: a
    period fitted to a bump, a reversal to a bump in one direction): when none is found beside the
    model, it is looked for again without each of them."""
    return effect(name).may_soak


def search_vocabulary(data: CampaignData, model: ErrorModel, given: dict[str, set[str]],
                      extra: list[Term] | None = None, left_out: frozenset[str] = frozenset()) -> Discovery:
    """The search over the vocabulary from the starting model, with `extra` terms (a local error
    found earlier) in the model from the start; the effects `left_out` are not tried."""
    notes: list[str] = []
    if data.time_source != "time_s":
        notes.append("the table has no time column: time effects use the point order (time constants "
                     "are in points, not seconds)")
    start = refine(data, start_terms(model, given, data, notes) + list(extra or []))
    current = start
    steps: list[Step] = []
    choices: list[Choice] = []
    unresolved: list[Unresolved] = []
    ranking: list[Candidate] = []
    remaining: list[Candidate] = []
    remaining_beside = None
    spreads: dict[str, float] = {}
    aliased: list[Aliased] = []
    for _ in range(MAX_STEPS):
        ranking = [try_candidate(data, current, name, notes)
                   for name in candidate_names(data, current.terms, notes, aliased) if name not in left_out]
        ranking.sort(key=lambda c: (c.fit is None, c.delta_bic))
        chosen, unresolved = choose(data, current, ranking, notes)
        held = [c for c in ranking if c.verdict.startswith(UNRESOLVED_VERDICTS)]
        remaining_beside = None
        tested_beside: Fit | None = None
        if chosen is None and held:
            # something is there that cannot be named (rivals, or a period not known): test the
            # others beside the best of it as a stand-in, so that its residual does not hide them
            stand_in = min(held, key=lambda c: c.delta_bic)
            # its own group stays out; another unresolved group is tried again beside it (a drift
            # seen beside an aliased period may tell its shape once the period's residual is held)
            own = stand_in_group(stand_in, held, unresolved)
            others = [try_candidate(data, stand_in.fitted, name, notes)
                      for name in candidate_names(data, stand_in.fitted.terms, notes, aliased)
                      if name not in own and name not in left_out]
            held = [c for c in held if c.name in own]
            others.sort(key=lambda c: (c.fit is None, c.delta_bic))
            chosen, more = choose(data, stand_in.fitted, others, notes)
            unresolved = [u for u in unresolved if set(u.effects) & own] + more
            ranking = [*held, *others]
            if chosen is not None:
                note_once(notes, f"{chosen.name} was tested beside the unresolved {stand_in.name} (as a stand-in, "
                             "not named), whose residual would otherwise hide it")
                tested_beside = refine(data, chosen.fitted.terms)  # its values as tested: the step says these
                # the search goes on from the named model
                chosen.fit = refine(data, [t for t in chosen.fitted.terms if t.name != stand_in.name])
            else:
                remaining_beside = stand_in.name
        for cand in ranking:
            if cand.accepted and cand is not chosen:
                cand.verdict = "significant, but not named at this step: tried again at the next"
        if chosen is None:
            remaining = ranking
            if ranking:
                steps_ranking_note(notes, ranking, remaining_beside)
            break
        choice = air_or_screw(data, ranking, chosen, len(steps) + 1)
        if choice:
            choices.append(choice)
            note_once(notes, choice.why)
        after = refine(data, chosen.fitted.terms)
        if chosen.periods:
            spreads[chosen.name] = period_spread_mm(chosen.periods)
        # named beside a stand-in, its values and errors are those it was tested with: without the stand-in
        # the reversal's residual swells them (18.8 ± 14 µm/m per h said for a drift named at 35.8 ± 2.8)
        said = tested_beside if tested_beside is not None else after
        errors = standard_errors(data, said).get(chosen.name, {})
        add_period_spread(errors, chosen.name, spreads)
        steps.append(Step(chosen.name, said.params()[chosen.name], gap_um(data, data.y - current.prediction),
                          gap_um(data, data.y - after.prediction),
                          ranking, data.y - current.prediction, data.y - after.prediction, errors))
        current = after
    kept: StandIn | None = None
    group = next((u for u in unresolved if "backlash" in u.effects and set(u.effects) <= STAND_IN_RIVALS),
                 None)
    backlash = next((c for c in remaining if c.name == "backlash" and c.fit is not None), None)
    if remaining_beside is not None and group is not None and backlash is not None and not waits_vary(data):
        # only at a constant wait do backlash and settling predict the same deviation wherever the
        # axis is used at that wait; where the waits vary they differ, and neither stands in
        without = gap_um(data, data.y - current.prediction)
        # backlash was fitted beside the stand-in; a stand-in that is not a reversal (a drift not pinned down,
        # a period) stays unresolved, out of the model, held later without a name (hold_unresolved)
        current = refine(data, [t for t in backlash.fitted.terms
                                if t.name == "backlash" or t.name != remaining_beside])
        b_um = current.params()["backlash"]["b_um"]  # in the deviation unit (µm, arcsec)
        dev = data.deviation_unit
        kept = StandIn("backlash", group.effects,
                       f"a reversal of {abs(b_um):.1f} {dev} between the directions (x̄↑ − x̄↓ = "
                       f"{-b_um:+.1f} {dev}): backlash, or settling not died out; cannot tell which",
                       current.params()["backlash"], without)
    beside: list[Term] = []
    if kept is None and remaining_beside in STAND_IN_RIVALS:  # held in the route chosen (hold_unresolved)
        stand_in_fit = next(c.fitted for c in remaining if c.name == remaining_beside)
        beside = [t for t in stand_in_fit.terms if t.name == remaining_beside]
    current = drop_failing(data, current, steps, notes, beside)
    all_errors = standard_errors(data, current)
    for name in all_errors:
        add_period_spread(all_errors[name], name, spreads)
    add_confounding_notes(data, current, notes)
    residual = data.y - current.prediction
    return Discovery(steps, start, current, gap_um(data, data.y - start.prediction), gap_um(data, residual),
                     pooled_scatter_um(data, residual), data.time_source, notes,
                     disagreement(data, data.y - start.prediction), disagreement(data, residual), choices,
                     unresolved, errors=all_errors, remaining=remaining, remaining_beside=remaining_beside,
                     stand_in=kept, starting=starting_report(data, start, current, all_errors, given),
                     aliased=aliased)


def stand_in_group(stand_in: Candidate, held: list[Candidate], unresolved: list[Unresolved]) -> set[str]:
    """The names of the stand-in's own unresolved group: its rivals (verdicts naming it), the effect it
    is held with (a position-dependent backlash held with an unresolved backlash) and the rest of every
    unresolved group they are in. Kept out of the others' search beside it, and kept unresolved: a
    stand-in held with backlash left backlash to be tried beside it, where it is confounded, and the
    reversal's group (backlash or settling) was lost with the 4 µm reversal it held (a user's trial: a
    thermal drift beside a 4 µm backlash, two seeds of six)."""
    own = {stand_in.name}
    while True:
        grown = set(own)
        for c in held:
            said = c.verdict.split("from ", 1)[-1]
            if c.name in own and c.verdict.startswith("held with "):
                grown.add(c.verdict.removeprefix("held with ").split(",", 1)[0])
            if any(name in said.replace(",", " ").split() for name in own) or any(
                    c.verdict == f"held with {name}, which is unresolved" for name in own):
                grown.add(c.name)
        for u in unresolved:
            if set(u.effects) & grown:
                grown |= set(u.effects)
        if grown == own:
            return own
        own = grown


def drop_failing(data: CampaignData, fit: Fit, steps: list[Step], notes: list[str],
                 beside: list[Term] | None = None) -> Fit:
    """The final model without any named effect that, beside what was named after it (and the
    `beside` terms: an unresolved reversal's stand-in, whose residual would otherwise swell its errors),
    no longer passes the naming gates (gate_failures): its step is removed from `steps` and a note says
    why."""
    def failing_step() -> tuple[Step, list[str]] | None:
        gated = linear_fit(data, [*fit.terms, *beside]) if beside else fit
        return next(((s, why) for s in steps if s.effect != "local_error"
                     and (why := gate_failures(data, gated, s.effect))), None)

    while failing := failing_step():
        step, why = failing
        steps.remove(step)
        fit = refine(data, [t for t in fit.terms if t.name != step.effect])
        note_once(notes, f"{step.effect} is not named: beside the other effects of the final model it fails the "
                     f"naming gates ({'; '.join(why)})")
    return fit


def add_period_spread(errors: dict[str, float], name: str, spreads: dict[str, float]) -> None:
    """A named period's error includes the spread over its competing optima (period_spread_mm)."""
    key = PERIOD_KEY.get(name)
    if name in spreads and key in errors:
        errors[key] = math.hypot(errors[key], spreads[name])


SIGNIFICANT = 0.05
"""An effect of the starting model whose F-test against leaving it out gives p at or above this is
said not to differ significantly from zero (a test of a given effect, not a search: no
look-elsewhere factor, the usual 5 %)."""


def starting_report(data: CampaignData, start: Fit, final: Fit, errors: dict[str, dict[str, float]],
                    given: dict[str, set[str]]) -> dict[str, StartingEffect]:
    """The starting model's effects as fitted at the end (beside the named effects): their
    parameters and errors, the parameters the model gave, and whether each fitted effect differs
    from zero (nested F-test of the final fit against it left out)."""
    n, out = len(data), {}
    params = final.params()
    for term in start.terms:
        if term.name not in EFFECT_PARAMS:
            continue  # a local error found earlier: reported on its own
        entry = StartingEffect(tuple(sorted(given.get(term.name, set()) & set(EFFECT_PARAMS.get(term.name, {})))),
                               term.fixed, params.get(term.name, dict(term.held)))
        if not term.fixed:
            reduced = linear_fit(data, [t for t in final.terms if t.name != term.name])
            p_value = f_test_p(reduced, final, n)
            entry = replace(entry, errors=errors.get(term.name, {}), p_value=p_value,
                            significant=p_value < SIGNIFICANT)
        out[term.name] = entry
    return out


DWELLS_HOW_TO_TELL = effect("settling").rivals["backlash"]


HOW_TO_TELL_DEFAULT = ("a campaign that varies what separates them: more runs over a longer time for time "
                       "effects, more targets for effects along the travel, varied dwells for settling")


PERIOD_HOW_TO_TELL = ("more targets (at least 4 per screw lead over part of the travel), a denser offset pattern "
                      "(offsets = \"golden\" with a larger offset_fraction), or the known screw lead in the model "
                      "(periodic_lead.period_mm): with the period given, only the amplitude is fitted")


DRIFT_HOW_TO_TELL = ("more runs over a longer time, at targets over the whole travel: how fast the slope changes "
                     "and where it pivots show in how the runs part")


UNRESOLVED_VERDICTS = ("not told apart", "held with", "period not identifiable", "not pinned down")
"""Verdicts of candidates that are neither named nor rejected: the data cannot resolve them."""


CONFOUNDED_PAIRS = {frozenset({"environment", "thermal_drift"}), frozenset({"environment", "linear_drift"})}
"""Pairs with their own way of choosing (air_or_screw), not treated as rivals."""


def choose(data: CampaignData, current: Fit, ranking: list[Candidate],
           notes: list[str]) -> tuple[Candidate | None, list[Unresolved]]:
    """The candidate to name at this step, and what cannot be resolved: a periodic error whose
    period is not identifiable, groups of candidates that explain the same residual about equally
    well (rivals), and, when nothing is named, a drift in time that passes the tests but that the
    campaign does not pin down (undetermined_drifts). None of these is named; the other candidates go
    on."""
    n = len(data.y)
    unresolved = [period_entry(c, data) for c in ranking if c.verdict == "period not identifiable"]
    held: list[Candidate] = []
    in_model = {t.name for t in current.terms}
    while pool := [c for c in ranking if c.accepted and c not in held]:
        best = prefer_simpler(pool[0], pool, n, notes)
        if best.name == "backlash" and "settling" not in in_model and not waits_vary(data):
            held += hold_reversal(best, ranking, data, n, unresolved)
            continue
        rivals = [c for c in ranking if c is not best and c.fit is not None and c not in held
                  and not gated_out(c, best) and are_rivals(data, best, c, n)]
        if not rivals:
            return best, unresolved
        group = [best, *rivals]
        unresolved.append(rival_entry(best, rivals))
        for cand in group:
            cand.verdict = "not told apart from " + ", ".join(c.name for c in group if c is not cand)
        names = {c.name for c in group}
        for cand in ranking:  # the larger form of an unresolved effect is held with it
            if NESTED_IN.get(cand.name) in names and cand not in group:
                cand.verdict = f"held with {NESTED_IN[cand.name]}, which is unresolved"
                group.append(cand)
        held += group
    if drifts := undetermined_drifts(ranking, unresolved, current):
        unresolved.append(drift_entry(drifts, data.deviation_unit))
    return None, unresolved


def undetermined_drifts(ranking: list[Candidate], unresolved: list[Unresolved], current: Fit) -> list[Candidate]:
    """The drifts in time (effects that need runs: a linear or exponential growth) that pass the three
    tests but not the gates (a size under 2σ, a parameter outside its physical range), and are in no
    unresolved group: the campaign shows a drift it cannot pin down (a 23 ppm/h growth pivoting at 597 mm,
    11 uniform targets, noise 0.66 µm: F-test p 4e-5 and a better CV, but a rate of 2.2 ± 7.4 ppm/h
    pivoting at 3,312 mm, bench seed 97, draw 16276). None when a drift is in `current` already: the
    drift is said, and what another shape of it adds beside it is not a drift of its own (its columns
    all but the named one's: a growth of 1,210 ± 1,700 µm/m beside a named linear drift)."""
    if any(NEEDS.get(t.name) == "runs" for t in current.terms):
        return []
    grouped = {name for u in unresolved for name in u.effects}
    return [c for c in ranking if c.fit is not None and NEEDS.get(c.name) == "runs" and c.name not in grouped
            and c.verdict.startswith("not named (")]  # a drift's only verdict that follows passed tests


def drift_entry(drifts: list[Candidate], unit: str) -> Unresolved:
    """The `unresolved` record of drifts in time that the campaign shows and does not pin down
    (undetermined_drifts): what each explains, its tests, and which of its values are not determined
    (`unit`: the deviation's). Each gets the verdict "not pinned down", with the others' names, so that
    they are held together (search_vocabulary's stand-in)."""
    names = [c.name for c in drifts]
    said = "; ".join(f"{c.name} explains {c.explained_pct:.1f} % (F-test p = {c.p_value:.2g}, cross-validated "
                     f"{c.cv_before_um:.3g} -> {c.cv_after_um:.3g} {unit}) but {c.verdict.removeprefix('not named (')[:-1]}"
                     for c in drifts)
    for cand in drifts:
        others = [name for name in names if name != cand.name]
        cand.verdict = "not pinned down" + (f", like {said_list(others)}" if others else "")
    return Unresolved(tuple(names), f"a drift in time is there, but this campaign does not pin it down ({said}): "
                                    "not named", DRIFT_HOW_TO_TELL, {c.name: round(c.delta_bic, 2) for c in drifts},
                      not_pinned_down=True)


LIMIT_OF: RegistryView[str] = RegistryView(lambda e: e.tends_to)
"""Effect -> the effect that is its limit (an exponential growth whose time constant is far beyond
the campaign is a linear drift): each effect's `tends_to`."""


def gated_out(cand: Candidate, best: Candidate) -> bool:
    """Is `cand`, which fits, no rival of `best` because it fails the naming gates: a parameter
    outside its physical range, or only its size under 2σ where `best` is its limit (a thermal
    growth whose time constant the campaign cannot tell is the linear drift)? A rival whose size is
    merely uncertain (settling beside backlash at waits that vary a little) stays a rival."""
    if not cand.verdict.startswith("not named"):
        return False
    return "not physical" in cand.verdict or LIMIT_OF.get(cand.name) == best.name


def hold_reversal(backlash: Candidate, ranking: list[Candidate], data: CampaignData, n: int,
                  unresolved: list[Unresolved]) -> list[Candidate]:
    """At a constant (or unrecorded) wait before each capture, settling leaves a constant offset per
    direction: exactly a backlash. The reversal is listed as unresolved, not named; so is a
    position-dependent backlash whose growth is not significant (it is the same reversal). A
    significant growth along the travel is no settling and stays a candidate."""
    b = backlash.fitted.params()["backlash"].get("b_um")
    size = f"a reversal of {b:+.3g} µm" if b is not None else "a reversal"
    wait = ("no wait before capture is recorded" if not len(stop_waits(data)) else
            f"the wait before every capture is about {float(np.mean(stop_waits(data))):.2g} s")
    unresolved.append(Unresolved(
        ("backlash", "settling"),
        f"{size} between the directions (backlash explains {backlash.explained_pct:.1f} %, ΔBIC "
        f"{backlash.delta_bic:.1f}), but {wait}: settling that has not died out leaves the same constant "
        "offset per direction, so this campaign cannot tell backlash from settling and names neither",
        DWELLS_HOW_TO_TELL, {"backlash": round(backlash.delta_bic, 2)}))
    backlash.verdict = "not told apart from settling (the wait before capture does not vary)"
    held = [backlash]
    for cand in ranking:
        if NESTED_IN.get(cand.name) == "backlash" and cand.accepted and f_test_p(backlash.fitted, cand.fitted, n) >= ALPHA:
            cand.verdict = "held with backlash, which is unresolved"
            held.append(cand)
    return held


WAITS_DECADE = 5.0
"""Longest over shortest wait before capture from which a campaign is said to vary the wait enough
to see a settling within its search (settling's τ up to 6 × the longest wait) fade."""


def settling_is_constant(data: CampaignData, settling: Candidate) -> bool:
    """Is the settling candidate a constant per direction over the waits measured? Its time
    constant at the top of its search (within 10 %), with waits varying by WAITS_DECADE or more:
    it then does not fade over the waits, and a settling that slow is a reversal (backlash) for
    every use of the axis at those waits."""
    waits = stop_waits(data)
    if not len(waits) or float(np.min(waits)) <= 0 or float(np.max(waits)) / float(np.min(waits)) < WAITS_DECADE:
        return False
    tau = settling.fitted.params()["settling"]["tau_s"]
    return bool(tau >= 0.9 * shape_bounds(data, "settling", "tau_s")[1])


def are_rivals(data: CampaignData, best: Candidate, other: Candidate, n: int) -> bool:
    """Do `best` and `other` explain the same residual about equally well? Within RIVAL_MARGIN in
    ΔBIC (which weighs what each explains against its parameters, a searched period included),
    and together clearly no better than `best` alone. Nested effects and the air/screw pair have their own rules."""
    pair = frozenset({best.name, other.name})
    if (NESTED_IN.get(best.name) == other.name or NESTED_IN.get(other.name) == best.name
            or pair in CONFOUNDED_PAIRS or other.verdict == "period not identifiable" or other.delta_bic >= 0):
        return False
    if other.delta_bic - best.delta_bic >= RIVAL_MARGIN:
        return False
    if "settling" in pair and pair & {"backlash", "position_dependent_backlash"}:
        settling = best if best.name == "settling" else other
        if settling_is_constant(data, settling):
            return False
    term = next(t for t in other.fitted.terms if t.name == other.name)
    term = drop_collinear(data, best.fitted.terms, replace(term, keep=None))
    if not any(term.keep or ()):
        return True
    joint = linear_fit(data, [*best.fitted.terms, term])
    return bic(joint, n) > bic(best.fitted, n) - RIVAL_MARGIN


def how_to_tell(names: list[str]) -> str:
    """What campaign separates a group of effects: the texts of its pairs (each once), and the
    general advice when a pair has none."""
    texts, unknown = [], False
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            text = how_to_tell_pairs().get(frozenset({a, b}))
            unknown |= text is None
            if text is not None and text not in texts:
                texts.append(text)
    if unknown or not texts:
        texts.append(HOW_TO_TELL_DEFAULT)
    return "; ".join(texts)


def said_list(names: list[str]) -> str:
    """'a and b', 'a, b and c'."""
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def rival_entry(best: Candidate, rivals: list[Candidate]) -> Unresolved:
    """The `unresolved` record of candidates that explain the same residual."""
    group = [best, *rivals]
    said = "; ".join(f"{c.name} explains {c.explained_pct:.1f} % (ΔBIC {c.delta_bic:.1f})" for c in group)
    names = [c.name for c in group]
    none = "neither is named" if len(names) == 2 else "none of them is named"
    return Unresolved(tuple(names),
                      f"{said_list(names)} explain the same part of the residual about equally well ({said}), "
                      f"and together no better than one alone: this campaign cannot tell which it is, so {none}",
                      how_to_tell(names), {c.name: round(c.delta_bic, 2) for c in group})


def period_entry(cand: Candidate, data: CampaignData) -> Unresolved:
    """The `unresolved` record of a periodic error whose period is not identifiable."""
    shown = ", ".join(f"{p:.4g} mm (ΔBIC {d:+.1f})" for p, d in cand.periods[:6])
    if len(cand.periods) > 6:
        shown += f" and {len(cand.periods) - 6} more"
    targets = len(np.unique(np.round(data.x, 6)))
    return Unresolved((cand.name,),
                      f"a periodic error explains {cand.explained_pct:.1f} % of the residual, but its period is not "
                      f"identifiable: {len(cand.periods)} periods fit about as well ({shown}); with {targets} targets "
                      "a screw lead aliases to other periods",
                      PERIOD_HOW_TO_TELL, periods_mm=tuple(round(p, 4) for p, _ in cand.periods),
                      period_delta_bic=tuple(round(d, 2) for _, d in cand.periods))


PLAUSIBLE_SHARE = 0.5
"""A confounded rival is "plausible" when it is significant itself or explains at least this share
of what the chosen candidate explains."""


def air_or_screw(data: CampaignData, ranking: list[Candidate], chosen: Candidate, step: int) -> Choice | None:
    """When environment and thermal_drift both explain the run-to-run slope change at this step,
    which one is chosen and why: the fit of the log against the exponential in time (ΔBIC), and
    the pivot of the slope change (air index: the laser datum; screw growth: its fixed bearing)."""
    if chosen.name not in ("environment", "thermal_drift"):
        return None
    other_name = "thermal_drift" if chosen.name == "environment" else "environment"
    other = next((c for c in ranking if c.name == other_name and c.fit is not None), None)
    if other is None or not (other.accepted or other.verdict.startswith(("significant", "not named"))
                             or other.explained_pct >= PLAUSIBLE_SHARE * chosen.explained_pct):
        return None
    env, thermal = (chosen, other) if chosen.name == "environment" else (other, chosen)
    pivot = thermal.fitted.params()["thermal_drift"]["pivot_mm"]
    travel = float(np.ptp(data.x)) or 1.0
    at_datum = abs(pivot - LASER_DATUM_MM) < 0.15 * travel
    logs = " and ".join(sorted({"air_factor": "air", "alpha_ppm_per_k": "material"}[k]
                               for k in env.fitted.params()["environment"]))
    margin = abs(env.delta_bic - thermal.delta_bic)
    if chosen.name == "environment":
        better = "more than" if env.explained_pct >= thermal.explained_pct else "as much as, with fewer parameters,"
        fit_why = (f"the {logs} log explains {better} an exponential in time "
                   f"(environment explains {env.explained_pct:.1f} %, ΔBIC {env.delta_bic:.1f}; thermal_drift "
                   f"{thermal.explained_pct:.1f} %, ΔBIC {thermal.delta_bic:.1f})")
        pivot_why = (f"thermal_drift's best pivot, {pivot:.0f} mm, is at the laser datum (x = {LASER_DATUM_MM:g}), "
                     "where a refractive-index change pivots" if at_datum else
                     f"but thermal_drift's best pivot, {pivot:.0f} mm, is away from the laser datum: part of the "
                     "change may be screw growth, which thermal_drift is tried for again at the next step")
    else:
        fit_why = (f"an exponential in time explains the slope change better than the {logs} log does "
                   f"(thermal_drift explains {thermal.explained_pct:.1f} %, ΔBIC {thermal.delta_bic:.1f}; "
                   f"environment {env.explained_pct:.1f} %, ΔBIC {env.delta_bic:.1f})")
        pivot_why = (f"the slope change pivots at {pivot:.0f} mm, away from the laser datum "
                     f"(x = {LASER_DATUM_MM:g}) where an air refractive-index change would pivot: screw growth "
                     "about its fixed bearing" if not at_datum else
                     f"but it pivots at {pivot:.0f} mm, at the laser datum, as an air index change would: "
                     "check the air log and the laser's air compensation")
    gated = f"; {other.name} is {other.verdict}" if other.verdict.startswith("not named") else ""
    why = (f"environment and thermal_drift both explain the run-to-run slope change (step {step}); "
           f"chose {chosen.name}: {fit_why}, by {margin:.1f} in BIC; {pivot_why}{gated}")
    return Choice(step, chosen.name, other.name, round(pivot, 1), bool(at_datum), round(env.explained_pct, 2),
                  round(thermal.explained_pct, 2), round(env.delta_bic, 2), round(thermal.delta_bic, 2), why)


def steps_ranking_note(notes: list[str], ranking: list[Candidate], beside: str | None) -> None:
    """Why nothing more is named: no remaining candidate passes the three tests; the share of the one
    that explains most, as in the printed ranking of the remaining candidates."""
    rest = [c for c in ranking if c.fit is not None and not c.verdict.startswith(UNRESOLVED_VERDICTS)]
    if not rest:
        return
    most = max(rest, key=lambda c: c.explained_pct)
    where = f" (tried beside the unresolved {beside} as a stand-in)" if beside else ""
    fails = most.verdict.split("(")[-1].rstrip(")")
    if most.explained_pct < 1.0:
        note_once(notes, f"nothing more is named: no other candidate{where} explains more than "
                     f"{most.explained_pct:.1f} % of the residual")
    else:
        note_once(notes, f"nothing more is named: no other candidate{where} passes the three tests; the one that "
                     f"explains most, {most.name} ({most.explained_pct:.1f} % of the residual), fails {fails}")


def add_confounding_notes(data: CampaignData, fit: Fit, notes: list[str]) -> None:
    """Say which named effects cannot be told from others on this data."""
    params = fit.params()
    logs = environment_logs(data)
    if "linear_scale" in params:
        note_once(notes, "linear_scale also holds any cosine error (always negative, < 1 µm/m) and a constant "
                     "air refractive-index or material-expansion error (only their changes follow the log): "
                     "they are confounded with it")
    if "environment" in params:
        env = params["environment"]
        if "air_factor" in env:
            note_once(notes, f"environment: the reading follows {env['air_factor']:.2f} × the air log's refractive-index "
                         "change (1: the instrument does not compensate the air; 0: it does)")
        if "alpha_ppm_per_k" in env:
            note_once(notes, f"environment: the reading follows the material temperature with "
                         f"{env['alpha_ppm_per_k']:.2f} µm/m per K (steel 11.5: the table is not normalised to 20 °C)")
    if "thermal_drift" in params:
        pivot = params["thermal_drift"]["pivot_mm"]
        datum = LASER_DATUM_MM
        travel = float(np.ptp(data.x)) or 1.0
        near = abs(pivot - datum) < 0.15 * travel
        if near and "air" not in logs:
            note_once(notes, f"thermal_drift pivots at {pivot:.0f} mm, near the laser datum (x = {datum:g}): screw "
                         "growth is confounded with a drift of the air's refractive index here (no air log)")
        elif abs(pivot - datum) > 2 * travel:
            note_once(notes, f"thermal_drift pivots at {pivot:.0f} mm, far outside the travel: mostly a drift of "
                         "the datum over time (e.g. the laser, its mount or the air warming), not screw growth")
        elif not near:
            note_once(notes, f"thermal_drift pivots at {pivot:.0f} mm, away from the laser datum (x = {datum:g}): "
                         "screw growth about a fixed bearing, not air refractive index (which pivots at the datum)")
        if "air" in logs and "environment" not in params:
            note_once(notes, "the air log varies, but its refractive-index change does not explain the slope change "
                         "(environment is not significant beside thermal_drift): the instrument compensates "
                         "the air, and the change is the machine's")

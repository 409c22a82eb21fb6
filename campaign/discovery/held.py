"""What an unresolved group shows, held in the final model without a name (hold_unresolved: the form of
its rival that explains most, under HELD_PREFIX, so that the gap shrinks while which of them it is
stays unresolved), what the held term shows in words (held_said), the other effects' parameters
averaged over an unresolved period's candidates (beside_unresolved_period), and the result's gaps,
noise and disagreement brought up to date after its final fit changes (after_final).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from campaign.discovery.data import CampaignData
from campaign.discovery.effects import FORMS, HELD_PREFIX, PERIOD_KEY, SIZE_SIGMAS, period_key
from campaign.discovery.fit import (
    Fit,
    Term,
    derived,
    drop_collinear,
    full_columns,
    linear_fit,
    standard_errors,
)
from campaign.discovery.local import LocalError, gap_um
from campaign.discovery.naming import naming_tests, search_factor
from campaign.discovery.records import Held, Unresolved
from campaign.discovery.result import STAND_IN_RIVALS, Candidate, Discovery, note_once, period_candidate
from campaign.discovery.vocabulary import disagreement, pooled_scatter_um, said_list
from campaign.model import EFFECT_PARAMS


def places(found: list[LocalError]) -> int:
    """In how many places along the axis the local errors lie: those whose regions overlap are one place
    (a departure at one target and at it and its neighbour together describe one error)."""
    count, reach = 0, -math.inf
    for low, high in sorted(e.region_mm for e in found):
        count += low > reach
        reach = max(reach, high) if low <= reach else high
    return count


def model_prediction(data: CampaignData, fit: Fit) -> np.ndarray:
    """The prediction of `fit` refitted without the terms that hold an unresolved group (HELD_PREFIX):
    what the model explains. What they hold is not explained, so the locator still reports it as left
    by the final model (located_after), though the gap after is the one with them. (Refitted, not
    subtracted: a held period near the target spacing is almost a constant, its coefficient large
    and cancelled by the offset.)"""
    model = [t for t in fit.terms if not t.name.startswith(HELD_PREFIX)]
    return fit.prediction if len(model) == len(fit.terms) else linear_fit(data, model).prediction


def hold_unresolved(data: CampaignData, result: Discovery, periods: bool) -> Discovery:
    """What an unresolved group of rivals shows is still held in the model, so that the gap shrinks by
    it: the form of the rival that explains most (lowest ΔBIC), refitted beside the final model under
    the name HELD_PREFIX + its name, kept when it passes the tests an effect passes before it is named
    (naming_tests: with a searched period's look-elsewhere factor, cross-validated by its form's group).
    The group stays in
    `unresolved` with how to tell; nothing is named (`added`), saved (final_model) or listed in
    params(): it is said in `held`. A group already held by the constant-wait stand-in is left as it is.
    `periods`: only a period that is not identifiable (held by its best candidate, which agrees with the
    others at the targets, though not between them: done last, once the other effects are averaged over
    its candidates and the local terms are tested beside it), else only the other groups (after the
    local terms too: held before they were first looked for, a reversal took the place of a local error
    seen in one direction, which was then not located; they are looked for beside it only when none is
    found without it, held_fit)."""
    for entry in result.unresolved:
        if ((entry.periods_mm is not None) != periods
                or (result.stand_in is not None and set(entry.effects) <= set(result.stand_in.rivals))
                or any(set(h.rivals) == set(entry.effects) for h in result.held)):  # held already
            continue
        group = [c for c in result.remaining if c.name in entry.effects and c.fit is not None]
        if not group:
            continue
        best = min(group, key=lambda c: c.delta_bic)
        own = next(t for t in best.fitted.terms if t.name == best.name)
        term = drop_collinear(data, result.final.terms, replace(own, name=HELD_PREFIX + best.name, keep=None))
        if not any(term.keep or ()):
            continue
        trial = linear_fit(data, [*result.final.terms, term])
        if naming_tests(data, result.final, trial, best.name, search_factor(data, best.name)).failed:
            continue
        without = result.gap_after_um
        result.final = trial
        after_final(data, result)
        result.held.append(Held(best.name, tuple(entry.effects),
                                held_said(data, trial, term.name, entry.effects, not_pinned_down=entry.not_pinned_down),
                                trial.params()[term.name], without))
        gap = f"gap {without:.3f} -> {result.gap_after_um:.3f} {data.deviation_unit}"
        note_once(result.notes, f"what {said_list(list(entry.effects))} explain alike is held in the model by "
                                f"{best.name}'s form ({gap}), not named: which of them it is stays unresolved"
                  if not entry.not_pinned_down else
                  f"the drift in time {said_list(list(entry.effects))} explain{'s' if len(entry.effects) == 1 else ''} "
                  f"is held in the model by {best.name}'s form ({gap}), not named: its values are not pinned down")
    return result


def held_fit(data: CampaignData, vocabulary: Discovery, periods: bool = False) -> Fit | None:
    """The vocabulary's final fit with what its unresolved groups (not a period) show held as
    hold_unresolved holds it (a reversal backlash and settling explain alike), `vocabulary` left as it
    is; None when nothing is held. Local errors are looked for beside it when none is found beside the
    vocabulary alone: a reversal left in the residual hides a step or a bump both directions share."""
    trial = replace(vocabulary, held=list(vocabulary.held), notes=[], unresolved=list(vocabulary.unresolved))
    trial = hold_unresolved(data, trial, periods=False)
    if periods:  # and an unresolved period, by its best candidate (as the route chosen will hold it, last)
        trial = hold_unresolved(data, trial, periods=True)
    return trial.final if len(trial.held) > len(vocabulary.held) else None


def held_said(data: CampaignData, fit: Fit, name: str, rivals: tuple[str, ...], places: str = "",
              not_pinned_down: bool = False) -> str:
    """What the term `name` of `fit`, holding an unresolved group, shows in words: a reversal between
    the directions (its mean going up less its mean going down) when the group is backlash against
    settling, a drift in time when the group is one the campaign does not pin down (`not_pinned_down`),
    else the rival's form that holds it (with local errors at `places` among the rivals when given)."""
    said = said_list(list(rivals)) + (f" or local errors at {places}" if places else "")
    if set(rivals) <= STAND_IN_RIVALS and not places:
        i = next(k for k, t in enumerate(fit.terms) if t.name == name)
        held = full_columns(data, fit.terms[i]) @ fit.coefs[i]
        up, down = float(np.mean(held[data.d > 0])), float(np.mean(held[data.d < 0]))
        dev = data.deviation_unit
        return (f"a reversal of {abs(up - down):.2g} {dev} between the directions (x̄↑ − x̄↓ = {up - down:+.2g} "
                f"{dev}): {said.replace(' and ', ' or ')}; cannot tell which")
    key = period_key(name)
    if not places and (entry_periods := [t.shape[key] for t in fit.terms if t.name == name and key in t.shape]):
        return (f"a wave seen at the targets (held by its best candidate period, {entry_periods[0]:.4g} "
                f"{data.position_unit}): which period it is stays unresolved")
    if not_pinned_down:  # a drift the campaign shows and does not pin down (Unresolved.not_pinned_down)
        return (f"a drift in time ({said.replace(' and ', ' or ')}), held by {name.removeprefix(HELD_PREFIX)}'s "
                "form: its values are not pinned down")
    return f"what {said} explain alike, held by {name.removeprefix(HELD_PREFIX)}'s form; cannot tell which"


def after_final(data: CampaignData, result: Discovery) -> None:
    """What follows from `result.final` once it changes: the gap and noise after (weighted as the fit
    is), the disagreement, the named effects' errors (the local terms' own, local_..., left out:
    they are said with each local error; so are a held unresolved group's, HELD_PREFIX)."""
    final = result.final
    result.gap_after_um = gap_um(data, data.y - final.prediction)
    result.noise_um = pooled_scatter_um(data, data.y - final.prediction)
    result.disagreement_after = disagreement(data, data.y - final.prediction)
    result.errors = {k: v for k, v in standard_errors(data, final).items()
                     if not k.startswith(("local_", HELD_PREFIX))}


def with_local_terms(data: CampaignData, again: Discovery, vocabulary: Discovery, final: Fit,
                     found: list[LocalError]) -> Discovery:
    """`again` (a search beside local terms) finished as a route's result: its final fit with the
    local errors `found`, the starting point and gap before of the vocabulary alone, the gap and
    noise after, and the named effects' errors (the local terms' own, local_..., left out: they are
    said with each local error)."""
    again.final, again.local_errors = final, found
    again.start, again.gap_before_um = vocabulary.start, vocabulary.gap_before_um
    again.disagreement_before = vocabulary.disagreement_before
    after_final(data, again)
    return again


def beside_unresolved_period(data: CampaignData, result: Discovery) -> Discovery:
    """When a periodic error is there but its period is not identifiable, the other effects are
    fitted beside each candidate period and averaged with the candidates' weights exp(-ΔBIC/2)
    (no period at all among them, with its own ΔBIC); their errors include the spread over the
    candidates. Left out, the wave's values at the targets go into the bow: on 11 targets with a
    1 µm, 10 mm lead its P3 came out about 0.3 µm low on every seed. The aliases agree at the
    targets, so the bow beside any of them is much the same. The gap stays that of the model
    without a period (nothing is added for it). A named effect whose averaged size is then under
    SIZE_SIGMAS of its error (the candidates disagree on it) is not named after all: the size gate
    holds for the values and errors reported."""
    entry = next((u for u in result.unresolved if u.periods_mm), None)
    cand = period_candidate(result.remaining)
    if entry is None or cand is None:
        return result
    while True:
        averages = _averaged_over_periods(data, result, entry, cand)
        failing = {name: small for name, (values, errors) in averages.items() if name in result.added
                   and (small := [f"{k} {values[k]:.3g} ± {errors[k]:.2g}" for k in FORMS[name].sizes
                                  if k in values and k in errors and abs(values[k]) < SIZE_SIGMAS * errors[k]])}
        if not failing:
            break
        for name, small in failing.items():
            result.steps[:] = [step for step in result.steps if step.effect != name]
            note_once(result.notes, f"{name} is not named: beside the candidate periods of the unresolved periodic "
                                f"error its size is under {SIZE_SIGMAS:g}σ ({', '.join(small)}; the error includes "
                                "the spread over the candidates)")
        result.final = linear_fit(data, [t for t in result.final.terms if t.name not in failing])
        after_final(data, result)
    for name, (values, errors) in averages.items():
        params = {k: v for k, v in values.items() if k in result.final.params()[name]}
        result.averaged[name] = params
        result.errors[name] = errors
        result.steps[:] = [replace(step, params=dict(params), errors=dict(errors)) if step.effect == name
                           else step for step in result.steps]
        if name in result.starting:
            result.starting[name] = replace(result.starting[name], params=params, errors=errors)
    note_once(result.notes, f"the named effects' values are fitted beside each of the {len(entry.periods_mm or ())} "
                        "candidate periods of the unresolved periodic error and averaged (weights exp(-ΔBIC/2)), their "
                        "errors include the spread over them: left out, the wave's values at the targets would bias "
                        "the bow")
    return result


def _averaged_over_periods(data: CampaignData, result: Discovery, entry: Unresolved,
                           cand: Candidate) -> dict[str, tuple[dict[str, float], dict[str, float]]]:
    """Per free effect of the final model: its parameters and derived sizes averaged over the
    unresolved period's candidates (and none), and their errors with the spread over them."""
    free = [t for t in result.final.terms if not t.fixed and t.name in EFFECT_PARAMS]
    fits = [(result.final, -cand.delta_bic)]
    for period, delta in zip(entry.periods_mm or (), entry.period_delta_bic):
        shape = {PERIOD_KEY[cand.name]: period}
        fits.append((linear_fit(data, [*result.final.terms, Term(cand.name, shape, False, dict(shape))]), delta))
    weights = np.exp(-(np.array([d for _, d in fits]) - min(d for _, d in fits)) / 2)
    weights /= weights.sum()
    beside = standard_errors(data, fits[int(np.argmax(weights))][0])
    out = {}
    for term in free:
        values = [{**(p := f.params()[term.name]), **derived(term.name, p)} for f, _ in fits]
        averaged, errors = {}, dict(result.errors.get(term.name, {}))
        for key, value in values[0].items():
            if not isinstance(value, float) or key in term.held or key in ("start_mm", "end_mm"):
                averaged[key] = value
                continue
            column = np.array([v[key] for v in values])
            mean = float(weights @ column)
            spread = float(np.sqrt(weights @ (column - mean) ** 2))
            averaged[key] = mean
            if key in beside.get(term.name, {}):
                errors[key] = math.hypot(beside[term.name][key], spread)
        out[term.name] = (averaged, errors)
    return out

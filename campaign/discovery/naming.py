"""One candidate effect tried beside the current model (try_candidate): fitted at its best shape (a
grid, or for a period the periodogram's peaks refined as local optima), and the tests it must pass to
be named (naming_tests: BIC lower by more than BIC_MARGIN, a nested F-test with p < ALPHA times its
look-elsewhere factor, a lower cross-validated RMS), the gates on its values (gate_failures: each size
at least twice its standard error, every parameter in its physical range), what one target alone or a
wave that is zero at the targets would explain, and between nested effects the simpler one unless
the larger earns its parameter (prefer_simpler).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from campaign.discovery.cv import cv_rms_um
from campaign.discovery.data import CampaignData, keep_rows
from campaign.discovery.effects import (
    ENVIRONMENT_RANGES,
    FORMS,
    PERIOD_KEY,
    SIZE_SIGMAS,
    fixed_shape,
    period_key,
)
from campaign.discovery.fit import (
    Fit,
    Term,
    bic,
    confounders,
    derived,
    drop_collinear,
    f_test_p,
    full_columns,
    linear_fit,
    refine,
    standard_errors,
    weighted,
)
from campaign.discovery.local import HOPELESS
from campaign.discovery.periodogram import independent_periods, periodogram_periods
from campaign.discovery.result import Candidate, note_once
from campaign.discovery.unexplained import wave_over_part
from campaign.effects import RegistryView, effects

ALPHA = 0.001
"""Largest p-value of the F-test (after the look-elsewhere factor) for an effect to be named."""


BIC_MARGIN = 2.0
"""How much lower the BIC must be to name an effect ("positive evidence")."""


RIVAL_MARGIN = 6.0
"""Two candidates closer than this in ΔBIC ("strong evidence" on the BIC scale) are not clearly
apart; a period beaten by less than this by another local optimum is not identifiable."""


PERIOD_STARTS = 12
"""Periodogram peaks refined as local optima of the period search."""


PERIOD_LIST = 10.0
"""Competing periods within this ΔBIC of the best are listed and enter the period's error."""


def try_candidate(data: CampaignData, current: Fit, name: str, notes: list[str]) -> Candidate:
    """Fit the model plus `name` (best shape from a grid or periodogram) and test it."""
    n = len(data)
    held = fixed_shape(name, data, {})
    starts: list[dict[str, float]] = [{}]
    period_key = PERIOD_KEY.get(name)
    searched = period_key is not None and period_key not in held
    look_elsewhere = search_factor(data, name)
    if period_key is not None:
        starts = [{period_key: p} for p in periodogram_periods(data, current, top=PERIOD_STARTS)]
        if not starts:  # a flat periodogram (few targets): no period to start from
            return Candidate(name, None, verdict="not significant (no period stands out)")
    elif FORMS[name].shape_grid is not None:
        starts = FORMS[name].grid(data, {})
    best: Fit | None = None
    fits = []
    for shape in starts:
        term = drop_collinear(data, current.terms, Term(name, {}, False, {**held, **shape}))
        if not any(term.keep or ()):
            continue
        fit = linear_fit(data, [*current.terms, term])
        fits.append(fit)
        if best is None or fit.rss < best.rss:
            best = fit
    env_note = None
    if name == "environment" and fits:
        best, env_note = environment_variant(fits, n)
    if best is None:
        others = confounders(data, current.terms, Term(name, {}, False, {**held, **(starts[0] if starts else {})}))
        note_once(notes, f"{name} is confounded with {' + '.join(others) or 'the model'} on this data: not named")
        return Candidate(name, None, verdict="confounded")
    periods: list[tuple[float, float]] = []
    hopeless = bic(best, n) - bic(current, n) + 2 * math.log(look_elsewhere) > HOPELESS
    if hopeless:
        pass  # refining its shape would not bring it near the tests (as a local term's: local.HOPELESS)
    elif searched and len(fits) > 1:
        best, periods = period_optima(data, fits, name)
    elif FORMS[name].shape:
        best = refine(data, best.terms)
    elif rivals_in_model := [t.name for t in current.terms if t.searched and PERIOD_KEY.get(t.name) is None
                             and rival_pair(t.name, name)]:
        # an effect it is a rival of, in the model with a shape (a settling's time constant): refitted
        # beside it, else what it would take is held by the other's shape as fitted without it
        best = refine(data, [t if t.name in rivals_in_model or t.name == name else replace(t, held={**t.held, **t.shape})
                             for t in best.terms])
    cand = Candidate(name, best, explained_pct=100 * (1 - best.rss / current.rss) if current.rss > 0 else 0.0,
                     periods=periods)
    tests = naming_tests(data, current, best, name, look_elsewhere)
    cand.delta_bic, cand.p_value, cand.cv_before_um, cand.cv_after_um = tests.delta_bic, tests.p_value, *tests.cv_um
    failed = tests.failed
    gates = [] if failed else gate_failures(data, best, name)
    cand.verdict = ("not significant (" + ", ".join(failed) + (
                        "; from its best start, its shape not refined: far from the tests" if hopeless else "") + ")"
                    if failed else "not named (" + "; ".join(gates) + ")" if gates else "accepted")
    failed += gates
    if not failed and len(periods) > 1 and periods[1][1] < RIVAL_MARGIN:
        cand.verdict = "period not identifiable"
    elif not failed and period_key is not None and (partial := wave_over_part(data, best)):
        cand.verdict = f"not named ({partial})"  # an identified period whose wave is not on every turn
        failed.append(partial)
    elif not failed and period_key is not None and (single := one_target(data, current, best, name,
                                                                            look_elsewhere)
                                                     or zero_at_targets(data, best, name)):
        cand.verdict = f"not named ({single})"  # a screw lead shows on every turn, not at one target
        failed.append(single)
    if env_note and not failed:  # which log it follows matters only when it explains something
        note_once(notes, *env_note)
    return cand


def how_to_tell_pairs() -> dict[frozenset[str], str]:
    """What campaign separates two effects that explain the same residual: every effect's `rivals`
    (campaign/effects/), one entry a pair."""
    return {frozenset({e.name, other}): text for e in effects() for other, text in e.rivals.items()}


def rival_pair(a: str, b: str) -> bool:
    """Are `a` and `b` rivals (either's `rivals` names the other: they can explain the same residual)?"""
    return frozenset({a, b}) in how_to_tell_pairs()


def search_factor(data: CampaignData, name: str) -> float:
    """The look-elsewhere factor of the effect `name`'s search on this campaign: the independent periods
    tried when its period is searched (not held by the model or the campaign), else 1."""
    key = PERIOD_KEY.get(name)
    return independent_periods(data) if key is not None and key not in fixed_shape(name, data, {}) else 1.0


@dataclass(frozen=True)
class NamingTests:
    """The three tests an effect's term passes before it is named, or held for an unresolved group
    (naming_tests): ΔBIC and the F-test's p with its search's look-elsewhere factor, the RMS
    cross-validated by the form's group (before, after: µm), and the names of those it fails."""

    delta_bic: float
    p_value: float
    cv_um: tuple[float, float]
    failed: list[str]


def naming_tests(data: CampaignData, without: Fit, fit: Fit, name: str, look_elsewhere: float) -> NamingTests:
    """`fit` (`without` and the effect `name`'s term) against `without`: ΔBIC lower by BIC_MARGIN and the
    F-test's p under ALPHA, each with the look-elsewhere factor of the term's search (a searched period:
    periodogram.independent_periods; 1 otherwise), and a lower RMS cross-validated by the form's group (a target
    left out, or a run for an effect of time)."""
    n = len(data)
    delta_bic = bic(fit, n) - bic(without, n) + 2 * math.log(look_elsewhere)  # a search costs, as in the p-value
    p_value = min(1.0, f_test_p(without, fit, n) * look_elsewhere)
    groups = data.run if FORMS[name].group == "run" else data.target_index
    cv = cv_rms_um(data, without.terms, groups), cv_rms_um(data, fit.terms, groups)
    failed = [why for ok, why in ((delta_bic < -BIC_MARGIN, "BIC"), (p_value < ALPHA, "F-test"),
                                  (cv[1] < cv[0], "cross-validation")) if not ok]
    return NamingTests(delta_bic, p_value, cv, failed)


def one_target(data: CampaignData, without: Fit, fit: Fit, name: str, factor: float) -> str | None:
    """Is what `name` explains in `fit` (beside `without`, the model before it) carried by one target?
    The target whose squared residual it lowers most is left out and the term, its shape held, tested
    again on the others (F-test, with the look-elsewhere factor `factor` of its search): why in
    words when it is then no longer significant (ALPHA), None otherwise. An error that one target
    alone shows is a local error seen there (narrower than the spacing of the targets), not an effect
    that repeats along the travel."""
    tested = one_target_p(data, without, fit, name, factor)
    if tested is None or tested[0] < ALPHA:
        return None
    p_value, at = tested
    return (f"carried by one target: without the one at {at:.4g} {data.position_unit} it is not significant "
            f"(p = {p_value:.2g})")


def one_target_p(data: CampaignData, without: Fit, fit: Fit, name: str, factor: float) -> tuple[float, float] | None:
    """one_target's test: the p-value of `name` (its shape held) without the target whose squared
    residual it lowers most, times the look-elsewhere factor `factor` of its search, and that target's
    position; None with fewer than four targets. The held shape is not a fitted parameter here: its
    search is paid for by `factor` alone (counted as a parameter too, a searched period would be
    charged twice, and a lead that every target shows said to be carried by one)."""
    targets = data.target_index
    gain = np.bincount(targets, weighted(data, data.y - without.prediction) ** 2  # on weighted rows, as the F-test
                       - weighted(data, data.y - fit.prediction) ** 2)
    if len(gain) < 4:
        return None
    worst = int(np.argmax(gain))
    rest = keep_rows(data, targets != worst)
    others = [t for t in fit.terms if t.name != name]
    searched = len(next(t for t in fit.terms if t.name == name).searched)
    reduced, full = linear_fit(rest, others), linear_fit(rest, fit.terms)
    full = replace(full, n_params=full.n_params - searched)
    p_value = min(1.0, f_test_p(reduced, full, len(rest)) * factor)
    return p_value, float(np.mean(data.x[targets == worst]))


WAVE_Z = 3.0
"""A fitted wave whose mean square at the targets is this many standard errors below that of a wave
sampled at random phases (half its amplitude squared) is not a screw lead seen at the targets."""


def zero_at_targets(data: CampaignData, fit: Fit, name: str) -> str | None:
    """Is the wave `name` of `fit` near zero at most targets, its amplitude carried by a few? A screw
    lead sampled at targets that do not follow its period is seen at random phases: the mean of
    sin² over N targets is 1/2 with a standard error of (1/√8)/√N. A period chosen so that most
    targets sit near its zero crossings fits what a few targets show (a local error), not a wave that
    repeats on every turn: why in words when the mean is WAVE_Z standard errors below 1/2."""
    i = next(k for k, t in enumerate(fit.terms) if t.name == name)
    coefs = fit.coefs[i]
    amplitude = float(np.hypot(*coefs[:2])) if len(coefs) >= 2 else float(abs(coefs[0]))
    if amplitude <= 0:
        return None
    wave = full_columns(data, fit.terms[i]) @ coefs  # coefs in the form's full column order
    positions, where = np.unique(np.round(data.x, 6), return_inverse=True)
    period = fit.terms[i].shape.get(period_key(name) or "")
    if period and len(positions) > 1 and float(np.median(np.diff(positions))) < period / 4:
        return None  # sampled along its period, not at random phases: the wave is seen whole
    at_targets = np.bincount(where, wave) / np.bincount(where)
    share = float(np.mean(at_targets**2)) / amplitude**2
    z = (share - 0.5) / (math.sqrt(1 / 8) / math.sqrt(len(at_targets)))
    if z >= -WAVE_Z:
        return None
    return (f"near zero at most targets: its mean square there is {share:.2f} of its amplitude squared, where a "
            f"lead seen at random phases gives 0.5 ± {math.sqrt(1 / 8 / len(at_targets)):.2f}")


def gate_failures(data: CampaignData, fit: Fit, name: str) -> list[str]:
    """Why `name`, fitted in `fit`, may not be named however well it fits (empty: it may): a size
    below SIZE_SIGMAS of its standard error, or a parameter outside its documented physical range
    (EffectForm.sizes, EffectForm.ranges; docs/error-model.md)."""
    term = next(t for t in fit.terms if t.name == name)
    if term.fixed:
        return []
    params = fit.params()[name]
    values = {**params, **derived(name, params)}
    errors = standard_errors(data, fit).get(name, {})
    form = FORMS[name]
    out = []
    small = [f"{k} {values[k]:.3g} ± {errors[k]:.2g}" for k in form.sizes
             if k in values and k in errors and abs(values[k]) < SIZE_SIGMAS * errors[k]]
    if small:
        out.append(f"size under {SIZE_SIGMAS:g}σ: {', '.join(small)}")
    outside = [f"{k} = {params[k]:.4g} outside {lo:.4g} to {hi:.4g}" for k, (lo, hi)
               in form.physical_ranges(data).items() if k in params and k not in term.held
               and not lo <= params[k] <= hi]
    if outside:
        out.append(f"not physical: {', '.join(outside)}")
    return out


def period_optima(data: CampaignData, fits: list[Fit], name: str) -> tuple[Fit, list[tuple[float, float]]]:
    """Refine every periodogram start to its local optimum; the best, and the distinct optima
    (period mm, ΔBIC to the best; same parameter count, so ΔBIC = n·ln(RSS/RSS_best)) within
    PERIOD_LIST of it, best first, of the periodic effect `name`. Aliases of a screw lead sampled at
    few targets show up here as optima that fit about as well."""
    n = len(data)
    optima: list[Fit] = []
    for fit in fits:
        local = refine(data, fit.terms)
        period = _period(local, name)
        if all(abs(period - _period(o, name)) > 0.005 * period for o in optima):
            optima.append(local)
        else:
            same = next(o for o in optima if abs(period - _period(o, name)) <= 0.005 * period)
            if local.rss < same.rss:
                optima[optima.index(same)] = local
    optima.sort(key=lambda f: f.rss)
    best = optima[0]
    listed = [(_period(f, name), n * math.log(max(f.rss, 1e-300) / max(best.rss, 1e-300))) for f in optima]
    return best, [(p, d) for p, d in listed if d < PERIOD_LIST]


def _period(fit: Fit, name: str) -> float:
    return next(t.shape[PERIOD_KEY[name]] for t in fit.terms if t.name == name)


def period_spread_mm(periods: list[tuple[float, float]]) -> float:
    """The spread of the period over the competing optima, weighted by exp(-ΔBIC/2) (their
    approximate posterior odds), mm: the part of the period's error that one optimum's curvature
    does not see."""
    if len(periods) < 2:
        return 0.0
    values = np.array([p for p, _ in periods])
    weights = np.exp(-np.array([d for _, d in periods]) / 2)
    return float(np.sqrt(np.sum(weights * (values - values[0]) ** 2) / np.sum(weights)))


def environment_variant(fits: list[Fit], n: int) -> tuple[Fit, tuple[str, str] | None]:
    """Of the environment fits with each log alone and both together, the one with the lowest BIC
    among those with plausible coefficients (all of them if none is). When the air and material
    logs move together the variants fit alike: the note (text, topic) says so, and which one the
    coefficients rule out; it is said only when environment passes the tests (try_candidate)."""
    def coefs(fit: Fit) -> dict[str, float]:
        return fit.params()["environment"]

    def plausible(fit: Fit) -> bool:
        return all(lo <= coefs(fit)[k] <= hi for k, (lo, hi) in ENVIRONMENT_RANGES.items() if k in coefs(fit))

    ranked = sorted(fits, key=lambda f: bic(f, n))
    chosen = next((f for f in ranked if plausible(f)), ranked[0])
    rivals = [f for f in ranked if f is not chosen and set(coefs(f)) != set(coefs(chosen))
              and bic(f, n) - bic(chosen, n) < BIC_MARGIN]
    note = None
    for rival in rivals:
        logs = {k: ("air" if k == "air_factor" else "material") for k in (*coefs(chosen), *coefs(rival))}
        said = ", ".join(f"{k} = {v:.3g}" for k, v in coefs(rival).items())
        reason = (f"the {' and '.join(logs[k] for k in coefs(rival))} log alone would need {said}, which is not "
                  "physical" if not plausible(rival) else "both are plausible: the attribution is uncertain")
        topic = "the air and material logs move together in this campaign"
        text = (f"{topic}, so their slopes are confounded; "
                f"environment is fitted with the {' and '.join(logs[k] for k in coefs(chosen))} log: {reason}")
        note = (text, topic)
    return chosen, note


NESTED_IN: RegistryView[str] = RegistryView(lambda e: e.nested_in)
"""Effect -> the simpler effect it contains (its k = 0 case): each effect's `nested_in`."""


def prefer_simpler(best: Candidate, accepted: list[Candidate], n: int, notes: list[str]) -> Candidate:
    """Between nested candidates the larger one must earn its extra parameters: a nested F-test
    against the simpler one with p < ALPHA; otherwise the simpler one is named."""
    simpler = next((c for c in accepted if c.name == NESTED_IN.get(best.name)), None)
    if simpler is None:
        return best
    p = f_test_p(simpler.fitted, best.fitted, n)
    if p < ALPHA:
        return best
    note_once(notes, f"{best.name} fits a little better than {simpler.name}, but its extra parameter is not "
                 f"significant (nested F-test p = {p:.2g}): {simpler.name} is named")
    return simpler

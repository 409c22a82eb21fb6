"""Discovery: find where the simulated and the measured campaign disagree, name the effect the
model is missing, add it, refit, and repeat until what is left is noise (issue 4, reference §5).

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

import itertools
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from campaign.discovery.data import CampaignData, keep_rows
from campaign.discovery.effects import (
    ENVIRONMENT_RANGES,
    FORMS,
    HELD_PREFIX,
    LASER_DATUM_MM,
    PERIOD_KEY,
    PERIOD_RANGE_MM,
    SHAPE_KEYS,
    SIZE_SIGMAS,
    environment_logs,
    even_spacing,
    fixed_shape,
    period_key,
    period_limits,
)
from campaign.discovery.fit import (
    Fit,
    Term,
    bic,
    confounders,
    cv_group_errors,
    cv_rms_um,
    cv_searched_errors,
    derived,
    drop_collinear,
    f_test_p,
    full_columns,
    linear_fit,
    refine,
    shape_bounds,
    shapes_held,
    standard_errors,
    weighted,
)
from campaign.discovery.local import (
    HOPELESS,
    SIDES,
    TARGET,
    LocalError,
    describe,
    find_local,
    find_locals,
    gap_um,
    is_local,
    look_elsewhere,
    other_shape,
    passes,
    point_weights,
    refit_local,
    shapes_refined,
    term_index,
    term_kind,
)
from campaign.discovery.local import MAX_REGIONS as MAX_LOCALS
from campaign.discovery.locate import Located, beside_period, locate
from campaign.discovery.periodogram import independent_periods, periodogram_periods
from campaign.discovery.records import (
    Choice,
    Held,
    LocalRival,
    NotExcluded,
    StandIn,
    StartingEffect,
    TableGap,
    Unresolved,
)
from campaign.discovery.unexplained import (
    REGION_SHARE,
    candidate_regions,
    describe_region,
    is_region,
    region_term,
    region_terms,
    wave_over_part,
)
from campaign.effects import RegistryView, effect, effects
from campaign.effects.base import stop_waits
from campaign.errors import InputError
from campaign.model import DEFAULTS, EFFECT_PARAMS, ErrorModel

ALPHA = 0.001
"""Largest p-value of the F-test (after the look-elsewhere factor) for an effect to be named."""
BIC_MARGIN = 2.0
"""How much lower the BIC must be to name an effect ("positive evidence")."""
MAX_STEPS = len(FORMS)
RIVAL_MARGIN = 6.0
"""Two candidates closer than this in ΔBIC ("strong evidence" on the BIC scale) are not clearly
apart; a period beaten by less than this by another local optimum is not identifiable."""
PERIOD_STARTS = 12
"""Periodogram peaks refined as local optima of the period search."""
PERIOD_LIST = 10.0
"""Competing periods within this ΔBIC of the best are listed and enter the period's error."""

DWELL_SPREAD = 0.05
"""Relative spread of the wait since arrival below which settling is not looked for."""
VARIED_WAIT_POINTS = 8
"""Points whose wait departs from the typical one by more than DWELL_SPREAD that it takes to tell
settling (two parameters, one per wait) from a constant reversal: one short capture in a
fixed-dwell campaign does not."""


NEEDS: RegistryView[str] = RegistryView(lambda e: e.needs)
"""Effect -> what a campaign must have for it to be looked for (each effect's `needs`: a varying
wait, a varying air or material log, two runs or more)."""


def periodic_in(names: Iterable[str]) -> bool:
    """Is one of these effects a periodic one (PERIOD_KEY)?"""
    return any(name in PERIOD_KEY for name in names)


def period_unresolved(unresolved: list[Unresolved]) -> bool:
    """Is a periodic effect in an unresolved group (its period not identifiable, or a rival's)?"""
    return any(periodic_in(u.effects) for u in unresolved)


def period_candidate(ranking: list[Candidate]) -> Candidate | None:
    """The fitted candidate of a periodic effect among `ranking`, if any."""
    return next((c for c in ranking if c.name in PERIOD_KEY and c.fit is not None), None)


@dataclass
class Candidate:
    """An effect tried at one step: its fit, the residual share it explains (%), and the tests."""

    @property
    def fitted(self) -> Fit:
        """The fit of an effect that was fitted; ValueError for one that could not be."""
        if self.fit is None:
            raise ValueError(f"{self.name} has no fit")
        return self.fit

    name: str
    fit: Fit | None
    explained_pct: float = 0.0
    delta_bic: float = 0.0
    p_value: float = 1.0
    cv_before_um: float = 0.0
    cv_after_um: float = 0.0
    verdict: str = ""
    periods: list[tuple[float, float]] = field(default_factory=list)
    """A periodic effect (PERIOD_KEY): the local optima of the period search, (period mm, ΔBIC to the best), best
    first, for the optima within PERIOD_LIST of the best."""

    @property
    def accepted(self) -> bool:
        return self.verdict == "accepted"


@dataclass(frozen=True)
class Step:
    """One named effect: its parameters and the gap (RMS of measured - simulated, µm) before and
    after; `ranking`: every candidate tried at this step; residuals µm per point."""

    effect: str
    params: dict[str, float]
    gap_before_um: float
    gap_after_um: float
    ranking: list[Candidate]
    residual_before: np.ndarray
    residual_after: np.ndarray
    errors: dict[str, float] = field(default_factory=dict)
    """1-σ standard errors of the fitted parameters (see discovery_fit.standard_errors); a
    period's includes the spread over its competing optima."""


STAND_IN_RIVALS = frozenset({"backlash", "settling"})
"""An unresolved group made only of these predicts one constant offset per direction at a constant
wait, wherever the axis is used: its size is known and is added (as backlash), its cause is not;
only when the waits do not vary (or are not recorded): where they vary, the two predict different
deviations at other waits, and neither stands in.
Rivals that predict differently between the measured points (aliased periods) get no stand-in."""


@dataclass
class Discovery:
    """The result. gaps µm; noise_um: pooled run-to-run scatter of the final residual per target
    and direction (µm); offset_um: the fitted datum offset; notes: confounding and caveats."""

    steps: list[Step]
    start: Fit
    final: Fit
    gap_before_um: float
    gap_after_um: float
    noise_um: float
    time_source: str
    notes: list[str] = field(default_factory=list)
    disagreement_before: dict = field(default_factory=dict)
    disagreement_after: dict = field(default_factory=dict)
    choices: list[Choice] = field(default_factory=list)
    """Where two confounded candidates were both plausible: step, chosen, other, why."""
    unresolved: list[Unresolved] = field(default_factory=list)
    """Effects the data cannot tell apart or pin down, none of them named: effects, why,
    how_to_tell (and periods_mm for a period that is not identifiable)."""
    errors: dict[str, dict[str, float]] = field(default_factory=dict)
    """1-σ standard errors of the final model's fitted parameters, per effect."""
    remaining: list[Candidate] = field(default_factory=list)
    """The candidates tried after the last step, none of them named."""
    remaining_beside: str | None = None
    """The unresolved effect the remaining candidates were tried beside (a stand-in), if any."""
    stand_in: StandIn | None = None
    """Rivals that predict the same deviation at every position the campaign can be used for
    (backlash and settling at a constant wait): one of them is in the final model in their place,
    not named (STAND_IN_RIVALS). effect, observable (what the data show, in words), rivals,
    params, errors, gap_without_um (the gap had nothing been added for it)."""
    averaged: dict[str, dict[str, float]] = field(default_factory=dict)
    """Beside a periodic error whose period is not identifiable: the other effects' parameters,
    averaged over its candidate periods (beside_unresolved_period); they replace the fitted ones."""
    local_errors: list[LocalError] = field(default_factory=list)
    """Errors outside the vocabulary, in the final model as local terms (bumps, steps; not named as
    effects of the model, not saved with it), in the order found (the one that explains most
    first; campaign.discovery.local.zones gives them along the axis)."""
    starting: dict[str, StartingEffect] = field(default_factory=dict)
    """The starting model's effects, as fitted at the end: params, errors, given (the keys the
    model gave), fixed, p_value (F-test of the effect against none of it) and significant."""
    located_before: Located | None = None
    """Where the campaign departs from the starting model beyond the noise, model-free
    (campaign.discovery.locate), before anything is named."""
    located_after: Located | None = None
    """The same for the final model: what it leaves unexplained, with its regions (what a held
    unresolved group holds included: model_prediction)."""
    tables: list[TableGap] = field(default_factory=list)
    """Tables fitted together: per table (campaign index order) its own gap and noise (gap_um,
    noise_um: its points alone, unweighted); gap_after_um and noise_um weigh each table as the fit
    does (campaign.discovery.local.gap_um). Empty for one table."""
    noise_measured: bool = True
    """False when no target is read twice in a direction: noise_um is then the residual itself, not
    a measured run-to-run scatter, and nothing can be said to be noise."""
    held: list[Held] = field(default_factory=list)
    """What an unresolved group shows (a reversal backlash and settling explain alike at waits that
    vary too little to tell them), held in the final fit by its better rival's form so that the gap
    shrinks (hold_unresolved): the group stays unresolved, nothing is named or saved for it."""
    not_excluded: list[NotExcluded] = field(default_factory=list)
    """Rivals of named effects the data leave room for (rivals_not_excluded)."""

    @property
    def local(self) -> LocalError | None:
        """The first error outside the vocabulary (the one that explains most), if any."""
        return self.local_errors[0] if self.local_errors else None

    def params(self) -> dict[str, dict[str, float]]:
        """The final model's parameters per effect (averaged over an unresolved period's candidates
        where that applies; a term holding an unresolved group, HELD_PREFIX, is not the model's: `held`)."""
        return {**{k: v for k, v in self.final.params().items() if not k.startswith(HELD_PREFIX)}, **self.averaged}

    @property
    def added(self) -> list[str]:
        return [s.effect for s in self.steps]

    def final_model(self, noise: dict[str, float] | None = None) -> ErrorModel:
        """The final model (the offset is left out: it belongs to the datum, not the axis; so is
        `environment`, which follows the log of one campaign and is not a parameter of the axis)."""
        effects = {name: {k: params[k] for k in EFFECT_PARAMS[name]} for name, params in self.params().items()
                   if name in EFFECT_PARAMS}
        effects["noise"] = noise or {"sigma_um": round(self.noise_um, 4)}
        return ErrorModel(effects)


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
            _note(notes, f"the model's {name} is left out: without a capture_wait_s column the wait since "
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


def candidate_names(data: CampaignData, terms: list[Term], notes: list[str]) -> list[str]:
    """Effects not in the model that this data can show; notes say why others are not tried."""
    present = {t.name for t in terms}
    names = [n for n in FORMS if n not in present]
    for name in [n for n in names if NEEDS.get(n) == "wait"]:
        if data.w is None:
            names.remove(name)
            _note(notes, f"{name} is not looked for: the table has no capture_wait_s column, and at a "
                         f"constant wait {name} looks exactly like backlash")
        elif not waits_vary(data):
            names.remove(name)
            _note(notes, f"{name} is confounded with backlash: the dwell does not vary, so {name} "
                         "is not looked for (vary the dwell to separate them)")
    low, high = period_limits(data)
    for name in [n for n in names if n in PERIOD_KEY]:
        if low < high:
            if even_spacing(data) is not None and low > PERIOD_RANGE_MM[0]:
                _note(notes, f"{name} is looked for at periods from {low:.4g} to {high:.4g} {data.position_unit}: "
                             "the targets are evenly spaced, so shorter periods alias onto longer ones")
            continue
        names.remove(name)
        spacing = even_spacing(data)
        _note(notes, f"{name} is not looked for: the targets are evenly spaced {spacing:.4g} "
                     f"{data.position_unit} apart, so a period shorter than twice that ({2 * (spacing or 0):.4g} "
                     f"{data.position_unit}) aliases into a smooth bow or vanishes, and the screw leads looked for "
                     f"end at {high:.4g} {data.position_unit} (plan with offsets = \"golden\" or \"random\", or "
                     "targets closer together)")
    for name in [n for n in names if NEEDS.get(n) == "log"]:
        if not environment_logs(data):
            names.remove(name)
            _note(notes, f"{name} is not looked for: the table has no air or material log that varies "
                         "(air_temp_c, air_pressure_hpa, humidity_pct, material_temp_c)")
    for name in [n for n in names if NEEDS.get(n) == "runs"]:
        if len(np.unique(data.run)) < 2:
            names.remove(name)
            _note(notes, f"{name} is not looked for: one run cannot show a run-to-run change")
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


def _note(notes: list[str], text: str, topic: str | None = None) -> None:
    """Add a note once. `topic`: the start of a note whose numbers change from step to step; an
    earlier note on it is replaced, so the reader sees it once, with the final numbers."""
    if topic is not None:
        notes[:] = [n for n in notes if not n.startswith(topic)]
    if text not in notes:
        notes.append(text)


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
        _note(notes, f"{name} is confounded with {' + '.join(others) or 'the model'} on this data: not named")
        return Candidate(name, None, verdict="confounded")
    periods: list[tuple[float, float]] = []
    hopeless = bic(best, n) - bic(current, n) + 2 * math.log(look_elsewhere) > HOPELESS
    if hopeless:
        pass  # refining its shape would not bring it near the tests (as a local term's: local.HOPELESS)
    elif searched and len(fits) > 1:
        best, periods = period_optima(data, fits, name)
    elif FORMS[name].shape:
        best = refine(data, best.terms)
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
        _note(notes, *env_note)
    return cand


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
    _note(notes, f"{best.name} fits a little better than {simpler.name}, but its extra parameter is not "
                 f"significant (nested F-test p = {p:.2g}): {simpler.name} is named")
    return simpler


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
            _note(routes[best].notes, f"{name} explained part of the residual before the local errors were located; "
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


def unnamed_forms(data: CampaignData, vocabulary: Discovery) -> Iterator[tuple[Candidate, Term]]:
    """Each effect the vocabulary search tried and did not name (not a period), as one form to hold beside
    the grid: its shape fixed (skipped when it has a shape to search, a time constant)."""
    for cand in [c for c in vocabulary.remaining if c.name not in PERIOD_KEY]:
        shape = fixed_shape(cand.name, data, {})
        if all(key in shape for key in FORMS[cand.name].shape):
            yield cand, Term(cand.name, {}, False, shape)


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


def places(found: list[LocalError]) -> int:
    """In how many places along the axis the local errors lie: those whose regions overlap are one place
    (a departure at one target and at it and its neighbour together describe one error)."""
    count, reach = 0, -math.inf
    for low, high in sorted(e.region_mm for e in found):
        count += low > reach
        reach = max(reach, high) if low <= reach else high
    return count


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
            _note(result.notes, f"{local.sentence()}: not told from {said}, which predicts left-out targets as "
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
                _note(result.notes, f"{rival} beside {named} is not excluded by this data: {rival_size} = "
                                    f"{value:.3g} ± {error:.2g} beside it, {named}'s shape refitted (up to "
                                    f"{abs(value) + SIZE_SIGMAS * error:.2g} against {named}'s {size_key} {size:.3g}); "
                                    f"{named}'s values may hold part of it. To tell: {how}")


TIME_CONSTANT = "tau_s"
"""The shape parameter that is a time constant in every effect that has one (effects.SHAPE_KEYS)."""


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
        result.held.append(Held(best.name, tuple(entry.effects), held_said(data, trial, term.name, entry.effects),
                                trial.params()[term.name], without))
        _note(result.notes, f"what {said_list(list(entry.effects))} explain alike is held in the model by "
                            f"{best.name}'s form (gap {without:.3f} -> {result.gap_after_um:.3f} "
                            f"{data.deviation_unit}), not named: which of them it is stays unresolved")
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


def held_said(data: CampaignData, fit: Fit, name: str, rivals: tuple[str, ...], places: str = "") -> str:
    """What the term `name` of `fit`, holding an unresolved group, shows in words: a reversal between
    the directions (its mean going up less its mean going down) when the group is backlash against
    settling, else the rival's form that holds it (with local errors at `places` among the rivals when
    given)."""
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
    return f"what {said} explain alike, held by {name.removeprefix(HELD_PREFIX)}'s form; cannot tell which"


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


def described_in(data: CampaignData, fit: Fit, local: LocalError) -> LocalError:
    """A bump or step found earlier (its tests as found), described from `fit`: its size and place as
    `fit` has them beside the terms added after it."""
    return describe(data, fit, local.term.name, explained_pct=local.explained_pct, delta_bic=local.delta_bic,
                    p_value=local.p_value, cv_before_um=local.cv_before_um, cv_after_um=local.cv_after_um,
                    gap_without_um=local.gap_without_um)


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
        _note(again.notes, f"{name} explained part of the residual beside the local errors, but not on the targets "
                           f"outside their regions (F-test p = {p:.2g} there): not named (it held what the local "
                           "terms leave of an error they describe in part)")
    if periodic and period_unresolved(again.unresolved):
        if rivals_said and (rivals := add_local_rivals(vocabulary, found)):
            _note(vocabulary.notes, f"{rivals[0].sentence()} would fit too, but the unresolved periodic error is "
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
                _note(result.notes, f"{name} is not named: local terms (bumps, steps) in its place predict left-out "
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
            _note(result.notes, f"{name} stays named: local terms over the regions it explains, located again "
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
        _note(result.notes, f"{name} is not named: local terms over the regions it explains predict left-out targets "
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
        _note(result.notes, f"what the model left beyond the noise is held by {len(added)} local term"
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
        _note(result.notes, f"{local.sentence()}: fitted in both directions, which predicts left-out targets better")
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
    _note(result.notes, f"{name} is not named: local terms in its place ({'; '.join(e.sentence() for e in new)}) "
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
            _note(result.notes, f"{name} is not named: beside the candidate periods of the unresolved periodic "
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
    _note(result.notes, f"the named effects' values are fitted beside each of the {len(entry.periods_mm or ())} "
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
    for _ in range(MAX_STEPS):
        ranking = [try_candidate(data, current, name, notes)
                   for name in candidate_names(data, current.terms, notes) if name not in left_out]
        ranking.sort(key=lambda c: (c.fit is None, c.delta_bic))
        chosen, unresolved = choose(data, current, ranking, notes)
        held = [c for c in ranking if c.verdict.startswith(UNRESOLVED_VERDICTS)]
        remaining_beside = None
        if chosen is None and held:
            # something is there that cannot be named (rivals, or a period not known): test the
            # others beside the best of it as a stand-in, so that its residual does not hide them
            stand_in = min(held, key=lambda c: c.delta_bic)
            # its own group stays out; another unresolved group is tried again beside it (a drift
            # seen beside an aliased period may tell its shape once the period's residual is held)
            own = {stand_in.name} | {c.name for c in held if stand_in.name in c.verdict.split("from ", 1)[-1]
                                     or c.verdict == f"held with {stand_in.name}, which is unresolved"}
            others = [try_candidate(data, stand_in.fitted, name, notes)
                      for name in candidate_names(data, stand_in.fitted.terms, notes)
                      if name not in own and name not in left_out]
            held = [c for c in held if c.name in own]
            others.sort(key=lambda c: (c.fit is None, c.delta_bic))
            chosen, more = choose(data, stand_in.fitted, others, notes)
            unresolved = [u for u in unresolved if set(u.effects) & own] + more
            ranking = [*held, *others]
            if chosen is not None:
                _note(notes, f"{chosen.name} was tested beside the unresolved {stand_in.name} (as a stand-in, "
                             "not named), whose residual would otherwise hide it")
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
            _note(notes, choice.why)
        after = refine(data, chosen.fitted.terms)
        if chosen.periods:
            spreads[chosen.name] = period_spread_mm(chosen.periods)
        errors = standard_errors(data, after).get(chosen.name, {})
        add_period_spread(errors, chosen.name, spreads)
        steps.append(Step(chosen.name, after.params()[chosen.name], gap_um(data, data.y - current.prediction),
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
        current = refine(data, backlash.fitted.terms)
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
                     stand_in=kept, starting=starting_report(data, start, current, all_errors, given))


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
        _note(notes, f"{step.effect} is not named: beside the other effects of the final model it fails the "
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


def how_to_tell_pairs() -> dict[frozenset[str], str]:
    """What campaign separates two effects that explain the same residual: every effect's `rivals`
    (campaign/effects/), one entry a pair."""
    return {frozenset({e.name, other}): text for e in effects() for other, text in e.rivals.items()}


HOW_TO_TELL_DEFAULT = ("a campaign that varies what separates them: more runs over a longer time for time "
                       "effects, more targets for effects along the travel, varied dwells for settling")
PERIOD_HOW_TO_TELL = ("more targets (at least 4 per screw lead over part of the travel), a denser offset pattern "
                      "(offsets = \"golden\" with a larger offset_fraction), or the known screw lead in the model "
                      "(periodic_lead.period_mm): with the period given, only the amplitude is fitted")
UNRESOLVED_VERDICTS = ("not told apart", "held with", "period not identifiable")
"""Verdicts of candidates that are neither named nor rejected: the data cannot resolve them."""
CONFOUNDED_PAIRS = {frozenset({"environment", "thermal_drift"}), frozenset({"environment", "linear_drift"})}
"""Pairs with their own way of choosing (air_or_screw), not treated as rivals."""


def choose(data: CampaignData, current: Fit, ranking: list[Candidate],
           notes: list[str]) -> tuple[Candidate | None, list[Unresolved]]:
    """The candidate to name at this step, and what cannot be resolved: a periodic error whose
    period is not identifiable, and groups of candidates that explain the same residual about
    equally well (rivals). Neither a rival nor an unidentifiable period is named; the other
    candidates go on."""
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
    return None, unresolved


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
        _note(notes, f"nothing more is named: no other candidate{where} explains more than "
                     f"{most.explained_pct:.1f} % of the residual")
    else:
        _note(notes, f"nothing more is named: no other candidate{where} passes the three tests; the one that "
                     f"explains most, {most.name} ({most.explained_pct:.1f} % of the residual), fails {fails}")


def add_confounding_notes(data: CampaignData, fit: Fit, notes: list[str]) -> None:
    """Say which named effects cannot be told from others on this data."""
    params = fit.params()
    logs = environment_logs(data)
    if "linear_scale" in params:
        _note(notes, "linear_scale also holds any cosine error (always negative, < 1 µm/m) and a constant "
                     "air refractive-index or material-expansion error (only their changes follow the log): "
                     "they are confounded with it")
    if "environment" in params:
        env = params["environment"]
        if "air_factor" in env:
            _note(notes, f"environment: the reading follows {env['air_factor']:.2f} × the air log's refractive-index "
                         "change (1: the instrument does not compensate the air; 0: it does)")
        if "alpha_ppm_per_k" in env:
            _note(notes, f"environment: the reading follows the material temperature with "
                         f"{env['alpha_ppm_per_k']:.2f} µm/m per K (steel 11.5: the table is not normalised to 20 °C)")
    if "thermal_drift" in params:
        pivot = params["thermal_drift"]["pivot_mm"]
        datum = LASER_DATUM_MM
        travel = float(np.ptp(data.x)) or 1.0
        near = abs(pivot - datum) < 0.15 * travel
        if near and "air" not in logs:
            _note(notes, f"thermal_drift pivots at {pivot:.0f} mm, near the laser datum (x = {datum:g}): screw "
                         "growth is confounded with a drift of the air's refractive index here (no air log)")
        elif abs(pivot - datum) > 2 * travel:
            _note(notes, f"thermal_drift pivots at {pivot:.0f} mm, far outside the travel: mostly a drift of "
                         "the datum over time (e.g. the laser, its mount or the air warming), not screw growth")
        elif not near:
            _note(notes, f"thermal_drift pivots at {pivot:.0f} mm, away from the laser datum (x = {datum:g}): "
                         "screw growth about a fixed bearing, not air refractive index (which pivots at the datum)")
        if "air" in logs and "environment" not in params:
            _note(notes, "the air log varies, but its refractive-index change does not explain the slope change "
                         "(environment is not significant beside thermal_drift): the instrument compensates "
                         "the air, and the change is the machine's")

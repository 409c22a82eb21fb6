"""Acceptance of issue 4 (discovery) on synthetic campaigns from campaign/discovery/simulate.py: one effect
hidden, two hidden at once, the null case over 100 seeds, and the confounding refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from campaign.config import parse_config
from campaign.discovery.data import campaign_data
from campaign.discovery.search import discover
from campaign.discovery.simulate import Environment, simulate_campaign
from campaign.model import ErrorModel
from campaign.plan import build_plan
from tests.conftest import sweep

PLAN = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 610.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 600.0
count = 21
overrun = 5.0
cycles = 5
dwell_s = 2.0
velocity = 20.0
offsets = "golden"
offset_fraction = 0.45

[capture]
average_s = 0.5
"""
CONFIG = parse_config(PLAN)
SIGMA_UM, READING_UM, SAMPLES = 0.3, 0.05, 5  # 0.5 s window at 10 Hz
NOISE_UM = math.sqrt(SIGMA_UM**2 + READING_UM**2 / SAMPLES)
SPAN = (min(build_plan(CONFIG).targets), max(build_plan(CONFIG).targets))  # mm

BASE = {"linear_scale": {"ppm": -12.4}, "backlash": {"b_um": 4.0},
        "noise": {"sigma_um": SIGMA_UM, "reading_sigma_um": READING_UM}}

HIDDEN = {
    "linear_scale": ({"ppm": 25.0}, ["ppm"]),
    "backlash": ({"b_um": 6.0}, ["b_um"]),
    "periodic_lead": ({"amplitude_um": 1.5, "period_mm": 10.0, "phase_rad": 0.7}, ["amplitude_um", "period_mm"]),
    "thermal_drift": ({"growth_ppm": 10.0, "tau_s": 250.0, "pivot_mm": 300.0}, ["growth_ppm"]),
    "nonlinear_lead": ({"p2_um": 2.0, "p3_um": -1.5, "start_mm": SPAN[0], "end_mm": SPAN[1]}, ["p2_um", "p3_um"]),
    "position_dependent_backlash": ({"b0_um": 0.0, "k_ppm": 10.0}, ["k_ppm"]),
    "settling": ({"e0_um": 2.0, "tau_s": 0.8}, ["e0_um"]),
}
"""Effect -> (its true parameters, the parameters checked to 15 %) on the 12-minute campaign of
PLAN. The time constants are checked separately (test_time_constants_...): on this campaign they
are determined to about ±12 % (1σ) only."""

TIME_CAMPAIGNS = {
    # 10 cycles (25 min, 6 time constants) and a 20 µm/m growth (1.7 K of a steel screw)
    "thermal_drift": (PLAN.replace("cycles = 5", "cycles = 10"),
                      {"growth_ppm": 20.0, "tau_s": 250.0, "pivot_mm": 300.0}, None),
    # 10 cycles, a 0.2 s capture window and dwells log-uniform from 0.25 to 5 s
    "settling": (PLAN.replace("cycles = 5", "cycles = 10").replace("average_s = 0.5", "average_s = 0.2"),
                 {"e0_um": 3.0, "tau_s": 0.8}, (0.25, 5.0)),
}
"""Campaigns designed to measure a time constant: effect -> (plan, true parameters, dwell range
s or None). Over 30 seeds the time constant's RMS error is 4 % (thermal) and 5 % (settling),
the largest 8 % and 12 %; the main parameter's 2 % (largest 4 % and 5 %)."""


def run_discovery(true_effects: dict, start_effects: list[str], seed: int = 3, dwell_jitter: float = 0.8,
                  config=CONFIG, dwells_s=None, environment=None):
    table = simulate_campaign(config, ErrorModel(true_effects), seed=seed, dwell_jitter=dwell_jitter,
                              dwells_s=dwells_s, environment=environment)
    start = ErrorModel({name: {} for name in start_effects})
    return discover(campaign_data(table), start, {name: set() for name in start_effects})


def test_simulation_is_deterministic_and_follows_the_plan_timeline():
    model = ErrorModel(BASE)
    a = simulate_campaign(CONFIG, model, seed=5, dwell_jitter=0.5)
    b = simulate_campaign(CONFIG, model, seed=5, dwell_jitter=0.5)
    c = simulate_campaign(CONFIG, model, seed=6, dwell_jitter=0.5)
    assert np.array_equal(a.deviation, b.deviation) and not np.array_equal(a.deviation, c.deviation)
    assert len(a) == 21 * 2 * 5 and set(a.run) == {1, 2, 3, 4, 5}
    assert np.all(np.diff(a.optional["time_s"]) > 0)
    waits = a.optional["capture_wait_s"]
    assert waits.min() >= 0.5 and waits.max() <= 3.0 + 1e-9 and np.ptp(waits) > 1.0
    # noise-free, the table is the model's deviation at the target and direction
    quiet = ErrorModel({k: v for k, v in BASE.items() if k != "noise"})
    clean = simulate_campaign(CONFIG, quiet, seed=5)
    assert np.allclose(clean.deviation, quiet.deviation_um(clean.target, clean.direction))


@pytest.mark.machine
@pytest.mark.parametrize("hidden", list(HIDDEN))
def test_one_hidden_effect_is_named_and_recovered(hidden):
    true_params, checked = HIDDEN[hidden]
    true_effects = {**BASE, hidden: true_params}
    start = [name for name in true_effects if name not in (hidden, "noise")]
    result = run_discovery(true_effects, start)
    assert result.added == [hidden], (result.added, result.notes)
    found = result.steps[0].params
    for key in checked:
        assert found[key] == pytest.approx(true_params[key], rel=0.15), (key, found)
    if "tau_s" in true_params:  # within 3 of its reported standard errors (~12 % here)
        assert abs(found["tau_s"] - true_params["tau_s"]) <= 3 * result.steps[0].errors["tau_s"], found
    assert result.gap_after_um <= 1.3 * NOISE_UM
    assert result.gap_after_um < result.gap_before_um


@pytest.mark.machine
@pytest.mark.parametrize("hidden", list(TIME_CAMPAIGNS))
@pytest.mark.parametrize("seed", sweep(3, 4))
def test_time_constants_are_recovered_within_15_percent_on_a_campaign_designed_for_them(hidden, seed):
    plan, true_params, dwell_range = TIME_CAMPAIGNS[hidden]
    config = parse_config(plan)
    dwells = None
    if dwell_range:
        rng = np.random.default_rng(1000 + seed)
        dwells = list(np.exp(rng.uniform(*np.log(dwell_range), len(build_plan(config).points))))
    true_effects = {**BASE, hidden: true_params}
    start = [name for name in true_effects if name not in (hidden, "noise")]
    result = run_discovery(true_effects, start, seed=seed, config=config, dwells_s=dwells)
    assert result.added == [hidden], (result.added, result.notes)
    found, errors = result.steps[0].params, result.steps[0].errors
    main = "growth_ppm" if hidden == "thermal_drift" else "e0_um"
    for key in (main, "tau_s"):
        assert found[key] == pytest.approx(true_params[key], rel=0.15), (key, found)
        assert errors[key] < 0.075 * true_params[key], errors  # designed: 15 % is at least 2 σ
    assert result.gap_after_um <= 1.3 * NOISE_UM


@pytest.mark.machine  # a sweep of simulated campaigns, about 3 s of CPU
def test_time_constants_on_the_short_campaign_are_only_known_to_about_12_percent():
    """What PLAN's 12-minute campaign can do: the reported standard error of tau is 7-25 %, so a
    15 % check would fail on a fair share of seeds; the errors stay within 3 standard errors."""
    for hidden in TIME_CAMPAIGNS:
        true_params = HIDDEN[hidden][0]
        ratios = []
        for seed in range(3, 9):
            true_effects = {**BASE, hidden: true_params}
            result = run_discovery(true_effects, [n for n in true_effects if n not in (hidden, "noise")], seed=seed)
            step = result.steps[0]
            assert 0.07 * true_params["tau_s"] < step.errors["tau_s"] < 0.25 * true_params["tau_s"], step.errors
            ratios.append((step.params["tau_s"] - true_params["tau_s"]) / step.errors["tau_s"])
        assert max(abs(r) for r in ratios) < 3, ratios


@pytest.mark.machine
@pytest.mark.parametrize("pair", [("periodic_lead", "thermal_drift"), ("nonlinear_lead", "settling"),
                                  ("backlash", "periodic_lead")])
def test_two_hidden_effects_are_both_named(pair):
    true_effects = {**BASE, **{name: HIDDEN[name][0] for name in pair}}
    start = [name for name in true_effects if name not in (*pair, "noise")]
    result = run_discovery(true_effects, start, seed=11)
    assert sorted(result.added) == sorted(pair), (result.added, result.notes)
    assert result.gap_after_um <= 1.3 * NOISE_UM


@pytest.mark.machine  # 100 simulated campaigns and discoveries: about 17 s, too long for the fast tier
def test_null_case_names_nothing_in_at_least_95_of_100_seeds():
    true_effects = {**BASE, "nonlinear_lead": HIDDEN["nonlinear_lead"][0]}
    start = [name for name in true_effects if name != "noise"]
    named = [run_discovery(true_effects, start, seed=seed).added for seed in range(100)]
    assert sum(1 for added in named if not added) >= 95, [a for a in named if a]


@pytest.mark.parametrize("hidden", ["settling", "backlash"])
def test_at_a_constant_dwell_settling_and_backlash_are_unresolved_not_named(hidden):
    """At a constant wait a settling tail is a constant offset per direction: the reversal is real,
    but whether it is backlash or settling the campaign cannot tell, so neither is named."""
    true_effects = {**{k: v for k, v in BASE.items() if k != "backlash"}, hidden: HIDDEN[hidden][0]}
    result = run_discovery(true_effects, ["linear_scale"], dwell_jitter=0.0)
    assert "settling" not in result.added and "backlash" not in result.added, result.added
    entry = next(e for e in result.unresolved if set(e.effects) == {"backlash", "settling"})
    assert "cannot tell backlash from settling" in entry.why and "decade" in entry.how_to_tell
    assert any("settling is confounded with backlash" in note for note in result.notes)


def test_a_reversal_that_grows_along_the_travel_is_named_at_a_constant_dwell():
    """Settling gives the same offset at every target: a growth of the reversal along the travel is
    no settling, so position_dependent_backlash is named even at a constant wait."""
    true_effects = {**BASE, "position_dependent_backlash": {"b0_um": 3.0, "k_ppm": 10.0}}
    del true_effects["backlash"]
    result = run_discovery(true_effects, ["linear_scale"], dwell_jitter=0.0)
    assert result.added == ["position_dependent_backlash"], (result.added, result.unresolved)


def test_an_effect_the_model_already_spans_is_reported_as_confounded():
    true_effects = {**BASE, "position_dependent_backlash": {"b0_um": 3.0, "k_ppm": 10.0}}
    del true_effects["backlash"]
    result = run_discovery(true_effects, ["linear_scale", "position_dependent_backlash"])
    assert result.added == []
    assert any("backlash is confounded with position_dependent_backlash" in n for n in result.notes)
    assert any("cosine error" in note for note in result.notes)


LONG_PLAN = PLAN.replace("cycles = 5", "cycles = 10").replace("dwell_s = 2.0", "dwell_s = 10.0")
"""An 80-minute campaign (10 cycles, 10 s dwells) over which the air warms 4 K and the pressure
falls 4 hPa: a workshop warming in the morning as the weather turns."""
WARMING_AIR = Environment(air_temp_c=(20.0, 24.0), air_pressure_hpa=(1015.0, 1011.0), humidity_pct=(45.0, 45.0))


def test_environment_air_is_named_and_its_share_recovered_and_preferred_to_thermal_drift():
    """An instrument without air compensation: the reading carries x·(n/n0 - 1) (4.9 µm/m by the
    end). Thermal drift, pivoting at the laser datum, fits almost as well: the output says why the
    air log is preferred."""
    result = run_discovery(BASE, ["linear_scale", "backlash"], seed=5, config=parse_config(LONG_PLAN),
                           environment=WARMING_AIR)
    assert result.added == ["environment"], (result.added, result.notes)
    found = result.steps[0].params
    assert set(found) == {"air_factor"}
    assert found["air_factor"] == pytest.approx(1.0, rel=0.15)
    assert result.steps[0].errors["air_factor"] < 0.05
    assert result.gap_after_um <= 1.3 * NOISE_UM
    [choice] = result.choices
    assert choice.chosen == "environment" and choice.other == "thermal_drift"
    assert choice.pivot_at_laser_datum and abs(choice.pivot_mm) < 90
    assert choice.why in result.notes and "laser datum" in choice.why


def test_environment_material_is_named_and_alpha_recovered_when_the_air_log_moves_with_it():
    """The machine warms 1 K in 12 minutes and the table is not normalised to 20 °C (11.5 µm/m per
    K); the air warms too, but the instrument compensates it. The two logs ramp together, so
    their slopes are confounded: the air alone would need an impossible share."""
    env = Environment(air_temp_c=(20.0, 20.5), material_temp_c=(20.0, 21.0), air_factor=0.0, alpha_ppm_per_k=11.5)
    result = run_discovery(BASE, ["linear_scale", "backlash"], seed=5, environment=env)
    assert result.added == ["environment"], (result.added, result.notes)
    assert result.steps[0].params["alpha_ppm_per_k"] == pytest.approx(11.5, rel=0.15)
    assert result.gap_after_um <= 1.3 * NOISE_UM
    assert any("air and material logs move together" in n and "not physical" in n for n in result.notes)
    assert "environment" not in result.final_model().effects  # it follows one campaign's log


@pytest.mark.parametrize("seed", sweep(3, 4, 5))
def test_thermal_drift_with_a_flat_environment_log_is_not_named_environment(seed):
    flat = Environment(material_temp_c=(20.0, 20.0))
    result = run_discovery({**BASE, "thermal_drift": HIDDEN["thermal_drift"][0]}, ["linear_scale", "backlash"],
                           seed=seed, environment=flat)
    assert result.added == ["thermal_drift"], (result.added, result.notes)
    assert any("environment is not looked for" in n for n in result.notes)
    assert result.steps[0].params["pivot_mm"] == pytest.approx(300.0, abs=90)


def test_screw_growth_with_a_compensated_warming_air_log_is_thermal_drift_and_says_why():
    """The air log varies, but the instrument compensates it; the screw grows about its bearing at
    300 mm. Both candidates explain part of the slope change: thermal_drift is chosen, by the fit
    and by the pivot away from the laser datum."""
    env = Environment(air_temp_c=(20.0, 21.5), air_factor=0.0)
    true = {**BASE, "thermal_drift": {"growth_ppm": 20.0, "tau_s": 250.0, "pivot_mm": 300.0}}
    result = run_discovery(true, ["linear_scale", "backlash"], seed=4, environment=env)
    assert result.added == ["thermal_drift"], (result.added, result.notes)
    [choice] = result.choices
    assert choice.chosen == "thermal_drift" and not choice.pivot_at_laser_datum
    assert "away from the laser datum" in choice.why
    assert any("the instrument compensates the air" in n for n in result.notes)

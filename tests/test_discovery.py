"""Acceptance of issue 4 (discovery) on synthetic campaigns from campaign/simulate.py: one effect
hidden, two hidden at once, the null case over 100 seeds, and the confounding refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from campaign.config import parse_config
from campaign.discovery import discover
from campaign.discovery_data import campaign_data
from campaign.model import ErrorModel
from campaign.plan import build_plan
from campaign.simulate import simulate_campaign

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
"""Effect -> (its true parameters, the parameters checked to 15 %). A time constant is checked to
35 %: in a 12-minute campaign with 0.3 µm scatter it is the least determined parameter."""


def run_discovery(true_effects: dict, start_effects: list[str], seed: int = 3, dwell_jitter: float = 0.8):
    table = simulate_campaign(CONFIG, ErrorModel(true_effects), seed=seed, dwell_jitter=dwell_jitter)
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
    if "tau_s" in true_params:
        assert found["tau_s"] == pytest.approx(true_params["tau_s"], rel=0.35), found
    assert result.gap_after_um <= 1.3 * NOISE_UM
    assert result.gap_after_um < result.gap_before_um


@pytest.mark.parametrize("pair", [("periodic_lead", "thermal_drift"), ("nonlinear_lead", "settling"),
                                  ("backlash", "periodic_lead")])
def test_two_hidden_effects_are_both_named(pair):
    true_effects = {**BASE, **{name: HIDDEN[name][0] for name in pair}}
    start = [name for name in true_effects if name not in (*pair, "noise")]
    result = run_discovery(true_effects, start, seed=11)
    assert sorted(result.added) == sorted(pair), (result.added, result.notes)
    assert result.gap_after_um <= 1.3 * NOISE_UM


def test_null_case_names_nothing_in_at_least_95_of_100_seeds():
    true_effects = {**BASE, "nonlinear_lead": HIDDEN["nonlinear_lead"][0]}
    start = [name for name in true_effects if name != "noise"]
    named = [run_discovery(true_effects, start, seed=seed).added for seed in range(100)]
    assert sum(1 for added in named if not added) >= 95, [a for a in named if a]


def test_settling_at_a_constant_dwell_is_refused_as_confounded_with_backlash():
    true_effects = {**BASE, "settling": HIDDEN["settling"][0]}
    del true_effects["backlash"]
    result = run_discovery(true_effects, ["linear_scale"], dwell_jitter=0.0)
    assert "settling" not in result.added and "backlash" in result.added
    assert any("settling is confounded with backlash" in note for note in result.notes)


def test_an_effect_the_model_already_spans_is_reported_as_confounded():
    true_effects = {**BASE, "position_dependent_backlash": {"b0_um": 3.0, "k_ppm": 10.0}}
    del true_effects["backlash"]
    result = run_discovery(true_effects, ["linear_scale", "position_dependent_backlash"])
    assert result.added == []
    assert any("backlash is confounded with position_dependent_backlash" in n for n in result.notes)
    assert any("cosine error" in note for note in result.notes)

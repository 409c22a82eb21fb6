"""A drift in time that the campaign shows but does not pin down (issue 34 item 5: what the campaign
cannot tell goes to `unresolved` with how to tell; item 2: an effect whose values break the gates is
not named). Before, such a drift was only a note ("fails size under 2σ"), and the located drift in
time was neither said nor held. Now it is an unresolved group, held in the fit without a name, so the
gap shrinks (campaign.discovery.vocabulary.undetermined_drifts, held.hold_unresolved)."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.discovery.data import campaign_data
from campaign.discovery.effects import HELD_PREFIX
from campaign.discovery.fit import Term, linear_fit
from campaign.discovery.followup import plan_follow_up
from campaign.discovery.records import Unresolved
from campaign.discovery.result import Candidate
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.discovery.vocabulary import NEEDS, UNRESOLVED_VERDICTS, drift_entry, undetermined_drifts
from campaign.model import ErrorModel
from tests.discovery_draws import PLAN, draw, judge, plan_config
from tests.test_discovery import BASE, CONFIG

START = ErrorModel({"linear_scale": {}}), {"linear_scale": set()}
DRIFTS = sorted(name for name in ("linear_drift", "thermal_drift") if NEEDS.get(name) == "runs")


def test_only_a_drift_that_passed_the_tests_and_failed_the_gates_is_not_pinned_down():
    """Of the candidates of a step, a drift (an effect that needs runs) whose verdict follows passed
    tests ("not named (...)": its gates) is undetermined; one that failed the tests is not, nor is an
    effect along the travel with the same verdict, nor a drift already in an unresolved group. The
    record says each one's tests and gates, and their verdicts name each other (held together)."""
    data = campaign_data(simulate_campaign(CONFIG, ErrorModel(BASE), seed=2))
    fit = linear_fit(data, [Term("linear_scale"), Term("backlash")])
    gates = "not named (size under 2σ: rate_ppm_per_h 2.2 ± 7.4; not physical: pivot_mm = 3312 outside -1200 to 1800)"
    linear = Candidate("linear_drift", fit, explained_pct=17.6, p_value=4e-5, cv_before_um=0.74, cv_after_um=0.66,
                       verdict=gates)
    thermal = Candidate("thermal_drift", fit, explained_pct=17.3, p_value=2e-4, verdict="not named (size under 2σ)")
    failed = Candidate("thermal_drift", fit, verdict="not significant (BIC, F-test)")
    bow = Candidate("nonlinear_lead", fit, verdict="not named (size under 2σ: p2_um 0.1 ± 0.2)")
    unfitted = Candidate("linear_drift", None, verdict="not named (size under 2σ)")

    assert undetermined_drifts([linear, failed, bow, unfitted], [], fit) == [linear]
    assert undetermined_drifts([linear, thermal, bow], [], fit) == [linear, thermal]
    # beside a drift named already, another shape of it is not a drift of its own
    assert undetermined_drifts([thermal], [], linear_fit(data, [*fit.terms, Term("linear_drift")])) == []
    grouped = Unresolved(("linear_drift", "environment"), "rivals", "a log")
    assert undetermined_drifts([linear, thermal], [grouped], fit) == [thermal]

    entry = drift_entry([linear, thermal], "µm")
    assert entry.effects == ("linear_drift", "thermal_drift")
    assert "does not pin it down" in entry.why and "pivot_mm = 3312 outside -1200 to 1800" in entry.why
    assert "F-test p = 4e-05" in entry.why and "0.74 -> 0.66 µm" in entry.why
    assert "runs" in entry.how_to_tell
    assert entry.not_pinned_down and entry.as_dict()["not_pinned_down"] is True
    assert "not_pinned_down" not in grouped.as_dict()
    assert linear.verdict.startswith(UNRESOLVED_VERDICTS) and "thermal_drift" in linear.verdict
    assert thermal.verdict.startswith(UNRESOLVED_VERDICTS) and "linear_drift" in thermal.verdict


def test_a_drift_not_pinned_down_as_the_stand_in_beside_a_reversal_stays_out_of_the_saved_model():
    """A reversal at a constant wait (backlash or settling: the stand-in backlash is kept) beside a drift
    whose pivot lies beyond the travel (10 ppm/h about 5,000 mm): the drift is the search's stand-in, the
    reversal found beside it. Before, the reversal's fit beside the drift became the final model, and
    linear_drift was saved with the model while said to be unresolved and not named (a reviewer's case)."""
    from tests.test_discovery import READING_UM, SIGMA_UM

    true = {"linear_scale": {"ppm": -12.4}, "backlash": {"b_um": 1.0},
            "linear_drift": {"rate_ppm_per_h": 10.0, "pivot_mm": 5000.0},
            "noise": {"sigma_um": SIGMA_UM, "reading_sigma_um": READING_UM}}
    result = discover(campaign_data(simulate_campaign(CONFIG, ErrorModel(true), seed=3)), *START)
    group = next(u for u in result.unresolved if "linear_drift" in u.effects)
    assert group.not_pinned_down
    assert not set(group.effects) & (set(result.added) | set(result.params()) | set(result.final_model().effects))
    assert result.stand_in is not None and result.stand_in.effect == "backlash"
    held = next(h for h in result.held if set(h.rivals) == set(group.effects))
    assert "not pinned down" in held.observable


def _drawn(count: int, offsets: str, seed: int):
    config = plan_config(count, offsets)
    truth = draw(np.random.default_rng(seed), "linear_growth", config)
    data = campaign_data(simulate_campaign(config, ErrorModel(truth.model), seed=seed, dwell_jitter=0.8))
    return truth, data


@pytest.mark.machine  # a simulated campaign and its discovery
def test_a_drift_whose_rate_and_pivot_the_campaign_cannot_pin_down_is_unresolved_and_held(tmp_path):
    """A slope growing 23 ppm/h pivoting at 597 mm, beside a bow, on 11 uniform targets, noise 0.66 µm
    (bench seed 97, draw 16276): the linear drift passes the three tests (F-test p 4e-5, a better CV)
    but its rate is 2.2 ± 7.4 ppm/h pivoting at 3,312 mm, outside the physical range. It is not named;
    it is unresolved with how to tell, held in the fit by its form, and the gap is smaller for it."""
    truth, data = _drawn(11, "none", 16276)
    result = discover(data, *START)
    group = next(u for u in result.unresolved if "linear_drift" in u.effects)
    assert not set(group.effects) & set(result.added)
    assert "does not pin it down" in group.why and group.how_to_tell
    held = next(h for h in result.held if set(h.rivals) == set(group.effects))
    assert "not pinned down" in held.observable
    assert any(t.name == HELD_PREFIX + held.effect for t in result.final.terms)
    assert not set(group.effects) & set(result.final_model().effects)
    assert result.gap_after_um < held.gap_without_um
    assert judge(result, truth).stated
    # a follow-up fitted with this campaign starts its time again: not planned, and said why
    follow = plan_follow_up(result.unresolved, result.remaining, data, result.final, plan_config(11, "none"), None,
                            result.noise_um, tmp_path / "follow.toml", [])
    assert follow is not None and not follow.parts
    assert any("does not pin down" in why for why in follow.unplanned), follow.unplanned


WEAK = 0.5
"""The drawn growth's rate is scaled by this: slopes of 1-2 µm over the campaign, near what it can show."""


@pytest.mark.machine  # four simulated campaigns and their discoveries
def test_no_drift_that_passed_the_tests_is_left_as_a_note():
    """Weak slopes growing linearly in time (drawn as the bench draws them, any rate and pivot, beside a
    random bow, backlash and scale, the rate then halved: WEAK), four draws on 17 uniform targets: at the
    end every drift that passed the three tests is named within its gates or in an unresolved group, never
    only a note, and no drift is both named and unresolved. (One of the four, draw 30775, has such a drift:
    before, it was a note.)"""
    config = plan_config(17, "none")
    for k in range(4):
        seed = 7001 + 7919 * k + 17
        truth = draw(np.random.default_rng(seed), "linear_growth", config)
        drift = truth.model["linear_drift"]
        model = {**truth.model, "linear_drift": {**drift, "rate_ppm_per_h": drift["rate_ppm_per_h"] * WEAK}}
        data = campaign_data(simulate_campaign(config, ErrorModel(model), seed=seed, dwell_jitter=0.8))
        result = discover(data, *START)
        unresolved = {name for u in result.unresolved for name in u.effects}
        for cand in result.remaining:
            if cand.name in DRIFTS:
                assert not cand.verdict.startswith("not named ("), (seed, cand.name, cand.verdict, result.added)
        assert not unresolved & (set(result.added) | set(result.params())) & set(DRIFTS), (
            seed, result.added, result.unresolved)


M16 = (PLAN.format(count=13, offsets="golden").replace("cycles = 5", "cycles = 4").replace("dwell_s = 2.0", "dwell_s = 4.0")
       .replace("velocity = 20.0", "velocity = 10.0").replace("offset_fraction = 0.45\n", "")
       .replace("[plan]\n", "[plan]\nseed = 3\n"))
"""The user's trial's plan (13 golden targets, 4 cycles, a fixed 4 s dwell) on the draws' 600 mm axis."""


@pytest.mark.parametrize("seed", [6, *(pytest.param(s, marks=pytest.mark.machine) for s in (9, 11, 13))])
def test_a_reversal_unresolved_beside_an_unresolved_drift_stays_in_the_model(seed):
    """A thermal drift (15 µm/m, τ 900 s) beside a 4 µm backlash, 13 golden targets at a fixed dwell (a
    user's trial). When both are unresolved, the position-dependent backlash held with the reversal
    stood in for it, backlash was tried beside it (confounded), and the reversal's group was dropped:
    nothing said the 4 µm reversal was there, and the model lost it (4 of 15 seeds, these four). Now the
    stand-in's group is kept (vocabulary.stand_in_group)."""
    from campaign.config import parse_config

    truth = {"linear_scale": {"ppm": 4.0}, "thermal_drift": {"growth_ppm": 15.0, "tau_s": 900.0, "pivot_mm": 600.0},
             "backlash": {"b_um": 4.0}, "noise": {"sigma_um": 0.4, "reading_sigma_um": 0.04}}
    data = campaign_data(simulate_campaign(parse_config(M16, "m16.toml"), ErrorModel(truth), seed=seed))
    result = discover(data, *START)
    assert any(u.effects == ("backlash", "settling") for u in result.unresolved), result.unresolved
    assert result.stand_in is not None and result.stand_in.effect == "backlash"
    assert 3.0 < result.params()["backlash"]["b_um"] < 5.0
    assert result.gap_after_um < 1.3 * result.noise_um
    assert "thermal_drift" in result.added or any("thermal_drift" in u.effects for u in result.unresolved)
    # saved, the stand-in says what it stands in for (a user's trial: saved as a backlash with no word)
    from campaign.commands.discover import saved_model

    saved = saved_model(result, START[0], "points.csv", data.time_source)
    assert "# Not named: [effects.backlash] stands in for backlash or settling" in saved
    assert "[effects.backlash]\nb_um = " in saved


def test_an_effect_named_beside_a_stand_in_is_said_at_the_step_with_the_values_it_was_tested_with():
    """Named beside the stand-in reversal, the drift's step gave its values refitted without it, where the
    reversal's residual swells them (a user's trial: the step said 18.8 ± 14 µm/m per h, failing the 2σ
    gate the drift had passed, for a drift the summary gave as 35.8 ± 2.8)."""
    from campaign.config import parse_config

    truth = {"linear_scale": {"ppm": 4.0}, "thermal_drift": {"growth_ppm": 15.0, "tau_s": 900.0, "pivot_mm": 600.0},
             "backlash": {"b_um": 4.0}, "noise": {"sigma_um": 0.4, "reading_sigma_um": 0.04}}
    result = discover(campaign_data(simulate_campaign(parse_config(M16, "m16.toml"), ErrorModel(truth), seed=1)),
                      *START)
    assert result.stand_in is not None and result.added == ["thermal_drift"]
    step = result.steps[0]
    final, errors = result.params()["thermal_drift"], result.errors["thermal_drift"]
    for key in ("growth_ppm", "tau_s"):
        assert step.params[key] == pytest.approx(final[key], rel=0.02)
        assert step.errors[key] == pytest.approx(errors[key], rel=0.1)
        assert abs(step.params[key]) > 2 * step.errors[key]  # the gate it passed, as said

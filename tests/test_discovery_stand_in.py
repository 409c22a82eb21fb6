"""Issue 24, item 1: the gap shrinks by what is known. A reversal that backlash and settling (at a
constant wait) explain alike is put in the model as a stand-in, named by what the data show, and
the pair stays unresolved; rivals that predict differently between the measured points (aliased
periods) get none (fast tier: tables written as a user's fixed-dwell ISO 230-2 file, no wait
column)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import sweep


def iso_table(path, deviation, kind="linear", runs=5, targets=11, spacing=60.0, seed=3):
    """A fixed-dwell table without capture_wait_s: `deviation(x, d, rng)` per point, targets with
    the golden-ratio offsets ISO 230-2 asks for."""
    rng = np.random.default_rng(seed)
    unit, dev = ("mm", "um") if kind == "linear" else ("deg", "arcsec")
    rows = []
    for run in range(1, runs + 1):
        for d in (1, -1):
            for i in (range(targets) if d > 0 else reversed(range(targets))):
                x = spacing * i + (i * 0.618034 % 1) * spacing * 0.1
                rows.append(f"{run},{'+' if d > 0 else '-'},{x:.4f},{deviation(x, d, rng):.4f}")
    path.write_text(f"run,direction,target_{unit},deviation_{dev}\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.machine
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_constant_reversal_without_a_wait_column_is_a_stand_in(cli, tmp_path, seed):
    table = iso_table(tmp_path / "p.csv", lambda x, d, rng: 0.012 * x - d * 3.0 + rng.normal(0, 0.5), seed=seed)
    said = cli("discover", table, "--json")
    assert said.code == 0, said.err
    out = json.loads(said.out)
    assert out["gap_before_um"] > 2.5 and out["gap_after_um"] <= 1.3 * out["noise_um"]
    assert out["added"] == [] and out["stand_in"]["effect"] == "backlash"  # in the model, not named
    assert out["stand_in"]["params"]["b_um"] == pytest.approx(6.0, abs=0.4)
    assert "cannot tell which" in out["stand_in"]["observable"] and "settling" in out["stand_in"]["observable"]
    assert any(set(u["effects"]) == {"backlash", "settling"} for u in out["unresolved"])
    assert out["model"]["backlash"]["b_um"] == pytest.approx(out["stand_in"]["params"]["b_um"])
    text = cli("discover", table)
    assert "in the model as a stand-in" in " ".join(text.out.split())


def test_a_rotary_table_reversal_is_a_stand_in_too(cli, tmp_path):
    table = iso_table(tmp_path / "r.csv", lambda x, d, rng: 0.01 * x - d * 2.0 + rng.normal(0, 0.8),
                      kind="rotary", targets=13, spacing=30.0)
    out = json.loads(cli("discover", table, "--json").out)
    assert out["stand_in"]["effect"] == "backlash" and out["gap_after_um"] <= 1.3 * out["noise_um"]
    assert "arcsec" in out["stand_in"]["observable"] and "µm" not in out["stand_in"]["observable"]
    text = " ".join(cli("discover", table).out.split())
    assert "arcsec (backlash or settling)" in text
    assert "µm" not in text and "arcsec RMS" in text  # the gap too (the old code said µm everywhere)


def test_an_aliased_period_gets_no_stand_in(cli, tmp_path):
    """A 10 mm lead seen at 11 targets 60 mm apart: periods that fit alike predict differently
    between the targets, so none is put in the model. What the targets show of it is held in the fit
    by the best candidate (issue 34: the gap shrinks by what the data show), said in `held`, not saved."""
    table = iso_table(tmp_path / "a.csv", lambda x, d, rng: 3.0 * np.sin(2 * np.pi * x / 10.0) + rng.normal(0, 0.3))
    out = json.loads(cli("discover", table, "--json").out)
    assert [u["effects"] for u in out["unresolved"]] == [["periodic_lead"]]  # there, but not pinned down
    assert out["stand_in"] is None and "periodic_lead" not in out["model"] and out["added"] == []
    assert [h["rivals"] for h in out["held"]] == [["periodic_lead"]]
    assert out["held"][0]["gap_without_um"] == out["gap_before_um"] > 3 * out["gap_after_um"]


@pytest.mark.parametrize("seed", sweep(2, 1))
@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_no_stand_in_where_the_waits_vary(seed):
    """Waits varying by ±10 % about 4 s and a slow settling (τ 8 s): backlash and settling are rivals
    (the rivals path, not the constant-wait one). The old code put a stand-in in the model on seed 1
    (backlash) and on seed 2, where settling explains a little more and was tried beside the others,
    raised KeyError 'b_um'. Where the waits vary the two predict different deviations, so neither
    stands in; the pair stays unresolved."""
    from campaign.discovery.data import campaign_data
    from campaign.discovery.search import discover
    from campaign.discovery.simulate import simulate_campaign
    from campaign.model import ErrorModel
    from tests.test_discovery_loop import BOW, user_config

    machine = {**BOW, "settling": {"e0_um": 4.0, "tau_s": 8.0}}
    table = simulate_campaign(user_config(), ErrorModel(machine), seed=seed, dwell_jitter=0.1)
    result = discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert any(set(u.effects) == {"backlash", "settling"} for u in result.unresolved)
    assert result.remaining_beside == {1: "backlash", 2: "settling"}[seed]
    assert result.stand_in is None and "backlash" not in result.params() and "settling" not in result.params()


@pytest.mark.machine
def test_the_stand_in_is_the_backlash_even_when_settling_is_tried_beside():
    """A wait column that does not vary (the fixed dwell, recorded): the stand-in is the backlash."""
    from campaign.discovery.data import campaign_data
    from campaign.discovery.search import discover
    from campaign.discovery.simulate import simulate_campaign
    from campaign.discovery.vocabulary import waits_vary
    from campaign.model import ErrorModel
    from tests.test_discovery_loop import BOW, user_config

    table = simulate_campaign(user_config(), ErrorModel({**BOW, "backlash": {"b_um": 3.0}}), seed=1)
    data = campaign_data(table)
    assert data.w is not None and not waits_vary(data)
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert result.stand_in is not None and result.stand_in.effect == "backlash"
    assert abs(result.stand_in.params["b_um"]) == pytest.approx(3.0, abs=0.5)


@pytest.mark.parametrize("seed", sweep(3, 7))
def test_one_short_capture_in_a_fixed_dwell_campaign_does_not_make_the_waits_vary(seed):
    """A fixed-dwell campaign where one point (or a few) was captured with fewer samples or a
    shorter wait: one wait cannot tell settling from a constant reversal (it made the waits 'vary'
    and backlash was named outright on a 4,000-point table). A ladder of waits at a few targets, as
    a follow-up asks, does vary them."""
    import dataclasses

    from campaign.discovery.data import campaign_data
    from campaign.discovery.simulate import simulate_campaign
    from campaign.discovery.vocabulary import VARIED_WAIT_POINTS, waits_vary
    from campaign.model import ErrorModel
    from tests.test_discovery_loop import BOW, user_config

    rng = np.random.default_rng(seed)
    data = campaign_data(simulate_campaign(user_config(), ErrorModel({**BOW, "backlash": {"b_um": 3.0}}), seed=seed))
    assert data.w is not None and not waits_vary(data)
    typical = float(np.nanmedian(data.w))
    for changed in (1, VARIED_WAIT_POINTS - 1, VARIED_WAIT_POINTS):
        w = data.w.copy()
        rows = rng.choice(len(data), changed, replace=False)
        w[rows] = w[rows] * rng.choice([0.5, 0.8, 1.5, 2.5], (changed, 1))  # the ladder's other waits
        assert waits_vary(dataclasses.replace(data, w=w)) == (changed >= VARIED_WAIT_POINTS), (changed, typical)


@pytest.mark.machine
@pytest.mark.parametrize("seed", [4, 5, 6])
def test_a_drift_beside_an_unresolved_reversal_is_gated_beside_what_holds_it(seed):
    """A slope growing 25-45 µm/m per hour about a drawn pivot beside a 3-4 µm backlash, the waits
    varying a little (dwell jitter 0.1 s): backlash and settling stay rivals, no stand-in kept, and the drift, found beside the
    reversal as a stand-in, was then gated beside a model without it, its rate's error swollen by the
    reversal left in the residual (a draw said 10.5 ± 16 µm/m per h for 26), and not named. Gated beside
    the stand-in (held in the final model), it is named, within 3σ of the truth, and passes the gates."""
    from campaign.discovery.data import campaign_data
    from campaign.discovery.naming import gate_failures
    from campaign.discovery.search import discover
    from campaign.discovery.simulate import simulate_campaign
    from campaign.model import ErrorModel
    from tests.discovery_draws import plan_config

    rng = np.random.default_rng(seed)
    rate = float(rng.uniform(25.0, 45.0)) * float(rng.choice([-1.0, 1.0]))
    machine = {"linear_scale": {"ppm": float(rng.uniform(-10, 10))}, "backlash": {"b_um": float(rng.uniform(3, 4))},
               "linear_drift": {"rate_ppm_per_h": rate, "pivot_mm": float(rng.uniform(100, 500))},
               "noise": {"sigma_um": 0.6}}
    table = simulate_campaign(plan_config(17, "golden"), ErrorModel(machine), seed=seed, dwell_jitter=0.1)
    data = campaign_data(table)
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert any(set(u.effects) == {"backlash", "settling"} for u in result.unresolved)
    assert result.added == ["linear_drift"], result.notes
    fitted, error = result.params()["linear_drift"]["rate_ppm_per_h"], result.errors["linear_drift"]["rate_ppm_per_h"]
    assert abs(fitted - rate) < 3 * error, (fitted, error, rate)
    assert not gate_failures(data, result.final, "linear_drift")


@pytest.mark.machine  # 8 drawn campaigns and their discoveries, about 30 s
def test_a_step_beside_an_unresolved_reversal_is_located():
    """A 2-3 µm step rising over 10-40 mm at a drawn place beside a 3-4 µm backlash on 17 golden targets,
    the waits varying a little: where backlash and settling stay rivals (at least 3 of 8 draws), the
    local grid, searched beside the vocabulary alone, saw the reversal left in the residual and found
    nothing, and the unresolved period's stand-in then soaked the step (a drawn step at 197 mm was
    neither located nor stated). Looked for beside what the unresolved reversal holds (held_fit), it is
    located within 10 mm or said between the two targets either side of it."""
    from campaign.discovery.data import campaign_data
    from campaign.discovery.search import discover
    from campaign.discovery.simulate import simulate_campaign
    from campaign.model import ErrorModel
    from tests.discovery_draws import plan_config

    checked = []
    for seed in range(7, 15):
        rng = np.random.default_rng(seed)
        at = float(rng.uniform(150.0, 450.0))
        machine = {"linear_scale": {"ppm": float(rng.uniform(-10, 10))},
                   "backlash": {"b_um": float(rng.uniform(3, 4))},
                   "local_step": {"height_um": float(rng.uniform(2, 3)) * float(rng.choice([-1.0, 1.0])), "at_mm": at,
                                  "rise_mm": float(rng.uniform(10, 40))},
                   "noise": {"sigma_um": 0.7}}
        table = simulate_campaign(plan_config(17, "golden"), ErrorModel(machine), seed=seed, dwell_jitter=0.1)
        result = discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
        if not any(set(u.effects) == {"backlash", "settling"} for u in result.unresolved):
            continue
        checked.append(seed)
        assert any(abs(e.params["centre_mm"] - at) <= 10.0 or (e.between_mm is not None
                                                               and e.between_mm[0] <= at <= e.between_mm[1])
                   for e in result.local_errors), (seed, at, [e.sentence() for e in result.local_errors])
    assert len(checked) >= 3, checked

"""Issue 34, done when: "gap after within 1.3 × the noise wherever a local term can hold it". Machines
drawn at random with an error discovery has no name for (tests/discovery_draws.py); where the targets
show it so that a local term can hold it (tests/discovery_gaps.py: a step, or every region seen at two
targets or more, and the final model beside the true deviation within 1.3 × the noise), the gap
after is within 1.3 × the noise; and what the final model leaves holds no local term that passes
the tests (campaign.discovery.unnamed.hold_what_is_left)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.discovery.data import campaign_data
from campaign.discovery.local import find_local, is_local
from campaign.discovery.locate import locate
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.discovery.unnamed import held_regions, within_targets
from campaign.model import ErrorModel
from tests.discovery_draws import SHAPES, draw, judge, plan_config
from tests.discovery_gaps import holdable, oracle_ratio, out_of_vocabulary_um

LIMIT = 1.3


def _discovered(shape: str, count: int, offsets: str, seed: int):
    config = plan_config(count, offsets)
    truth = draw(np.random.default_rng(seed), shape, config)
    data = campaign_data(simulate_campaign(config, ErrorModel(truth.model), seed=seed + 3000, dwell_jitter=0.8))
    return truth, data, discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})


@pytest.mark.machine  # 20 simulated campaigns and discoveries (bench/discovery_gaps.py: 144 a seed)
def test_the_gap_is_within_1_3_noise_wherever_a_local_term_can_hold_it():
    """Every out-of-vocabulary shape at 17 and 21 targets, golden and uniform, drawn per seed: of the
    draws whose error a local term can hold (and whose model beside the true error leaves noise only),
    at most one in twenty ends above 1.3 × the noise (before the final model's leftovers were located
    again and held, steps beside an unresolved period and waves seen at a few targets stayed there)."""
    above, holdable_draws = [], 0
    for shape in SHAPES:
        for count, offsets in ((17, "golden"), (17, "none"), (21, "golden"), (21, "none")):
            for seed in (911,):
                truth, data, result = _discovered(shape, count, offsets, seed + 37 * count)
                column = out_of_vocabulary_um(truth, data.x, data.d, data.t)
                if not holdable(truth, data, column).startswith(("yes", "step")):
                    continue
                if oracle_ratio(data, result, column) > LIMIT:
                    continue  # the rest of the model leaves more than noise: not a local term's gap
                holdable_draws += 1
                ratio = judge(result, truth).gap_ratio
                if ratio > LIMIT:
                    above.append((shape, count, offsets, seed, round(ratio, 2), result.added,
                                  [e.sentence() for e in result.local_errors]))
    assert holdable_draws >= 5
    assert len(above) <= 0.05 * holdable_draws, (holdable_draws, above)


@pytest.mark.machine  # 8 simulated campaigns and discoveries
@pytest.mark.parametrize("shape", ["step", "bump", "two_regions", "partial_wave"])
def test_what_the_final_model_leaves_holds_no_local_term(shape):
    """What the final model leaves, located again: no region term over it (its flexibility chosen by
    cross-validation) and no bump or step passes the local tests beside the final model. Beside an
    unresolved period a region term must pass beside its best candidate too, and no bump or step is
    tried (one there may be that period seen at a few targets: it is listed as the period's rival)."""
    left = []
    for count, offsets in ((17, "none"), (21, "golden")):
        for seed in (921,):
            _, data, result = _discovered(shape, count, offsets, seed + 37 * count)
            final = result.final
            index = 1 + sum(1 for t in final.terms if t.name.startswith("local_region"))
            period = next((c for c in result.remaining if c.name == "periodic_lead" and c.fit is not None), None)
            beside = ([t for t in period.fitted.terms if t.name == "periodic_lead"] if period is not None
                      and any("periodic_lead" in u.effects for u in result.unresolved) else [])
            regions = held_regions(data, final, locate(data, data.y - final.prediction), index, beside)
            taken = {int(t.name.split("#")[1]) if "#" in t.name else 1 for t in final.terms
                     if is_local(t) and not t.name.startswith("local_region")}
            more = None if beside else find_local(data, final, max(taken, default=0) + 1)
            if regions or (more is not None and within_targets(data, more.term)):
                left.append((count, offsets, seed, [t.shape for t in regions], more and more.sentence()))
    assert not left, left


@pytest.mark.machine  # 12 simulated campaigns and discoveries
def test_an_unresolved_reversal_is_held_in_the_fit_and_never_named():
    """Issue 34: what the data show still goes into the model. A small backlash (0.6-1.5 µm) recorded
    with waits that vary by about ±40 %: where discovery cannot tell it from settling, the reversal is
    held in the final fit by the better rival's form, so the gap ends within 1.3 × the noise (it stayed
    above when nothing held it); the pair stays unresolved with how to tell, nothing is named, saved
    or listed in the model for it, and --json says it under `held`."""
    from campaign.commands.discover import as_json

    unresolved = 0
    for seed in range(60, 72):
        rng = np.random.default_rng(seed)
        machine = {"linear_scale": {"ppm": float(rng.uniform(-15, 15))},
                   "backlash": {"b_um": float(rng.uniform(0.6, 1.5))}, "noise": {"sigma_um": float(rng.uniform(0.3, 0.8))}}
        data = campaign_data(simulate_campaign(plan_config(17, "golden"), ErrorModel(machine), seed=seed,
                                               dwell_jitter=0.8))
        result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
        if not any(set(u.effects) == {"backlash", "settling"} for u in result.unresolved):
            assert "backlash" in result.added, (seed, result.added)
            continue
        unresolved += 1
        assert [set(h.rivals) for h in result.held] == [{"backlash", "settling"}], seed
        assert not {"backlash", "settling"} & set(result.added)
        assert not {"backlash", "settling"} & set(result.params())
        assert not {"backlash", "settling"} & set(result.final_model().effects)
        assert result.held[0].gap_without_um > result.gap_after_um
        assert result.gap_after_um <= LIMIT * result.noise_um, (seed, result.gap_after_um, result.noise_um)
        out = as_json(result)
        assert out["held"][0]["rivals"] in (["backlash", "settling"], ["settling", "backlash"])
        assert any(set(u["effects"]) == {"backlash", "settling"} and u["how_to_tell"] for u in out["unresolved"])
        assert not {"backlash", "settling"} & set(out["model"])
        assert not [k for k in (*out["model"], *out["model_standard_errors"]) if k.startswith("held_")]
    assert unresolved >= 2


@pytest.mark.parametrize("shape, count, seed, sim_seed", [
    ("skewed_bump", 21, 302, 5302),  # no bow: a bow beside a step and a bump fitted a skewed bump as well
])
def test_an_effect_local_terms_fit_as_well_is_held_not_named_nor_replaced(cli, tmp_path, shape, count, seed,
                                                                          sim_seed):
    """Issue 34 item 2 (a): bumps in a bow's place predicted left-out targets as well, with their places
    chosen on all the targets; with their places searched again in each fold they do not win. The
    campaign cannot tell the bow from local errors there: it is neither named nor replaced by the bumps
    (the first case had a bow and said a local error, the second had none and named it). It holds what
    it explains (`held`), an unresolved group lists the local errors as its rivals, and the follow-up
    measures over them instead of calling the group unplanned."""
    from campaign.commands.discover import as_json
    from campaign.pointtable import write_points

    config = plan_config(count, "none")
    truth = draw(np.random.default_rng(seed), shape, config)
    table = simulate_campaign(config, ErrorModel(truth.model), seed=sim_seed, dwell_jitter=0.8)
    result = discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert "nonlinear_lead" not in result.added
    group = next(u for u in result.unresolved if u.effects == ("nonlinear_lead",))
    assert group.local_rivals and "denser targets over" in group.how_to_tell
    assert [h.effect for h in result.held] == ["nonlinear_lead"]
    assert result.gap_after_um <= LIMIT * result.noise_um
    assert not [name for name in result.added if name not in truth.vocabulary | {"linear_scale"}]
    if shape == "null":
        assert not result.local_errors
    else:
        assert judge(result, truth).located
    out = as_json(result)
    assert out["held"][0]["effect"] == "nonlinear_lead" and "nonlinear_lead" not in out["model"]
    directory = tmp_path / "first"
    directory.mkdir()
    (directory / "config.toml").write_text(config.text)
    write_points(directory / "points.csv", table)
    said = cli("discover", directory / "points.csv", "--follow-up", "-o", tmp_path / "follow.toml", "--json")
    assert said.code == 0, said.err
    follow = json.loads(said.out)["follow_up"]
    assert follow is not None and not any("nonlinear_lead" in u for u in follow["unplanned"]), follow
    lo, hi = group.local_rivals[0].region_mm
    assert any(lo - 1 <= t <= hi + 1 for t in follow["targets"]), (group.local_rivals, follow["targets"])


def test_a_small_bow_no_bump_stands_in_for_is_named():
    """A null draw with a 0.3 µm P3 bow (seed 16489, 21 uniform targets): a 0.66 µm bump at 151 mm once
    fitted it as well, so the bow was held, not named. With two neighbouring targets' departure among the
    grid's candidates the local terms no longer take the bow's place: the bow and the backlash the machine has are named, within 3σ of the truth, and nothing else."""
    config = plan_config(21, "none")
    truth = draw(np.random.default_rng(16489), "null", config)
    table = simulate_campaign(config, ErrorModel(truth.model), seed=16489, dwell_jitter=0.8)
    result = discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert set(result.added) == {"backlash", "nonlinear_lead"} and not result.local_errors and not result.unresolved
    for name, key in (("nonlinear_lead", "p3_um"), ("backlash", "b_um")):
        fitted, error = result.params()[name][key], result.errors[name][key]
        assert abs(fitted - truth.model[name][key]) <= 3 * error, (name, fitted, error, truth.model[name])


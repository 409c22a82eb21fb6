"""Issue 34 item 8: discovery tried on errors it was never taught, drawn at random the way real axes
make them (tests/discovery_draws.py), and on null machines. The full table is bench/discovery_draws.py
(docs/discovery.md); here a sweep in the machine tier."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from campaign.discovery.data import campaign_data
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from tests.discovery_draws import SHAPES, draw, judge, plan_config

DRAWN_PLANS = ((11, "golden"), (17, "none"), (21, "golden"), (21, "none"))
"""The plans the out-of-vocabulary sweeps below draw on (targets, offsets)."""
DRAWN_SEEDS = (601, 602)
_DISCOVERED: dict[tuple[str, int, str, int], tuple] = {}


def discovered(shape: str, count: int, offsets: str, seed: int):
    """The truth drawn and what discovery says of its simulated campaign: each computed once per process
    (the two sweeps share their draws, and xdist_group keeps them on one worker)."""
    key = (shape, count, offsets, seed)
    if key not in _DISCOVERED:
        config = plan_config(count, offsets)
        truth = draw(np.random.default_rng(seed), shape, config)
        table = simulate_campaign(config, ErrorModel(truth.model), seed=seed + 5000, dwell_jitter=0.8)
        result = discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
        _DISCOVERED[key] = truth, result
    return _DISCOVERED[key]


@pytest.mark.machine  # 24 simulated campaigns and discoveries
def test_null_machines_name_nothing_and_locate_nothing():
    """The vocabulary part alone (a random bow, backlash and scale, noise 0.3-0.8 µm): no effect the
    machine lacks is named and no local error is found, in at least 95 % of draws (here: all but one
    of 24)."""
    said = []
    for seed in range(200, 206):
        for count, offsets in ((11, "golden"), (17, "none"), (21, "golden"), (21, "none")):
            truth, result = discovered("null", count, offsets, seed)
            false = [n for n in result.added if n not in truth.vocabulary and n != "linear_scale"]
            if false or result.local_errors:
                said.append((seed, count, offsets, false, [e.sentence() for e in result.local_errors]))
    assert len(said) <= 1, said


@pytest.mark.machine  # 48 simulated campaigns and discoveries (32 shared with the sweep below)
@pytest.mark.xdist_group("discovery_draws")
def test_out_of_vocabulary_draws_name_no_effect_the_machine_lacks():
    """Over random out-of-vocabulary draws (every shape, 11, 17 and 21 targets, golden and uniform): no
    vocabulary effect the machine lacks is named in at least 95 % of draws."""
    false = []
    for shape in SHAPES:
        for count, offsets in DRAWN_PLANS:
            for seed in DRAWN_SEEDS:
                truth, result = discovered(shape, count, offsets, seed)
                judged = judge(result, truth)
                if judged.false_names:
                    false.append((shape, count, offsets, seed, judged.said))
    assert len(false) <= 0.05 * len(SHAPES) * len(DRAWN_PLANS) * len(DRAWN_SEEDS), false


@pytest.mark.machine  # 32 simulated campaigns and discoveries (the bench: 144 a seed)
@pytest.mark.xdist_group("discovery_draws")
def test_out_of_vocabulary_errors_are_located_or_stated_with_their_region():
    """Issue 34's done-when: every visible out-of-vocabulary error located (a region within its width,
    a step within 10 mm), or stated as unexplained structure with its region (a region the locator finds
    in what the final model leaves, within the same tolerance), or a step said to lie between the two
    targets either side of it: in at least 90 % of the visible draws of bumps, two regions, waves over
    part of the travel and steps (11, 17 and 21 targets, golden and uniform; seeds the bench does not
    use). Among them: errors one target sees beside a reversal, and waves shorter than the spacing
    beside an unresolved period."""
    visible, missed = 0, []
    for shape in ("bump", "two_regions", "partial_wave", "step"):
        for count, offsets in DRAWN_PLANS:
            for seed in DRAWN_SEEDS:
                truth, result = discovered(shape, count, offsets, seed)
                if not truth.visible:
                    continue
                visible += 1
                judged = judge(result, truth)
                if not (judged.stated or judged.bracketed):
                    missed.append((shape, count, offsets, seed, judged.said))
    assert visible >= 20 and len(missed) <= 0.1 * visible, missed


def test_the_oracle_tells_an_error_the_campaign_shows_from_one_it_cannot():
    """oracle_p (the bench's "beyond"): a step of 3.6 µm at 403 mm on 11 targets beside a bow and a
    backlash is shown far beyond p 0.001 when its exact deviation is fitted; the same step a
    thousandth as high is not; a null machine has nothing to show (1.0)."""
    from tests.discovery_draws import oracle_p

    config = plan_config(11, "golden")
    truth = draw(np.random.default_rng(353), "step", config)
    assert truth.model["local_step"]["height_um"] == pytest.approx(-3.577, abs=1e-3)
    data = campaign_data(simulate_campaign(config, ErrorModel(truth.model), seed=353, dwell_jitter=0.8))
    assert oracle_p(data, truth) < 1e-6
    small = {**truth.model, "local_step": {**truth.model["local_step"], "height_um": -3.577e-3}}
    faint = replace(truth, model=small)
    data = campaign_data(simulate_campaign(config, ErrorModel(small), seed=353, dwell_jitter=0.8))
    assert oracle_p(data, faint) > 0.001
    null = draw(np.random.default_rng(5), "null", config)
    assert oracle_p(data, null) == 1.0

"""A local error's other shape (campaign.discovery.local.other_shape, for rivals.shape_rivals) is fitted
as a local error found is: the grid's best in both directions, its shape the grid's own when refinement
takes it past what the targets can tell. Draw 16233 of bench seed 53 (a 3.7 µm wave of period 37 mm
over 137-280 mm beside a bow and a 3.2 µm backlash, 11 golden targets), simulated as the bench simulates
it."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.discovery.data import campaign_data
from campaign.discovery.effects import fixed_shape
from campaign.discovery.fit import Term, linear_fit
from campaign.discovery.local import MIN_SEEN, other_shape, seen_at
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from tests.discovery_draws import draw, plan_config


@pytest.mark.parametrize("beside_bow", [False, True])
def test_the_other_shape_is_a_bump_in_both_directions_the_targets_see(beside_bow):
    """Beside the backlash (and the bow) the grid's best bump is at 256 (266) mm, 122 (133) mm wide;
    refined, it was 264 (274) mm and 99 (109) mm wide, which the targets (58 mm apart on average) see at
    half its height at two, fewer than a bump needs: the step's rival said before was one the campaign
    cannot show."""
    config = plan_config(11, "golden")
    truth = draw(np.random.default_rng(16233), "partial_wave", config)
    data = campaign_data(simulate_campaign(config, ErrorModel(truth.model), seed=16233, dwell_jitter=0.8))
    terms = [Term("linear_scale"), Term("backlash")]
    if beside_bow:
        terms.append(Term("nonlinear_lead", {}, False, fixed_shape("nonlinear_lead", data, {})))
    rival = other_shape(data, linear_fit(data, terms), "bump", 1)
    assert rival is not None
    shape = rival.terms[-1].shape
    assert seen_at(data.targets_mm, np.array([shape["centre_mm"]]), shape["width_mm"])[0] >= MIN_SEEN, shape

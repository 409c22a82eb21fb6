"""Issue 34 item 4: a period is looked for down to twice the target spacing whatever the plan's
pattern (aliasing is decided by the spacing, not by "evenly spaced"): the seed paper's plan and every
dense table are uniform."""

from __future__ import annotations

import pytest

from campaign.config import parse_config
from campaign.discovery.data import campaign_data
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from tests.conftest import sweep

FINE = parse_config("""
[axis]
soft_limit_min = -5.0
soft_limit_max = 65.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 60.0
count = 61
overrun = 2.0
cycles = 3
dwell_s = 1.0
velocity = 20.0
offsets = "none"

[capture]
method = "dwell"
average_s = 0.5
""")
"""61 targets 1 mm apart over 60 mm, three runs: ten targets per 10 mm screw lead."""


def fine_discovery(effects: dict, seed: int):
    table = simulate_campaign(FINE, ErrorModel(effects), seed=seed)
    return discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})


@pytest.mark.machine
@pytest.mark.parametrize("seed", sweep(1, 2, 3))
def test_a_10_mm_lead_on_61_uniform_targets_1_mm_apart_is_named_with_its_period_within_1_percent(seed):
    """The old search did not look for a period on evenly spaced targets at all ("named: nothing")."""
    lead = {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3 * seed}
    result = fine_discovery({"periodic_lead": lead, "noise": {"sigma_um": 0.3}}, seed)
    assert result.added == ["periodic_lead"], (result.added, result.unresolved, result.notes)
    found = result.steps[0].params
    assert found["period_mm"] == pytest.approx(10.0, rel=0.01)
    assert found["amplitude_um"] == pytest.approx(1.0, rel=0.2)
    assert result.gap_after_um <= 1.3 * result.noise_um


@pytest.mark.parametrize("seed", sweep(1, 2))
def test_uniform_targets_without_a_lead_name_nothing(seed):
    result = fine_discovery({"linear_scale": {"ppm": 5.0}, "noise": {"sigma_um": 0.3}}, seed)
    assert result.added == [] and result.local is None, (result.added, result.notes)
    assert any("looked for at periods from 2.04" in n for n in result.notes), result.notes

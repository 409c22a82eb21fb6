"""One target's departure as a local error (issue 34 item 3, campaign.discovery.local.TARGET): an error
narrower than the targets' spacing reaches one target alone. No bump of the grid can hold it (a bump is
looked for only where three targets see it), so it was held by a step and two wide bumps that also took
the machine's bow, and the bow was not named. It is now a term of its own, at that target, said to lie
somewhere between its neighbours. Machines drawn per seed."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.discovery.data import campaign_data
from campaign.discovery.fit import Term, linear_fit
from campaign.discovery.local import TARGET, find_locals
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from tests.discovery_draws import plan_config


def narrow_error_found(rng: np.random.Generator, config, at: float, widths_mm: tuple[float, float], seed: int):
    """A drawn machine with a 2-4 µm raised-cosine error at `at` mm (width drawn from `widths_mm`) beside
    a scale and 0.3-0.6 µm noise, its campaign on `config`, and the local errors found beside the scale:
    (machine, data, found)."""
    size = float(rng.uniform(2, 4)) * float(rng.choice([-1.0, 1.0]))
    machine = {"linear_scale": {"ppm": float(rng.uniform(-10, 10))},
               "local_defect": {"amplitude_um": size, "centre_mm": at, "width_mm": float(rng.uniform(*widths_mm)),
                                "skew": 0.0},
               "noise": {"sigma_um": float(rng.uniform(0.3, 0.6))}}
    data = campaign_data(simulate_campaign(config, ErrorModel(machine), seed=seed, dwell_jitter=0.8))
    return machine, find_locals(data, linear_fit(data, [Term("linear_scale")]))


@pytest.mark.parametrize("seed", range(3))
def test_a_departure_at_one_target_is_found_there_with_its_size(seed: int) -> None:
    """A 2-4 µm error 2-6 mm wide on an inner target of 17 targets 37.5 mm apart, beside a scale: the
    first local error found is that target's departure, its size within 3σ of the error's mean over
    the target's samples, said to lie between the neighbours, with no place or width error it cannot
    have."""
    rng = np.random.default_rng(seed)
    config = plan_config(17, "none")
    at = 37.5 * int(rng.integers(2, 15))
    machine, found = narrow_error_found(rng, config, at, (2, 6), seed)
    size = machine["local_defect"]["amplitude_um"]
    assert found and found[0].kind == TARGET, [e.sentence() for e in found]
    first = found[0]
    assert first.params["centre_mm"] == pytest.approx(at)
    assert first.region_mm == pytest.approx((at - 37.5, at + 37.5))
    assert abs(first.size_um - size) < 3 * first.errors["amplitude_um"] + 0.05 * abs(size), (first.size_um, size)
    assert "centre_mm" not in first.errors and "width_mm" not in first.errors
    assert "width_mm" not in first.params  # the data say no width
    assert f"at the target at {at:.4g} mm alone (the reading there, not the error's peak" in first.sentence()


@pytest.mark.machine  # 8 drawn campaigns and their discoveries, about 15 s
def test_a_narrow_error_beside_a_bow_is_one_target_and_the_bow_stays_named() -> None:
    """A 2.5-4 µm error 5-25 mm wide near an inner target of 21 targets 30 mm apart, beside a drawn bow
    (1.5-3 µm) and backlash: nothing the machine lacks is named, and the error is said where it is (a
    departure at one target whose neighbours hold it between them), not held by terms that also take the bow (the bow was dropped as
    "it soaked up a local error" beside a step and two wide bumps; seed 53 draw 704 of the bench). Only
    the draws whose error some target sees above twice the noise are checked (as the bench's visible
    ones): a 5 mm error 4 mm from its nearest target reaches none."""
    from campaign.plan import build_plan
    from tests.discovery_draws import _visible

    config = plan_config(21, "none")
    targets = np.array(build_plan(config).targets)
    checked = []
    for seed in range(8):
        rng = np.random.default_rng(100 + seed)
        centre = 30.0 * int(rng.integers(3, 18)) + float(rng.uniform(-6, 6))
        machine = {"linear_scale": {"ppm": float(rng.uniform(-10, 10))},
                   "nonlinear_lead": {"p2_um": float(rng.uniform(1.5, 3)) * float(rng.choice([-1.0, 1.0])),
                                      "p3_um": float(rng.uniform(-0.5, 0.5)), "start_mm": 0.0, "end_mm": 600.0},
                   "backlash": {"b_um": float(rng.uniform(1, 3))},
                   "local_defect": {"amplitude_um": float(rng.uniform(2.5, 4)) * float(rng.choice([-1.0, 1.0])),
                                    "centre_mm": centre, "width_mm": float(rng.uniform(5, 25)), "skew": 0.0},
                   "noise": {"sigma_um": float(rng.uniform(0.3, 0.6))}}
        if not _visible({"local_defect": machine["local_defect"]}, targets, machine["noise"]["sigma_um"]):
            continue
        checked.append(seed)
        table = simulate_campaign(config, ErrorModel(machine), seed=seed, dwell_jitter=0.8)
        result = discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
        said = (seed, centre, result.added, [e.sentence() for e in result.local_errors])
        assert set(result.added) <= {"linear_scale", "nonlinear_lead", "backlash"}, said
        assert any(e.kind == TARGET and e.region_mm[0] <= centre <= e.region_mm[1] for e in result.local_errors), said
        assert "nonlinear_lead" in result.added, said
    assert len(checked) >= 6, checked

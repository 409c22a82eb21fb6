"""Issue 34 items 2 and 3: an error no effect of the vocabulary has the shape of stays an unexplained
local error (a local term whose shape follows the data over the located region: a spline, not the
simulator's formula, not one fixed profile), and no vocabulary effect is named for it unless it
predicts left-out targets better (campaign/discovery/unexplained.py, unnamed.unnamed_beside_regions)."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.discovery.effects import region_basis
from campaign.discovery.search import discover
from campaign.model import ErrorModel
from tests.test_discovery_locate import table


def zone(x: np.ndarray, low: float, high: float, height: float, ramp: float = 15.0) -> np.ndarray:
    """A raised (or sunken) zone with a flat top and straight ramps `ramp` mm long: a worn section of
    a screw, neither a Gaussian nor a raised cosine."""
    return height * np.clip(np.minimum((x - low) / ramp, (high - x) / ramp), 0.0, 1.0)


def test_the_region_term_is_zero_before_its_region_and_holds_its_level_after():
    x = np.linspace(0.0, 600.0, 601)
    cols = region_basis(x, 200.0, 300.0, 4)
    assert cols.shape == (601, 5)
    assert np.all(cols[x <= 200.0] == 0.0)
    assert np.allclose(cols[x >= 300.0], cols[300])  # held at its end value: a step's level goes on
    inside = (x > 200.0) & (x < 300.0)
    assert np.linalg.matrix_rank(cols[inside]) == 5


@pytest.mark.parametrize("pieces", [1, 2, 5])
def test_a_region_open_at_both_sides_spans_with_the_offset_what_its_whole_basis_spans(pieces):
    """A region from the first target whose level goes on after it: its whole clamped basis sums to one,
    the offset's column. One column fewer, full rank beside the offset, the same span with it."""
    x = np.linspace(0.0, 600.0, 301)
    cols = region_basis(x, 0.0, 250.0, pieces, True, True, offset_level=True)
    assert cols.shape == (301, pieces + 2)
    assert np.all(cols[x <= 0.0] == 0.0) and np.allclose(cols[x >= 250.0], cols[-1])
    with_offset = np.column_stack([np.ones_like(x), cols])
    assert np.linalg.matrix_rank(with_offset) == pieces + 3
    open_start = region_basis(x, 0.0, 250.0, pieces, False, True)  # closed at the end: nothing sums to one
    assert np.linalg.matrix_rank(np.column_stack([np.ones_like(x), open_start])) == open_start.shape[1] + 1
    inner = np.linspace(0.0, 250.0, pieces + 1)  # the whole basis: every cubic B-spline of those knots, clamped
    from scipy.interpolate import BSpline

    knots = np.r_[[0.0] * 3, inner, [250.0] * 3]
    whole = BSpline.design_matrix(np.clip(x, 0.0, 250.0), knots, 3).toarray()
    assert np.allclose(whole.sum(1), 1.0)
    projected = with_offset @ np.linalg.lstsq(with_offset, whole, rcond=None)[0]
    assert np.abs(projected - whole).max() < 1e-9
    assert np.allclose(region_basis(x, 0.0, 250.0, pieces, True, True), whole)  # one direction's: all stay


def test_only_a_region_in_both_directions_from_the_first_target_leaves_its_level_to_the_offset():
    """region_term marks the offset's level only where the whole basis sums to the offset's column: a
    region in both directions, from the first target, its level going on; a one-direction region keeps
    every column (beside the offset alone its basis sums to that direction's indicator, a level the
    offset does not hold)."""
    from campaign.discovery.effects import form_of
    from campaign.discovery.locate import Region
    from campaign.discovery.unexplained import region_term

    data = table(np.random.default_rng(3), 11, lambda x, d, t: 0.0 * x, 0.3, golden=False)
    for direction, side in (("both", 0), ("+", 1), ("-", -1)):
        for shape, start in (("step", 0.0), ("bump", 0.0), ("step", 200.0)):
            region = Region("position", "deviation", start, start + 150.0, 2.0, start + 60.0, direction, shape)
            term = region_term(data, region, 1)
            assert term is not None
            marked = side == 0 and shape == "step" and start == 0.0
            assert term.shape["offset_level"] == float(marked), (direction, shape, start)
            cols = form_of(term.name).columns(data, term.shape, {})
            rank = np.linalg.matrix_rank(np.column_stack([np.ones(len(data)), cols]))
            assert rank == cols.shape[1] + 1, (direction, shape, start)  # none is the offset's


@pytest.mark.parametrize("seed", range(12))
def test_a_region_step_is_said_between_the_targets_it_changes_most_between(seed):
    """A region term whose level goes on after it, fitted to a sharp step between two drawn neighbouring
    targets (the spline, a few pieces, spreads it over the region): the step is said between those two
    targets, not at the steepest point of the spline between them (a drawn 2.8 µm step at 519 mm between
    targets at 480 and 540 mm was said "at 598.8 mm", the region's end, where no target lies)."""
    from campaign.discovery.unexplained import steepest_between

    rng = np.random.default_rng(seed)
    count = int(rng.choice([11, 17, 21]))
    targets = np.linspace(0.0, 600.0, count)
    k = int(rng.integers(3, count - 4))  # the step lies between targets k and k + 1
    start = float(targets[k - int(rng.integers(1, 4))] - 5.0)
    end = float(targets[k + int(rng.integers(1, 4))] + 5.0)
    inside = int(np.sum((targets >= start) & (targets <= end)))
    pieces = float(np.clip(inside // 2, 1, 6))  # as unexplained.region_term chooses them
    shape = {"start_mm": start, "end_mm": end, "pieces": pieces, "open_end": 1.0, "open_start": 0.0}
    at = float(rng.uniform(targets[k], targets[k + 1]))
    height = float(rng.uniform(2.0, 4.0) * rng.choice([-1.0, 1.0]))
    x = np.repeat(targets, 10)
    y = height * (x > at) + rng.normal(0.0, 0.3, len(x))
    cols = region_basis(x, start, end, int(shape["pieces"]), True)
    coefs = np.linalg.lstsq(cols[x >= start - 1e-9], y[x >= start - 1e-9], rcond=None)[0]
    assert steepest_between(targets, shape, coefs) == (targets[k], targets[k + 1])


@pytest.mark.machine  # 8 discoveries, about 40 s
def test_a_flat_topped_zone_is_an_unexplained_local_error_and_nothing_is_named():
    """Zones 60-160 mm long, 2-4 µm of either sign, with 15 mm ramps, on 21 targets (uniform and
    golden-like), 0.4 µm of noise, a 10 µm/m scale: nothing of the vocabulary is named, a local error
    is located and the gap ends within 1.3 × the noise in at least 6 of 8 draws (6 here). The code
    before (one Gaussian or logistic profile) named the bow or a screw lead in 4 of these 8 and met all
    three in 3."""
    good, said = 0, []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        low, length = float(rng.uniform(80.0, 380.0)), float(rng.uniform(60.0, 160.0))
        height = float(rng.uniform(2.0, 4.0) * rng.choice([-1.0, 1.0]))
        data = table(rng, 21, lambda x, d, t, a=low, b=low + length, h=height: zone(x, a, b, h) + 0.01 * x, 0.4, bool(seed % 2))
        result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
        ok = not result.added and bool(result.local_errors) and result.gap_after_um <= 1.3 * result.noise_um
        good += ok
        said.append((seed, result.added, [e.sentence() for e in result.local_errors],
                     round(result.gap_after_um / result.noise_um, 2)))
    assert good >= 6, said


def test_a_region_growing_in_time_says_its_change_over_the_campaign_in_micrometres():
    """A flat-topped zone (200-320 mm) that grows from 1 to 4 µm over the campaign, 0.3 µm of noise: the
    unexplained local error over it changes with time by about +3 µm (its size at the end less its size
    at the start), not by the share of its fitted shape (about 1.2, printed as µm before)."""
    rng = np.random.default_rng(3)

    def growing(x, d, t):
        return zone(x, 200.0, 320.0, 1.0) * (1.0 + 3.0 * (t - t.min()) / np.ptp(t))

    result = discover(table(rng, 21, growing, 0.3, False), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    regions = [e for e in result.local_errors if e.kind == "region"]
    assert regions, [e.sentence() for e in result.local_errors]
    change = regions[0].time_change_um
    assert 2.2 < change < 3.8, (change, regions[0].time_text())
    assert regions[0].time_change_error_um < 1.0, regions[0].time_text()


@pytest.mark.machine  # a few seconds: the fast tier stays under a minute
def test_a_local_error_near_the_end_of_the_travel_is_said_within_the_positions_measured(tmp_path):
    """A bump centred 30 mm inside the first target, wider than that: its region was said from one
    width below its centre, beyond the travel (a reviewer saw 'a local error at -45–254.6 mm' on an
    axis measured from 0 mm)."""
    from campaign.discovery.data import campaign_data
    from campaign.discovery.search import discover
    from campaign.model import ErrorModel
    from campaign.pointtable import read_points
    from tests.test_discovery_stand_in import iso_table

    seen = 0
    for seed in (3, 4):
        table = iso_table(tmp_path / f"edge{seed}.csv", lambda x, d, rng: 3.0 * np.exp(-(((x - 30.0) / 50.0) ** 2))
                          + rng.normal(0, 0.3), targets=21, spacing=30.0, seed=seed)
        data = campaign_data(read_points(table))
        result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
        for local in result.local_errors:
            low, high = local.region_mm
            assert float(data.x.min()) <= low < high <= float(data.x.max()), local.sentence()
            seen += local.kind == "bump" and local.params["centre_mm"] - local.params["width_mm"] < float(data.x.min())
    assert seen  # the case: a bump that reaches beyond the first target

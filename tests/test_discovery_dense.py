"""Issue 34 item 4 (dense tables): regions located over most of the travel are a structure over it
(a screw lead seen lobe by lobe), the vocabulary's to explain, not local errors: the region route is
not taken for them (campaign.discovery.search.over_the_travel). The bench is bench/discovery_dense.py."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.discovery.data import campaign_data
from campaign.discovery.locate import Located, Region
from campaign.discovery.search import over_the_travel
from campaign.pointtable import PointTable


def axis(travel_mm: float = 600.0, targets: int = 121):
    x = np.linspace(0.0, travel_mm, targets)
    run = np.repeat([1, 2], 2 * targets)
    direction = np.tile(np.repeat([1, -1], targets), 2)
    target = np.tile(np.concatenate([x, x[::-1]]), 2)
    return campaign_data(PointTable(kind="linear", run=run, direction=direction, target=target,
                                    deviation=np.zeros(len(target)), optional={}, meta={}, source="<test>"))


def lobes(starts: np.ndarray, width: float, direction: str = "both") -> list[Region]:
    return [Region("position", "deviation", float(s), float(s) + width, 1.0, float(s) + width / 2, direction, "wave")
            for s in starts]


def test_lobes_over_most_of_the_travel_are_over_the_travel():
    data = axis()
    # a 10 mm lead's lobes, 4 mm of each 5 mm half-period out of its band: 80 % of the travel
    assert over_the_travel(data, Located(lobes(np.arange(0.0, 600.0, 5.0), 4.0)))


def test_a_few_local_regions_are_not():
    data = axis()
    assert not over_the_travel(data, Located(lobes(np.array([100.0, 400.0]), 120.0)))
    # a zone with the starting model bent around it on either side: 93 % of the travel in three regions
    zone = [Region("position", "deviation", s, e, 1.0, (s + e) / 2, "both", "bump")
            for s, e in ((0.0, 181.25), (196.25, 322.5), (338.75, 600.0))]
    assert not over_the_travel(data, Located(zone))


def test_overlapping_regions_count_once():
    """The same place seen in each direction is counted once: the union's length, not the sum."""
    data = axis()
    both = lobes(np.arange(0.0, 280.0, 10.0), 8.0, "+") + lobes(np.arange(0.0, 280.0, 10.0), 8.0, "-")
    assert not over_the_travel(data, Located(both))  # 224 mm of 600 (the sum would be 448)
    wider = lobes(np.arange(0.0, 400.0, 10.0), 8.0, "+") + lobes(np.arange(0.0, 400.0, 10.0), 8.0, "-")
    assert over_the_travel(data, Located(wider))  # 320 mm of 600


def dense_axis(seed: int, targets: int = 6000):
    """`targets` positions over 600 mm, both directions, one run: a bump or step drawn at random, a
    reversal and 0.3 µm noise."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 600.0, targets)
    target = np.concatenate([x, x[::-1]])
    direction = np.repeat([1, -1], targets)
    centre, width, size = rng.uniform(100.0, 500.0), rng.uniform(5.0, 120.0), rng.choice([-1.0, 1.0]) * rng.uniform(1, 3)
    if rng.random() < 0.5:
        shape = np.exp(-4 * np.log(2) * ((target - centre) / width) ** 2)
    else:
        shape = 1 / (1 + np.exp(-(target - centre) * 4.39 / width))
    deviation = size * shape - 0.7 * direction + rng.normal(0.0, 0.3, len(target))
    return campaign_data(PointTable(kind="linear", run=np.ones(len(target), dtype=int), direction=direction,
                                    target=target, deviation=deviation, optional={}, meta={}, source="<test>"))


@pytest.mark.parametrize("seed", range(6))
def test_the_grid_binned_finds_the_best_of_the_grid_unbinned(seed, monkeypatch):
    """On a dense table the grid evaluates wide shapes once per bin (local.GRID_BINS_PER_WIDTH): it picks
    the shape, side and width the grid picks over every distinct position, its centre within one step
    of the grid."""
    from campaign.discovery import local
    from campaign.discovery.fit import Term, linear_fit

    data = dense_axis(seed)
    fit = linear_fit(data, [Term("backlash")])
    binned = local._grid_best(data, fit)
    monkeypatch.setattr(local, "GRID_BINS_PER_WIDTH", 1e12)  # bins never hold two positions
    whole = local._grid_best(data, fit)
    assert binned is not None and whole is not None
    assert (binned[0], binned[2], binned[3]) == (whole[0], whole[2], whole[3])
    assert abs(binned[1] - whole[1]) <= 600.0 / local.MAX_CENTRES + 1e-9


def test_bins_hold_the_sums_of_their_positions():
    from campaign.discovery.local import _binned, _Side

    rng = np.random.default_rng(3)
    xs = np.sort(rng.uniform(0.0, 100.0, 500))
    side = _Side(0, rng.uniform(0.5, 2.0, 500), rng.normal(size=(500, 4)), rng.normal(size=3))
    at, ((count, sums, above, count_above),) = _binned(xs, [side], 1.0)
    assert len(at) < len(xs) and np.all(np.diff(at) > 0)
    assert count.sum() == pytest.approx(side.count.sum()) and sums.sum(0) == pytest.approx(side.sums.sum(0))
    # from each bin on: the sums of that bin and those after it; nothing after the last
    assert above[:-1] == pytest.approx(np.cumsum(sums[::-1], axis=0)[::-1])
    assert count_above[:-1] == pytest.approx(np.cumsum(count[::-1])[::-1]) and above[-1] == pytest.approx(0.0)
    # positions too sparse for the bins: the distinct positions themselves
    assert _binned(xs, [side], 0.01)[0] is xs

"""Issue 34 item 4 (dense tables): regions located over most of the travel are a structure over it
(a screw lead seen lobe by lobe), the vocabulary's to explain, not local errors: the region route is
not taken for them (campaign.discovery.search.over_the_travel). The bench is bench/discovery_dense.py."""

from __future__ import annotations

import numpy as np

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

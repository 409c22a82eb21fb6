"""The shared outlier test (campaign/outliers.py): a glitch is found and named, a clean campaign
rarely shows one, and the scores equal a direct computation of the studentised deleted residual."""

import numpy as np
import pytest

from campaign.outliers import ALPHA, find_outliers
from campaign.pointtable import PointTable, parse_points, read_points
from tests.conftest import PAPER


def campaign(seed: int, runs: int = 5, targets: int = 11, sigma: float = 0.5) -> PointTable:
    rng = np.random.default_rng(seed)
    rows = [(r, d, 60.0 * i) for r in range(1, runs + 1) for d in (1, -1) for i in range(targets)]
    run, direction, target = (np.array(c) for c in zip(*rows))
    deviation = -0.0124 * target + 0.5 * direction + rng.normal(0, sigma, len(rows))
    return PointTable("linear", run, direction, target.astype(float), deviation)


def test_a_12_um_glitch_in_half_a_micron_of_noise_is_flagged():
    table = campaign(1)
    glitch = int(np.flatnonzero((table.run == 3) & (table.direction == -1) & (table.target == 240.0))[0])
    table.deviation[glitch] += 12.0
    result = find_outliers(table)
    assert [(o.run, o.direction, o.target) for o in result.found] == [(3, -1, 240.0)]
    assert result.found[0].score > result.critical
    assert result.s_with > 2 * result.s_without and result.s_without == pytest.approx(0.5, rel=0.2)
    assert result.mask(table).sum() == 1 and result.mask(table)[glitch]


def test_clean_campaigns_rarely_show_an_outlier():
    flagged = sum(bool(find_outliers(campaign(seed)).found) for seed in range(300))
    assert flagged <= 300 * ALPHA * 3  # about 1 % expected; 3 % is far above chance


def test_scores_equal_the_direct_formula():
    table = campaign(7, runs=3, targets=4)
    result = find_outliers(table, alpha=0.5)  # a lax level, so that some points are listed
    groups = {}
    for i, key in enumerate(zip(table.target, table.direction)):
        groups.setdefault(key, []).append(i)
    x = table.deviation
    n, g = len(x), len(groups)
    for o in result.found:
        i = next(i for i in range(n) if (table.run[i], table.direction[i], table.target[i]) == (o.run, o.direction, o.target))
        members = groups[(table.target[i], table.direction[i])]
        others = [j for j in range(n) if j != i]
        # refit without point i: its group's mean from the others in it, the pooled variance of the rest
        sse = sum((x[j] - np.mean([x[m] for m in groups[(table.target[j], table.direction[j])] if m != i])) ** 2
                  for j in others)
        s2 = sse / (n - 1 - g)
        predicted = np.mean([x[m] for m in members if m != i])
        t = abs(x[i] - predicted) / np.sqrt(s2 * (1 + 1 / (len(members) - 1)))
        assert o.score == pytest.approx(t, rel=1e-9)


def test_the_papers_tables_have_no_outlier_at_one_percent():
    for name in ("horizontal_before.csv", "vertical_before.csv"):
        assert find_outliers(read_points(PAPER / name)).found == ()


def test_too_few_points_cannot_be_tested():
    table = PointTable("linear", np.array([1, 1]), np.array([1, -1]), np.array([0.0, 0.0]), np.array([1.0, 2.0]))
    result = find_outliers(table)
    assert result.found == () and result.critical is None and result.tested == 0


def test_readings_of_a_coarse_resolution_are_not_flagged_for_repeating_exactly():
    """An instrument reading in 0.1 µm steps: up 0.1/0.1 (no scatter at all), down 0.2/0.3 (one step
    apart). Deleting one down reading left no scatter, and both were flagged at a score of 7e163 (a new
    user's trial); against the rounding of a 0.1 µm step they are not outliers."""
    table = parse_points("run,direction,target_mm,deviation_um\n1,+,0,0.1\n2,+,0,0.1\n1,-,0,0.2\n2,-,0,0.3\n")
    found = find_outliers(table)
    assert found.tested == 4 and found.found == ()
    # a 12 µm glitch among readings in 0.1 µm steps is still one
    rows = "".join(f"{r},{d},{t},{v}\n" for t in (0, 50, 100) for d in "+-" for r, v in
                   zip(range(1, 6), (0.1, 0.2, 0.1, 0.3, 0.2)))
    glitched = parse_points("run,direction,target_mm,deviation_um\n" + rows.replace("5,+,50,0.2", "5,+,50,12.2"))
    assert [(o.run, o.target) for o in find_outliers(glitched).found] == [(5, 50.0)]

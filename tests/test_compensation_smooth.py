"""Smoothing the means before they become a table (campaign/compensation_smooth.py)."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.compensation import corrections
from campaign.compensation_smooth import pooled_variance, smooth_means
from campaign.errors import InputError
from campaign.pointtable import parse_points

TARGETS = np.array([0.0, 100.0, 200.0, 300.0])
BEND = np.array([1.0, -1.0, -1.0, 1.0])
"""Orthogonal to a line through 4 equally spaced targets: what a line fit leaves of it."""


def test_pooled_variance_weights_by_degrees_of_freedom():
    # (4·1² + 2·2²) / 6 = 2
    assert pooled_variance([1.0, 2.0], [5, 3]) == (pytest.approx(2.0), 6)
    assert pooled_variance([], []) is None


@pytest.mark.parametrize(("a", "degree"), [(0.59, 1), (0.61, None)])
def test_a_line_is_kept_below_the_critical_f_and_refused_above(a, degree):
    # means = line + a·BEND, s² = 1 with 16 degrees of freedom, n = 5 per mean: the line leaves
    # χ² = 4a²·5, F = χ²/2 = 10a². The 5 % point of F(2, 16) is 3.6337 (F tables), so a = 0.59
    # (F = 3.48) keeps the line and a = 0.61 (F = 3.72) does not; with 4 targets degree 1 is the
    # only one tested, so the raw means stay.
    means = 2.0 + 0.01 * TARGETS + a * BEND
    sm = smooth_means(TARGETS, means, np.full(4, 1 / 5), (1.0, 16))
    assert sm.degree == degree
    if degree is None:
        assert np.array_equal(sm.values, means)
        assert "raw means are kept" in sm.reason
    else:
        assert sm.values == pytest.approx(2.0 + 0.01 * TARGETS)
        assert sm.max_change == pytest.approx(a)


def test_a_cubic_screw_gets_degree_3_and_a_step_stays_raw():
    rng = np.random.default_rng(0)  # a typical draw (F = 0.54 for degree 3)
    targets = np.linspace(0.0, 600.0, 11)
    u = targets / 300 - 1
    cubic = 40 * u - 25 * u**3
    noisy = cubic + rng.normal(0, 0.3 / np.sqrt(5), 11)
    sm = smooth_means(targets, noisy, np.full(11, 1 / 5), (0.09, 88))
    assert sm.degree == 3
    step = noisy + np.where(targets < 30, 0.0, 5.0)  # 5 µm at 30 mm: far beyond the scatter
    step[1] += 4.0
    raw = smooth_means(targets, step, np.full(11, 1 / 5), (0.09, 88))
    assert raw.degree is None and np.array_equal(raw.values, step)


def test_smoothing_brings_the_table_closer_to_the_true_error():
    # 300 simulated 5-run campaigns of a cubic screw (s = 1): the table's errors at the targets
    # lie closer to the truth when smoothed. Raw means miss by s/√5 = 0.447 RMS; a cubic fitted
    # to 11 targets by about √(4/11)·0.447 = 0.27.
    rng = np.random.default_rng(7)
    targets = np.linspace(0.0, 600.0, 11)
    u = targets / 300 - 1
    truth = 30 * u + 8 * (1.5 * u**2 - 0.5) - 12 * (2.5 * u**3 - 1.5 * u)
    raw_miss, smooth_miss = [], []
    for _ in range(300):
        runs = truth[:, None] + rng.normal(0, 1, (11, 5))
        means, sds = runs.mean(axis=1), runs.std(axis=1, ddof=1)
        sm = smooth_means(targets, means, np.full(11, 1 / 5), pooled_variance(list(sds), [5] * 11))
        raw_miss.append(means - truth)
        smooth_miss.append(sm.values - truth)
    raw_rms = float(np.sqrt(np.mean(np.square(raw_miss))))
    smooth_rms = float(np.sqrt(np.mean(np.square(smooth_miss))))
    assert raw_rms == pytest.approx(1 / np.sqrt(5), rel=0.05)
    assert smooth_rms < 0.7 * raw_rms


def points_text(bend: float) -> str:
    rows = []
    for r, wobble in ((1, 0.1), (2, -0.1), (3, 0.05), (4, -0.05)):
        for d, shift in (("+", 1.0), ("-", -1.0)):
            for t, b in zip(TARGETS, BEND, strict=True):
                rows.append(f"{r},{d},{t},{shift + 0.02 * t + bend * b + wobble}\n")
    return "run,direction,target_mm,deviation_um\n" + "".join(rows)


def test_corrections_smooth_by_default_and_not_with_none():
    # 4 runs whose readings differ by ±0.1 / ±0.05 µm (s = 0.0913): a 0.01 µm bend lies inside the
    # scatter and is smoothed away; with smooth="none" the table keeps it.
    table = parse_points(points_text(0.01))
    smoothed = corrections(table, "uni", "simple")
    raw = corrections(table, "uni", "simple", "none")
    line = -(0.02 * TARGETS)
    assert smoothed.common == pytest.approx(line, abs=1e-9)
    assert raw.common == pytest.approx(line - 0.01 * BEND, abs=1e-9)
    assert smoothed.smoothing[0].degree == 1 and raw.smoothing[0].degree is None
    # a 1 µm bend is far beyond the scatter: kept in both
    big = corrections(parse_points(points_text(1.0)), "bi", "simple")
    assert big.forward == pytest.approx(-(1.0 + 0.02 * TARGETS + BEND), abs=1e-9)
    assert big.smoothing[1].degree is None and big.smoothing[-1].degree is None


def test_unknown_smoothing_is_an_input_error():
    with pytest.raises(InputError, match="unknown smoothing 'cubic'"):
        corrections(parse_points(points_text(0.0)), smooth="cubic")

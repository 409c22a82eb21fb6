"""Smoothing the means before they become a table (campaign/compensation/smooth.py).

Critical values of F and t are quoted from printed tables, not computed by the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from campaign.compensation.corrections import corrections
from campaign.compensation.smooth import scatter_within_runs, smooth_means
from campaign.errors import InputError
from campaign.pointtable import parse_points

TARGETS = np.array([0.0, 100.0, 200.0, 300.0])
BEND = np.array([1.0, -1.0, -1.0, 1.0])
"""Orthogonal to a line through 4 equally spaced targets: what a line fit leaves of it."""
CHECKER = np.array([[1, -1, 1, -1], [-1, 1, -1, 1], [1, -1, 1, -1], [-1, 1, -1, 1]], dtype=float)
"""Scatter [target, run] with zero target means and zero run offsets: the additive model leaves
all of it, RSS = 16 w² for amplitude w, on 16 - 4 - 4 + 1 = 9 degrees of freedom."""


def test_scatter_within_runs_hand_worked():
    # targets A, B; runs 1, 2: A = 1, 3; B = 2, 8. The interaction (1 - 3 - 2 + 8)/4 = 1 leaves
    # residuals ±1: RSS 4 on 4 - 2 - 2 + 1 = 1 degree of freedom.
    s2, dof = scatter_within_runs(np.array([1, 2, 1, 2]), np.array([0.0, 0.0, 5.0, 5.0]),
                                  np.array([1.0, 3.0, 2.0, 8.0]))
    assert (s2, dof) == (pytest.approx(4.0), 1)
    assert scatter_within_runs(np.array([1, 1]), np.array([0.0, 5.0]), np.array([1.0, 2.0])) is None


def test_scatter_within_runs_ignores_run_offsets_and_handles_a_missing_point():
    rng = np.random.default_rng(11)
    run = np.repeat(np.arange(1, 6), 7)
    target = np.tile(np.arange(7) * 50.0, 5)
    x = rng.normal(0, 1, 35)
    offsets = np.array([0.0, 3.0, -2.0, 5.0, 1.0])
    assert scatter_within_runs(run, target, x + offsets[run - 1]) == pytest.approx(scatter_within_runs(run, target, x))
    # one point missing: against a dense least-squares fit of the same model
    keep = np.arange(35) != 12
    design = np.column_stack([target[keep, None] == np.arange(7) * 50.0, run[keep, None] == np.arange(2, 6)])
    coef, *_ = np.linalg.lstsq(design.astype(float), x[keep], rcond=None)
    rss = float(np.sum((x[keep] - design @ coef) ** 2))
    s2, dof = scatter_within_runs(run[keep], target[keep], x[keep])
    assert dof == 34 - 7 - 5 + 1
    assert s2 == pytest.approx(rss / dof, rel=1e-9)


@pytest.mark.parametrize(("a", "degree"), [(0.59, 1), (0.61, None)])
def test_a_line_is_kept_below_the_critical_f_and_refused_above(a, degree):
    # means = line + a·BEND, s² = 1 on 16 degrees of freedom, n = 5 per mean: the line leaves
    # χ² = 4a²·5, F = χ²/2 = 10a². The 5 % point of F(2, 16) is 3.6337, so a = 0.59 (F = 3.48)
    # keeps the line and a = 0.61 (F = 3.72) does not; with 4 targets degree 1 is the only one
    # tested, so the raw means stay.
    means = 2.0 + 0.01 * TARGETS + a * BEND
    sm = smooth_means(TARGETS, means, np.full(4, 1 / 5), (1.0, 16))
    assert sm.degree == degree
    if degree is None:
        assert np.array_equal(sm.values, means)
        assert "raw means are kept" in sm.reason
    else:
        assert sm.values == pytest.approx(2.0 + 0.01 * TARGETS)
        assert sm.max_change == pytest.approx(a)


def points_text(bend: float, w: float = 0.3, reversal: float = 2.0) -> str:
    """4 targets, 4 runs, both directions: + reads reversal/2 above the line, - below; CHECKER·w
    on top (s² = 16w²/9 per direction), a·BEND in both directions."""
    rows = []
    for r in range(4):
        for d, shift in (("+", reversal / 2), ("-", -reversal / 2)):
            for i, t in enumerate(TARGETS):
                rows.append(f"{r + 1},{d},{t},{shift + 0.02 * t + bend * BEND[i] + w * CHECKER[i, r]}\n")
    return "run,direction,target_mm,deviation_um\n" + "".join(rows)


@pytest.mark.parametrize(("mode", "a", "smoothed"), [("bi", 0.28, True), ("bi", 0.30, False),
                                                      ("uni", 0.18, True), ("uni", 0.20, False)])
def test_corrections_weigh_each_mode_at_the_critical_value(mode, a, smoothed):
    # s² = 16·0.09/9 = 0.16 per direction, n = 4.
    # bi: each direction alone, var(x̄) = s²/4: F = 4a²·4/s²/2 = 8a²/s² on (2, 9); 5 % point 4.2565,
    #     so a = 0.28 (F = 3.92) smooths and a = 0.30 (F = 4.50) does not.
    # uni: the mean of both, var = s²(1/4 + 1/4)/4 = s²/8, s² pooled on 18: F = 16a²/s² on (2, 18);
    #     5 % point 3.5546, so a = 0.18 (F = 3.24) smooths and a = 0.20 (F = 4.00) does not.
    # (Weights off by 2, or one direction's s² alone in uni mode, move a case across the line.)
    corr = corrections(parse_points(points_text(a)), mode, "simple")
    keys = (1, -1) if mode == "bi" else (0,)
    assert [corr.smoothing[k].degree for k in keys] == [1 if smoothed else None] * len(keys)
    line = -(0.02 * TARGETS)
    expected = line if smoothed else line - a * BEND
    assert corr.common == pytest.approx(expected, abs=1e-9)


def test_no_scatter_few_targets_and_one_direction():
    flat = points_text(0.1, w=0.0)  # identical runs: nothing to judge a fit by
    assert "no scatter" in corrections(parse_points(flat), "uni").smoothing[0].reason
    three = "run,direction,target_mm,deviation_um\n" + "".join(
        f"{r},+,{t},{0.01 * t + 0.1 * ((r + i) % 2)}\n" for r in (1, 2, 3) for i, t in enumerate((0, 10, 20)))
    assert "3 targets" in corrections(parse_points(three)).smoothing[1].reason
    forward_only = "\n".join(line for line in points_text(0.0).splitlines() if ",-," not in line)
    corr = corrections(parse_points(forward_only), method="simple")
    assert list(corr.smoothing) == [1] and corr.smoothing[1].degree == 1
    assert corr.forward == pytest.approx(-(1.0 + 0.02 * TARGETS), abs=1e-9)


def cubic_campaigns(count: int, bump: float = 0.0, run_offset: float = 0.0, seed: int = 7):
    """`count` simulated 5-run campaigns of a cubic screw on 11 targets, s = 1 (deviation unit),
    optionally a bump at target 4 and a per-run offset (standard deviation, deviation unit).
    Yields (truth, raw means, Smoothing)."""
    rng = np.random.default_rng(seed)
    targets = np.linspace(0.0, 600.0, 11)
    u = targets / 300 - 1
    truth = 30 * u + 8 * (1.5 * u**2 - 0.5) - 12 * (2.5 * u**3 - 1.5 * u)
    truth[4] += bump
    run, target = np.tile(np.arange(5), 11), np.repeat(targets, 5)
    for _ in range(count):
        x = truth[:, None] + rng.normal(0, 1, (11, 5)) + rng.normal(0, run_offset, (1, 5))
        means = x.mean(axis=1)
        yield truth, means, smooth_means(targets, means, np.full(11, 1 / 5),
                                         scatter_within_runs(run, target, x.ravel()))


def test_a_cubic_screw_gets_degree_3_and_a_large_bump_stays_raw():
    # two tests at 5 % each: degree 3 is expected in about 90-95 % of campaigns
    degrees = [sm.degree for _, _, sm in cubic_campaigns(200)]
    assert degrees.count(3) >= 0.85 * len(degrees)
    # a bump of 4 s (8.9 s/√5) at one target: no polynomial may swallow it
    kept = [sm.degree is None for _, _, sm in cubic_campaigns(100, bump=4.0)]
    assert all(kept)


@pytest.mark.parametrize("run_offset", [0.0, 1.0])
def test_smoothing_brings_the_table_closer_to_the_true_error(run_offset):
    # Raw means miss the truth by s/√5 = 0.447 RMS; a cubic fitted to 11 targets by about
    # √(4/11)·0.447 = 0.27. Per-run offsets (1 s) move every mean alike; A ignores that
    # common part, so it is removed before comparing, and they must not spoil the tests.
    raw_miss, smooth_miss = [], []
    for truth, means, sm in cubic_campaigns(300, run_offset=run_offset):
        raw_miss.append(means - truth - np.mean(means - truth))
        smooth_miss.append(sm.values - truth - np.mean(sm.values - truth))
    raw_rms = float(np.sqrt(np.mean(np.square(raw_miss))))
    smooth_rms = float(np.sqrt(np.mean(np.square(smooth_miss))))
    assert raw_rms == pytest.approx(np.sqrt(10 / 11 / 5), rel=0.05)  # less the common part: 10/11 of s²/5
    assert smooth_rms < 0.7 * raw_rms


def test_compensate_prints_the_smoothing(cli, tmp_path):
    source = tmp_path / "p.csv"
    source.write_text(points_text(0.05))
    result = cli("compensate", source, "--format", "csv", "-o", tmp_path / "t.csv", "--mode", "uni")
    assert result.code == 0, result.err
    assert ("smoothing, mean of both directions: polynomial of degree 1" in result.out
            and "the means move by at most 0.050 µm" in result.out)
    raw = cli("compensate", source, "--format", "csv", "-o", tmp_path / "r.csv", "--smooth", "none")
    assert "not smoothed (--smooth none)" in raw.out


def test_unknown_smoothing_is_an_input_error():
    with pytest.raises(InputError, match="unknown smoothing 'cubic'"):
        corrections(parse_points(points_text(0.0)), smooth="cubic")

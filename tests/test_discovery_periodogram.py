"""The periodogram's two ways to its sums (campaign.discovery.periodogram): on positions at a common
step (a dense plan, a scan's bins) the sums come from FFTs of the values placed on the grid, else
every sine is evaluated. Both must give the same power at the same frequencies, whatever the grid's
step, origin and gaps, the rows' weights and the model projected out. Tables drawn per seed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from campaign.discovery import periodogram
from campaign.discovery.data import PROFILE_U, campaign_data
from campaign.discovery.fit import Term, linear_fit
from campaign.discovery.periodogram import on_grid, periodogram_power
from campaign.pointtable import PointTable


def _grid_table(rng: np.random.Generator, weighted: bool) -> tuple[PointTable, float]:
    """Positions on a grid of a random step and origin with random nodes left out, both directions
    and 1-3 runs, a sine of a random period (mm) beside a bow, a reversal and noise; with `weighted`
    each row its own uncertainty (as a scan profile's bins). The table and the sine's period."""
    step = float(rng.choice([0.05, 0.08, 0.25, 1.0]) * rng.uniform(0.9, 1.1))
    nodes = np.sort(rng.choice(int(rng.integers(1500, 4000)), size=int(rng.integers(1100, 1500)), replace=False))
    x = float(rng.uniform(-60, 60)) + step * nodes
    period = float(np.exp(rng.uniform(np.log(3), np.log(min(60.0, np.ptp(x) / 4)))))
    rows = [(r, d, xi) for r in range(1, int(rng.integers(1, 4)) + 1) for d in (1, -1) for xi in x[::d]]
    run, direction, target = (np.array(v) for v in zip(*rows, strict=True))
    u = 2 * (target - x[0]) / (x[-1] - x[0]) - 1
    y = (rng.uniform(0.5, 2) * np.sin(2 * np.pi * target / period + rng.uniform(0, 6)) + 0.8 * u**2
         - 0.6 * direction + rng.normal(0, 0.3, len(target)))
    extra = {PROFILE_U: rng.uniform(0.1, 0.5, len(target))} if weighted else {}
    return PointTable(kind="linear", run=run, direction=direction.astype(float), target=target, deviation=y,
                      extra=extra), period


def _refused(*args, **kwargs):
    raise AssertionError("the other way to the sums was taken")


@pytest.mark.parametrize("seed", range(6))
def test_the_grids_ffts_give_the_direct_sums_power(seed, monkeypatch):
    rng = np.random.default_rng(7100 + seed)
    table, period = _grid_table(rng, weighted=seed % 2 == 1)
    data = campaign_data(table)
    assert on_grid(np.unique(data.x), 0.5) is not None
    fit = linear_fit(data, [Term("linear_scale"), Term("nonlinear_lead"), Term("backlash")])
    with monkeypatch.context() as only_the_grid:
        only_the_grid.setattr(periodogram, "_direct_sums", _refused)
        freqs, power = periodogram_power(data, fit)
    monkeypatch.setattr(periodogram, "GRID_POSITIONS", 10**9)  # every sine evaluated
    direct_freqs, direct = periodogram_power(data, fit)
    assert len(freqs) == len(direct_freqs) > 100
    assert np.abs(freqs - direct_freqs).max() < 1e-9 * freqs.max()
    assert np.abs(power - direct).max() < 1e-9 * direct.max()
    assert 1 / freqs[np.argmax(power)] == pytest.approx(period, rel=0.01)  # and it shows the sine
    # positions as a point table holds them (to 1e-6 mm) stay on the grid, the power within 1e-5
    rounded = campaign_data(replace(table, target=np.round(table.target, 6)))
    monkeypatch.undo()
    assert on_grid(np.unique(rounded.x), 0.5) is not None
    rounded_freqs, on_nodes = periodogram_power(rounded, linear_fit(rounded, fit.terms))
    assert np.abs(rounded_freqs - freqs).max() < 1e-6 * freqs.max()  # the travel rounded too
    assert np.abs(on_nodes - direct).max() < 1e-5 * direct.max()


@pytest.mark.parametrize("seed", range(3))
def test_positions_off_a_common_step_take_the_direct_sums(seed, monkeypatch):
    rng = np.random.default_rng(7200 + seed)
    table, _ = _grid_table(rng, weighted=False)
    off = replace(table, target=table.target + 1e-3 * np.sin(table.target))  # each a different distance off
    data = campaign_data(off)
    monkeypatch.setattr(periodogram, "_grid_sums", _refused)
    freqs, power = periodogram_power(data, linear_fit(data, [Term("linear_scale")]))
    assert len(freqs) > 100 and power.max() > 0
    x = np.unique(table.target)
    assert on_grid(x, 0.5) is not None
    step = float(np.min(np.diff(x)))
    moved = x.copy()
    moved[int(rng.integers(1, len(x)))] += 1e-5  # one position 10 nm off its node: 3e-5 rad at 2 mm
    assert on_grid(moved, 0.5) is None
    assert on_grid(moved, 0.1) is not None  # where no sine searched turns by 1e-5 rad
    assert on_grid(x[:periodogram.GRID_POSITIONS - 1], 0.5) is None  # too few to pay for an FFT
    sparse = np.concatenate([x[:periodogram.GRID_POSITIONS], x[-1] + step * np.arange(1, 4) * 10**5])
    assert on_grid(sparse, 0.5) is None  # a grid mostly of empty nodes


def test_a_long_fine_grid_held_to_a_micrometre_is_a_grid():
    """50,000 positions 0.04 mm apart over 2 m, as a point table holds them (to 1e-6 mm): the smallest
    gap errs the step by a part in 10⁵, which counted from the first position misplaces the last
    nodes; each gap counted on its own places every one."""
    x = np.round(np.linspace(0.0, 2000.0, 50_000), 6)
    grid = on_grid(x, 0.5)
    assert grid is not None
    nodes, step = grid
    assert np.array_equal(nodes, np.arange(50_000))
    assert step == pytest.approx(2000.0 / 49_999, rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_the_chirp_transform_is_the_fourier_sum_at_its_frequencies(seed):
    """chirp_dft against its definition, Σₙ v[n]·exp(−2πi·n·(start + k·stride/length)), on drawn
    sizes, starts and strides."""
    from campaign.discovery.periodogram import chirp_dft

    rng = np.random.default_rng(7300 + seed)
    nodes, outputs = int(rng.integers(5, 400)), int(rng.integers(1, 300))
    length, stride, start = int(rng.integers(nodes, 8 * nodes)), int(rng.integers(1, 3)), float(rng.uniform(0, 0.1))
    values = rng.normal(size=(nodes, 3))
    n, k = np.arange(nodes), np.arange(outputs)
    expected = np.exp(-2j * np.pi * np.outer(start + k * stride / length, n)) @ values
    assert np.abs(chirp_dft(values, outputs, start, stride, length) - expected).max() < 1e-10 * np.abs(expected).max()

"""The points `axiscal run` records on the simulated machine against the simulator's truth.

A backlash-only axis (2 µm, the shipped horizontal config's scatter and reading noise): every
recorded point must be where the simulated carriage really was at its capture (its approach's
scatter included), with the stability trigger as with a fixed dwell, and the backlash fitted from
the points must name the true 2 µm within its own standard error. The axis has no wait-dependent
effect, so the truth at the capture is also the settled truth: a capture taken too early, or a
reversal the machine takes up differently from the fitted -d·b/2, would show here."""

from __future__ import annotations

import re

import numpy as np
import pytest

from campaign.pointtable import read_points
from drivers.sim.machine import SimAxisPhysics
from tests.conftest import DATA

TRUE_B_UM = 2.0
MACHINE = (f"[effects.backlash]\nb_um = {TRUE_B_UM}\n"
           "[effects.noise]\nsigma_um = 0.34\nreading_sigma_um = 0.05\n")
MEASURE = SimAxisPhysics.measure
"""The simulated interferometer's reading, as the simulated machine has it."""


def backlash_fit(deviation_um: np.ndarray, direction: np.ndarray) -> tuple[float, float]:
    """Least-squares fit of deviation = offset - d·b/2: (b µm, its standard error µm)."""
    design = np.column_stack([np.ones_like(deviation_um), -direction / 2])
    coef, residual, _, _ = np.linalg.lstsq(design, deviation_um, rcond=None)
    dof = len(deviation_um) - 2
    variance = float(residual[0]) / dof
    covariance = variance * np.linalg.inv(design.T @ design)
    return float(coef[1]), float(np.sqrt(covariance[1, 1]))


def record(cli, tmp_path, monkeypatch, seed: int, method: str):
    """Run the campaign; returns its point table and the truth (µm, no reading noise) at each
    point's capture."""
    truth_at: dict[float, float] = {}

    def measure_and_note(physics: SimAxisPhysics, t: float) -> dict:
        reading = MEASURE(physics, t)
        truth_at[round(t, 6)] = physics.true_position(t, with_reading_noise=False)
        return reading

    monkeypatch.setattr(SimAxisPhysics, "measure", measure_and_note)
    tmp_path.mkdir(exist_ok=True)
    (tmp_path / "machine.toml").write_text(MACHINE)
    config = (DATA / "configs" / "horizontal-sim.toml").read_text()
    config = re.sub(r"(?m)^model = .*$", f'model = "{tmp_path / "machine.toml"}"', config)
    config = re.sub(r"\[sim\]\nseed = \d+", f"[sim]\nseed = {seed}", config)
    config = config.replace('method = "stable"', f'method = "{method}"')
    (tmp_path / "c.toml").write_text(config)
    assert cli("run", tmp_path / "c.toml", "--out", tmp_path / "m").code == 0
    table = read_points(tmp_path / "m" / "points.csv")
    truth_um = np.array([(truth_at[round(float(t), 6)] - x) * 1e3
                         for t, x in zip(table.optional["time_s"], table.target, strict=True)])
    return table, truth_um


@pytest.mark.machine
@pytest.mark.parametrize("method", ["stable", "dwell"])
@pytest.mark.parametrize("seed", [21])
def test_each_point_is_where_the_carriage_was(cli, tmp_path, monkeypatch, seed, method):
    """The capture: what was recorded is where the carriage was, to the reading noise (the
    recorded reversal within a quarter of its own standard error of the true one)."""
    table, truth_um = record(cli, tmp_path, monkeypatch, seed, method)
    measured_b, measured_se = backlash_fit(table.deviation, table.direction)
    truth_b, _ = backlash_fit(truth_um, table.direction)
    error_b, error_se = backlash_fit(table.deviation - truth_um, table.direction)
    assert abs(error_b) <= 4 * error_se, (error_b, error_se)
    assert abs(measured_b - truth_b) <= 0.25 * measured_se, (measured_b, truth_b, measured_se)


@pytest.mark.machine
def test_the_fitted_backlash_is_the_true_one_over_seeds(cli, tmp_path, monkeypatch):
    """The reversal: four campaigns with the stability trigger, each fit within 3.5 of its standard
    errors of the true 2 µm, their mean within 3 standard errors of the mean (a 0.12 µm shortfall,
    what a reviewer once reported, is about 3.7 of them; six campaigns made it 4.5, at a quarter
    more of the suite's time)."""
    fits = []
    for seed in range(31, 35):
        table, _ = record(cli, tmp_path / str(seed), monkeypatch, seed, "stable")
        fits.append(backlash_fit(table.deviation, table.direction))
    b_um, se_um = np.array(fits).T
    assert np.all(np.abs(b_um - TRUE_B_UM) <= 3.5 * se_um), fits
    pooled_se = float(np.sqrt(np.sum(se_um**2))) / len(se_um)
    assert abs(float(b_um.mean()) - TRUE_B_UM) <= 3 * pooled_se, (b_um.mean(), pooled_se, fits)

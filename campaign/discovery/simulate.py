"""A fast, deterministic simulation of a campaign's point table under an error model.

It walks the plan of a config (campaign.plan) on a timeline and, at each captured point, averages
the same `ErrorModel.deviation_um` the simulated machine uses over the capture window's samples,
plus the per-approach scatter N(0, sigma_um) and the per-sample reading noise N(0,
reading_sigma_um). No ADS, no pty, no clock: a 110-point campaign takes milliseconds.

What it simplifies, compared with the simulated machine (drivers/sim/machine.py):
- moves take `campaign.plan.move_time_s` (trapezoidal at the plan velocity and the axis
  acceleration); the executor's tick quantisation, PLC cycle and in-position wait are left out, so
  times differ by a fraction of a second per move;
- the capture averages the samples at every 1/rate_hz over the window, ending at the end of the
  dwell; the deviation during a sample is taken at the target (the carriage is at rest);
- the random streams differ from the machine's: the same seed gives a statistically, not
  bitwise, equal campaign;
- no beam loss, no faults; the environment is simulated only when asked (`Environment`): the air
  and material temperatures follow a ramp (linear, or exponential with a time constant) and the
  reading carries the error an instrument without air compensation (or material normalisation)
  shows, with the log written as the point table's environment columns.

Units: positions mm (deg for a rotary axis), deviations µm (arcsec), times s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from campaign.config import Config
from campaign.edlen import REFERENCE_TEMPERATURE_C, refractive_index
from campaign.model import ErrorModel
from campaign.plan import build_plan, move_time_s
from campaign.pointtable import PointTable

SAMPLE_PERIOD_META = "sample_period_s"
"""Point-table metadata key: the instrument's sample period, s (for the capture averages)."""


@dataclass(frozen=True)
class Environment:
    """The air and machine temperature during a simulated campaign, and what they do to the reading.

    Each logged quantity goes from its start to its end value over the campaign (from t = 0 to the
    last capture), linearly in time, or as 1 - exp(-t/tau_s) when tau_s is given. Each is a
    (start, end) pair; material_temp_c None means no material sensor (no column).

    air_factor: the share of the air's refractive-index change the reading carries: 1 for an
    instrument that keeps the index it had at t = 0 (no air compensation), 0 for one that
    compensates from the log. The reading error is air_factor · x · (n(t)/n(0) - 1), µm for x in
    µm: the reference's -Δn·x, negative when the air warms (opposite to screw growth), pivoting at
    the laser datum x = 0.
    alpha_ppm_per_k: the expansion seen in the reading, α·(T_m - 20)·x, µm/m per K (0: the table is
    normalised to 20 °C).
    log_sigma: the sensors' noise, per logged value (°C, hPa, %), 0 for a perfect log.
    """

    air_temp_c: tuple[float, float] = (20.0, 20.0)
    air_pressure_hpa: tuple[float, float] = (1013.25, 1013.25)
    humidity_pct: tuple[float, float] = (50.0, 50.0)
    material_temp_c: tuple[float, float] | None = None
    tau_s: float | None = None
    air_factor: float = 1.0
    alpha_ppm_per_k: float = 0.0
    log_sigma: float = 0.0

    def values(self, t: ArrayLike, t_end: float) -> dict[str, np.ndarray]:
        """The true values at times t (s): column name -> array (°C, hPa, %)."""
        t = np.asarray(t, dtype=float)
        if self.tau_s is None:
            share = t / max(t_end, 1e-9)
        else:
            share = (1 - np.exp(-t / self.tau_s)) / (1 - math.exp(-max(t_end, 1e-9) / self.tau_s))
        pairs = {"air_temp_c": self.air_temp_c, "air_pressure_hpa": self.air_pressure_hpa,
                 "humidity_pct": self.humidity_pct, "material_temp_c": self.material_temp_c}
        return {k: v[0] + (v[1] - v[0]) * share for k, v in pairs.items() if v is not None}

    def deviation_um(self, x: ArrayLike, t: ArrayLike, t_end: float) -> np.ndarray:
        """The reading error, µm, at position x (mm) and times t (s) (broadcast)."""
        v = self.values(t, t_end)
        index = np.vectorize(lambda tc, p, rh: refractive_index(tc, p * 100.0, rh))
        n0 = refractive_index(self.air_temp_c[0], self.air_pressure_hpa[0] * 100.0, self.humidity_pct[0])
        n = index(v["air_temp_c"], v["air_pressure_hpa"], v["humidity_pct"])
        error = self.air_factor * np.asarray(x, dtype=float) * 1e3 * (n / n0 - 1)
        if self.material_temp_c is not None and self.alpha_ppm_per_k:
            error = error + self.alpha_ppm_per_k * np.asarray(x, dtype=float) * 1e-3 * (
                v["material_temp_c"] - REFERENCE_TEMPERATURE_C)
        return error


def capture_average_um(model: ErrorModel, x: ArrayLike, d: ArrayLike, t_samples: np.ndarray,
                       w_samples: np.ndarray) -> np.ndarray:
    """The deterministic deviation (µm) each point's capture reads: the mean of
    `model.deviation_um` over its samples. x (mm) and d (±1) have one entry per point; t_samples
    (s since start) and w_samples (s since arrival) one row per point, one column per sample (NaN
    pads rows with fewer samples)."""
    x = np.asarray(x, dtype=float)[:, None]
    d = np.asarray(d, dtype=float)[:, None]
    values = model.deviation_um(x, d, np.nan_to_num(t_samples), np.nan_to_num(w_samples, nan=np.inf))
    return np.nanmean(np.where(np.isnan(t_samples), np.nan, values), axis=1)


def sample_times(capture_end_s: ArrayLike, capture_wait_s: ArrayLike, samples: ArrayLike,
                 sample_period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(t, w) sample matrices, s: sample j of a point is at capture end - j·sample_period_s, for
    `samples` samples (NaN beyond a point's count)."""
    end = np.asarray(capture_end_s, dtype=float)
    wait = np.asarray(capture_wait_s, dtype=float)
    count = np.asarray(samples, dtype=int)
    back = np.arange(max(int(count.max()), 1)) * sample_period_s
    valid = back[None, :] < (count[:, None] - 0.5) * sample_period_s
    t = np.where(valid, end[:, None] - back[None, :], np.nan)
    w = np.where(valid, wait[:, None] - back[None, :], np.nan)
    return t, w


def simulate_campaign(config: Config, model: ErrorModel, seed: int = 1, dwell_jitter: float = 0.0,
                      dwells_s: list[float] | None = None, environment: Environment | None = None) -> PointTable:
    """Simulate the campaign of `config` on an axis with error `model`, noise drawn with `seed`.

    dwell_jitter: each point's dwell is the plan's dwell × U(1 - dwell_jitter, 1 + dwell_jitter)
    (never shorter than the capture window), so that settling can be told from backlash.
    dwells_s: explicit dwell per point, s (overrides the jitter). Only for the dwell capture method.
    environment: the air (and material) log and its effect on the reading (see `Environment`);
    None: no environment columns and no environment error.

    Returns a PointTable with the optional columns time_s (capture end, s since start),
    capture_wait_s (wait since arrival at capture end, s) and samples (readings averaged), the
    environment columns when `environment` is given (each point's log: the value at the middle of
    its capture window), and `meta["sample_period_s"]`.
    """
    if config.capture.method != "dwell":
        raise ValueError("simulate_campaign models the dwell capture method only")
    plan = build_plan(config)
    rng = np.random.default_rng(seed)
    accel = config.axis.max_acceleration
    period = 1.0 / config.instrument.rate_hz
    dwell = config.plan.dwell_s
    n_points = len(plan.points)
    if dwells_s is None:
        dwells_s = list(dwell * rng.uniform(1 - dwell_jitter, 1 + dwell_jitter, n_points))
    elif len(dwells_s) != n_points:
        raise ValueError(f"dwells_s has {len(dwells_s)} entries for {n_points} points")

    rows: list[tuple] = []
    t, here = 0.0, None
    for stop in plan.stops():
        if here is not None:
            t += move_time_s(stop.position - here, stop.move.velocity, accel)
        here = stop.position
        if stop.point is not None and stop.capture is not None:  # the Settle is the dwell minus the window
            point, window = stop.point, stop.capture.window_s
            settle = max(dwells_s[point.index], window) - window
            count = max(round(window / period), 1)
            t += settle + window
            rows.append((point.run, point.direction, point.target, t, settle + window, count))
    run, direction, target, end, wait, counts = (np.array(c) for c in zip(*rows))
    t_samples, w_samples = sample_times(end, wait, counts, period)
    deviation = capture_average_um(model, target, direction, t_samples, w_samples)
    deviation += rng.normal(0.0, model.sigma_um, len(rows)) if model.sigma_um else 0.0
    if model.reading_sigma_um:
        reading = rng.normal(0.0, model.reading_sigma_um, t_samples.shape)
        deviation += np.nanmean(np.where(np.isnan(t_samples), np.nan, reading), axis=1)
    optional = {"time_s": end, "capture_wait_s": wait, "samples": counts.astype(float)}
    if environment is not None:
        t_end = float(end[-1])
        valid = ~np.isnan(t_samples)
        env_error = environment.deviation_um(target[:, None], np.where(valid, t_samples, 0.0), t_end)
        deviation += np.nanmean(np.where(valid, env_error, np.nan), axis=1)
        middle = np.nanmean(t_samples, axis=1)
        for name, values in environment.values(middle, t_end).items():
            noisy = values + (rng.normal(0.0, environment.log_sigma, len(values)) if environment.log_sigma else 0.0)
            optional[name] = np.round(noisy, 4)
    return PointTable(
        kind=config.axis.kind, run=run.astype(int), direction=direction.astype(int),
        target=target.astype(float), deviation=deviation,
        optional=optional,
        meta={SAMPLE_PERIOD_META: f"{period:g}", "plan_seed": str(config.plan.seed)},
        source="<simulated>")

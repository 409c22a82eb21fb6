"""environment: the slope that follows a campaign's environment log (the air's refractive index, the
material's temperature). Discovery only: it follows one campaign's log, so it is not a parameter of
the axis model and the simulator has no deviation for it (its environment comes from the log)."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import LASER_DATUM_MM, Effect, EffectForm, Ranges, Samples, Shape

ENVIRONMENT_RANGES = {"air_factor": (-0.5, 1.5), "alpha_ppm_per_k": (-5.0, 30.0)}
"""Physically plausible environment coefficients: the share of the air index change the reading
carries (0 to 1, with room for noise), and an expansion coefficient, µm/m per K (invar to
aluminium and beyond)."""


def air(data: Samples) -> np.ndarray:
    if data.air_index_change is None:
        raise ValueError("the air term needs the air log")
    return data.air_index_change


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    """The slope that follows the log: the air's refractive-index change since the first point,
    x·(n/n0 - 1) (µm per unit air_factor), and the material's temperature above 20 °C,
    x·(T_m - 20) (µm per µm/m/K), both about the laser datum."""
    x = data.x - LASER_DATUM_MM
    cols = []
    if shape.get("air"):
        cols.append(x * 1e3 * air(data))
    if shape.get("material"):
        cols.append(x * 1e-3 * (data.env["material_temp_c"] - 20.0))
    return np.column_stack(cols) if cols else np.zeros((len(data), 0))


def to_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    names = [k for k, flag in (("air_factor", "air"), ("alpha_ppm_per_k", "material")) if shape.get(flag)]
    return {k: float(v) for k, v in zip(names, c)}


def environment_logs(data: Samples) -> list[str]:
    """Which environment logs vary in this campaign: "air" and/or "material"."""
    logs = []
    if data.air_index_change is not None and np.ptp(data.air_index_change) > 0:
        logs.append("air")
    if "material_temp_c" in data.env and np.ptp(data.env["material_temp_c"]) > 0:
        logs.append("material")
    return logs


def grid(data: Samples, held: Shape) -> list[Shape]:
    logs = environment_logs(data)
    variants = [{log: 1.0} for log in logs]
    return variants + ([{log: 1.0 for log in logs}] if len(logs) > 1 else [])


def ranges(data: Samples) -> Ranges:
    return dict(ENVIRONMENT_RANGES)


EFFECT = Effect(
    "environment", 80, {"air_factor": "share of the air log's refractive-index change in the reading, 1",
                        "alpha_ppm_per_k": "expansion following the material log, µm/m per K"},
    None,
    EffectForm("environment", ("air_factor", "alpha_ppm_per_k"), (), "run", columns, to_params, grid,
               sizes=("air_factor", "alpha_ppm_per_k"), ranges=ranges),
    follow_up="runs", needs="log")

"""thermal_drift: the screw growing as it warms, towards a steady state (an exponential in time)
about its fixed bearing."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import (
    GROWTH_PPM,
    Effect,
    EffectForm,
    Ranges,
    Samples,
    Shape,
    duration,
    dwell,
    mean_samples,
    tau_grid,
    travel,
)


def warming(data: Samples, tau_s: float) -> np.ndarray:
    return mean_samples(1 - np.exp(-data.t / tau_s))


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    f = warming(data, shape["tau_s"])
    if "pivot_mm" in held:
        return ((data.x - held["pivot_mm"]) * 1e-3 * f)[:, None]
    return np.column_stack([data.x * 1e-3 * f, -1e-3 * f])


def to_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    if "pivot_mm" in held:
        return {"growth_ppm": float(c[0]), "tau_s": shape["tau_s"], "pivot_mm": held["pivot_mm"]}
    pivot = float(c[1] / c[0]) if abs(c[0]) > 1e-12 else 0.0
    return {"growth_ppm": float(c[0]), "tau_s": shape["tau_s"], "pivot_mm": pivot}


def grid(data: Samples, held: Shape) -> list[Shape]:
    span = duration(data)
    return tau_grid(span / 30, span * 3)


def ranges(data: Samples) -> Ranges:
    """Growth within GROWTH_PPM; a time constant between the dwell and ten times the campaign; a
    pivot within two travels of the targets (further, it is the datum drifting, not the screw)."""
    lo, hi, length = float(data.x.min()), float(data.x.max()), travel(data)
    return {"growth_ppm": (-GROWTH_PPM, GROWTH_PPM), "tau_s": (dwell(data), 10 * duration(data)),
            "pivot_mm": (lo - 2 * length, hi + 2 * length)}


EFFECT = Effect(
    "thermal_drift", 40, {"growth_ppm": "steady-state screw growth, µm/m", "tau_s": "time constant, s",
                          "pivot_mm": "fixed bearing position, mm"},
    lambda p, x, d, t, w: p["growth_ppm"] * 1e-3 * (x - p["pivot_mm"]) * (1 - np.exp(-t / p["tau_s"])),
    EffectForm("thermal_drift", ("growth_ppm", "growth_pivot"), ("tau_s",), "run", columns, to_params, grid,
               sizes=("growth_ppm",), ranges=ranges),
    defaults={"pivot_mm": 0.0}, positive=("tau_s",),
    rivals={"linear_scale": "more runs over a longer time: a drift changes from run to run",
            "linear_drift": (
                "a longer campaign (several of the drift's time constants, or a second campaign later): an "
                "exponential growth levels off, a linear one does not")},
    tends_to="linear_drift",
    derived=lambda p: {"initial_rate_ppm_per_h": p["growth_ppm"] / p["tau_s"] * 3600},
    follow_up="runs", needs="runs")

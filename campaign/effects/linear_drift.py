"""linear_drift: a slope that changes at a constant rate during the campaign (a shop warming up)."""

from __future__ import annotations

import numpy as np

from campaign.effects import thermal_drift
from campaign.effects.base import GROWTH_PPM, Effect, EffectForm, Ranges, Samples, Shape, duration, hours


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    h = hours(data)
    if "pivot_mm" in held:
        return ((data.x - held["pivot_mm"]) * 1e-3 * h)[:, None]
    return np.column_stack([data.x * 1e-3 * h, -1e-3 * h])


def to_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    if "pivot_mm" in held:
        return {"rate_ppm_per_h": float(c[0]), "pivot_mm": held["pivot_mm"]}
    pivot = float(c[1] / c[0]) if abs(c[0]) > 1e-12 else 0.0
    return {"rate_ppm_per_h": float(c[0]), "pivot_mm": pivot}


def ranges(data: Samples) -> Ranges:
    """A slope change over the campaign within GROWTH_PPM; the pivot as thermal drift's."""
    length_h = duration(data) / 3600
    return {"rate_ppm_per_h": (-GROWTH_PPM / length_h, GROWTH_PPM / length_h),
            "pivot_mm": thermal_drift.ranges(data)["pivot_mm"]}


EFFECT = Effect(
    "linear_drift", 45, {"rate_ppm_per_h": "slope change per hour, µm/m per h", "pivot_mm": "where the slope pivots, mm"},
    lambda p, x, d, t, w: p["rate_ppm_per_h"] * 1e-3 * (x - p["pivot_mm"]) * t / 3600,
    EffectForm("linear_drift", ("rate_ppm_per_h", "rate_pivot"), (), "run", columns, to_params,
               sizes=("rate_ppm_per_h",), ranges=ranges),
    defaults={"pivot_mm": 0.0}, follow_up="runs", needs="runs")

"""periodic_lead: a screw-lead error that repeats every turn of the screw (a sine of the position)."""

from __future__ import annotations

import math

import numpy as np

from campaign.effects.base import SIZE_UM, Effect, EffectForm, Ranges, Samples, Shape, period_limits


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    angle = 2 * np.pi * data.x / shape["period_mm"]
    return np.column_stack([np.sin(angle), np.cos(angle)])


def to_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    return {"amplitude_um": float(math.hypot(c[0], c[1])), "period_mm": shape["period_mm"],
            "phase_rad": float(math.atan2(c[1], c[0]))}


def ranges(data: Samples) -> Ranges:
    return {"amplitude_um": (0.0, SIZE_UM), "period_mm": period_limits(data)}


EFFECT = Effect(
    "periodic_lead", 30, {"amplitude_um": "amplitude, µm", "period_mm": "period (screw lead), mm",
                          "phase_rad": "phase at x = 0, rad"},
    lambda p, x, d, t, w: p["amplitude_um"] * np.sin(2 * np.pi * x / p["period_mm"] + p["phase_rad"]),
    EffectForm("periodic_lead", ("sin_um", "cos_um"), ("period_mm",), "target", columns, to_params,
               sizes=("amplitude_um",), ranges=ranges),
    defaults={"phase_rad": 0.0}, positive=("period_mm",),
    rivals={"nonlinear_lead": (
        "more targets (at least 4 per screw lead over part of the travel, offsets = \"golden\"), or the known "
        "screw lead in the model (periodic_lead.period_mm) so that only its amplitude is fitted")},
    follow_up="cluster", may_soak=True, period="period_mm")

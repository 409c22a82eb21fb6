"""position_dependent_backlash: a reversal that grows along the travel (a screw worn more at one end)."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import SCALE_PPM, SIZE_UM, Effect, EffectForm, Ranges, Samples, Shape


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    return np.column_stack([-data.d / 2, -data.d * data.x * 1e-3 / 2])


def ranges(data: Samples) -> Ranges:
    return {"b0_um": (-SIZE_UM, SIZE_UM), "k_ppm": (-SCALE_PPM, SCALE_PPM)}


EFFECT = Effect(
    "position_dependent_backlash", 60, {"b0_um": "backlash at x = 0, µm", "k_ppm": "growth along the axis, µm/m"},
    lambda p, x, d, t, w: -d * (p["b0_um"] + p["k_ppm"] * x * 1e-3) / 2,
    EffectForm("position_dependent_backlash", ("b0_um", "k_ppm"), (), "target", columns,
               sizes=("k_ppm",), ranges=ranges),
    defaults={"b0_um": 0.0}, nested_in="backlash", follow_up="travel", may_soak=True)

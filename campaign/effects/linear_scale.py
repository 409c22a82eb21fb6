"""linear_scale: a lead (scale) error that grows along the travel, µm per m."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import SCALE_PPM, Effect, EffectForm, Ranges, Samples, Shape


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    return (data.x * 1e-3)[:, None]


def ranges(data: Samples) -> Ranges:
    return {"ppm": (-SCALE_PPM, SCALE_PPM)}


EFFECT = Effect(
    "linear_scale", 10, {"ppm": "cumulative lead error, µm/m"},
    lambda p, x, d, t, w: p["ppm"] * x * 1e-3,
    EffectForm("linear_scale", ("ppm",), (), "target", columns, sizes=("ppm",), ranges=ranges))

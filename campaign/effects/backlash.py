"""backlash: lost motion at a reversal, the same everywhere along the travel."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import SIZE_UM, Effect, EffectForm, Ranges, Samples, Shape


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    return (-data.d / 2)[:, None]


def ranges(data: Samples) -> Ranges:
    return {"b_um": (-SIZE_UM, SIZE_UM)}


EFFECT = Effect(
    "backlash", 20, {"b_um": "lost motion at reversal, µm (e = -d*b/2)"},
    lambda p, x, d, t, w: -d * p["b_um"] / 2,
    EffectForm("backlash", ("b_um",), (), "target", columns, sizes=("b_um",), ranges=ranges),
    rivals={"position_dependent_backlash": (
        "both directions at targets over the whole travel: a reversal that grows along the travel is "
        "position_dependent_backlash, a constant one backlash")},
    follow_up="travel", may_soak=True, reversal=True)

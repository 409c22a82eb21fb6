"""settling: a deviation left at arrival that decays with the wait before capture."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import (
    SIZE_UM,
    Effect,
    EffectForm,
    Ranges,
    Samples,
    Shape,
    mean_samples,
    stop_waits,
    tau_grid,
    waits,
)

DWELLS_HOW_TO_TELL = (
    "a campaign whose wait before each capture varies over a decade (fixed dwells from 0.5 s to 5 s, "
    "e.g. two campaigns with --capture dwell at dwell_s = 0.5 and 5): settling fades with the wait, "
    "backlash does not")


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    return (-data.d * mean_samples(np.exp(-waits(data) / shape["tau_s"])))[:, None]


def grid(data: Samples, held: Shape) -> list[Shape]:
    measured = waits(data)[np.isfinite(waits(data))]
    return tau_grid(max(measured.min() / 10, 1e-3), measured.max() * 2)


def ranges(data: Samples) -> Ranges:
    """A size within SIZE_UM and a time constant from 1 ms to ten times the longest wait."""
    return {"e0_um": (-SIZE_UM, SIZE_UM), "tau_s": (1e-3, 10 * float(np.max(stop_waits(data), initial=1e-3)))}


EFFECT = Effect(
    "settling", 70, {"e0_um": "deviation left at arrival, µm (decays)", "tau_s": "settling time constant, s"},
    lambda p, x, d, t, w: -d * p["e0_um"] * np.exp(-w / p["tau_s"]),
    EffectForm("settling", ("e0_um",), ("tau_s",), "target", columns, None, grid, sizes=("e0_um",), ranges=ranges),
    positive=("tau_s",),
    rivals={"backlash": DWELLS_HOW_TO_TELL, "position_dependent_backlash": DWELLS_HOW_TO_TELL},
    follow_up="dwells", may_soak=True, needs="wait")

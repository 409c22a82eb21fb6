"""local_step: a step in the deviation, as at a joint between two scale or screw sections
(simulator only)."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import Effect, side
from campaign.effects.local_defect import DIRECTIONS


def step(p: dict[str, float], x: np.ndarray, d: np.ndarray) -> np.ndarray:
    """A rise of height_um centred at at_mm over rise_mm (a smooth step: 0 before, height after)."""
    u = np.clip((x - p["at_mm"]) / p["rise_mm"] + 0.5, 0.0, 1.0)
    return p["height_um"] * (3 * u**2 - 2 * u**3) * side(p, d)


EFFECT = Effect(
    "local_step", 120, {"height_um": "the deviation after the step less before it, µm",
                        "at_mm": "the middle of the rise, mm", "rise_mm": "the length of the rise, mm",
                        "direction": "0: both directions; +1 or -1: only when approached from that side, 1"},
    lambda p, x, d, t, w: step(p, x, d),
    defaults={"direction": 0.0}, choices={"direction": DIRECTIONS}, positive=("rise_mm",))

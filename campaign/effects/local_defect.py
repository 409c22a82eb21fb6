"""local_defect: a screw defect or worn zone, a raised cosine at one place (simulator only: discovery
has no name for it and must locate it)."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import Effect, side

DIRECTIONS = (0.0, 1.0, -1.0)
"""A local error's `direction`: 0 both directions; +1 or -1 only when approached from that side."""


def defect(p: dict[str, float], x: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A raised cosine, full width at half height width_mm, its two sides stretched by 1 ± skew, and
    growing linearly in time by growth_per_h of its size per hour."""
    skew = p.get("skew", 0.0)
    half = np.where(x < p["centre_mm"], 1 - skew, 1 + skew) * p["width_mm"]
    reach = np.clip((x - p["centre_mm"]) / half, -1.0, 1.0)  # cos² is half at width/2
    grown = 1 + p.get("growth_per_h", 0.0) * t / 3600
    return p["amplitude_um"] * np.cos(np.pi * reach / 2) ** 2 * side(p, d) * grown


EFFECT = Effect(
    "local_defect", 100, {"amplitude_um": "peak deviation, µm", "centre_mm": "where it peaks, mm",
                          "width_mm": "full width at half the peak, mm",
                          "direction": "0: both directions; +1 or -1: only when approached from that side, 1",
                          "skew": "the side above the centre is 1 + skew times as wide, the side below "
                                  "1 - skew (-0.9 to 0.9), 1",
                          "growth_per_h": "growth of the size in time, a share of it per hour, 1/h"},
    lambda p, x, d, t, w: defect(p, x, d, t),
    defaults={"direction": 0.0, "skew": 0.0, "growth_per_h": 0.0}, choices={"direction": DIRECTIONS},
    limits={"skew": (-0.9, 0.9)}, positive=("width_mm",))

"""partial_wave: a screw-lead wave over part of the travel only (a lead worn in one section;
simulator only)."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import Effect, span_ends


def wave(p: dict[str, float], x: np.ndarray) -> np.ndarray:
    inside = (x >= p["start_mm"]) & (x <= p["end_mm"])
    return p["amplitude_um"] * np.sin(2 * np.pi * x / p["period_mm"] + p["phase_rad"]) * inside


EFFECT = Effect(
    "partial_wave", 130, {"amplitude_um": "amplitude, µm", "period_mm": "period, mm",
                          "phase_rad": "phase at x = 0, rad", "start_mm": "where the wave starts, mm",
                          "end_mm": "where it ends, mm"},
    lambda p, x, d, t, w: wave(p, x),
    defaults={"phase_rad": 0.0}, positive=("period_mm",), check=span_ends)

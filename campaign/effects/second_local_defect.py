"""second_local_defect: a second local_defect on the same axis (simulator only)."""

from __future__ import annotations

from campaign.effects.base import Effect
from campaign.effects.local_defect import DIRECTIONS, defect

EFFECT = Effect(
    "second_local_defect", 110, {"amplitude_um": "peak deviation, µm", "centre_mm": "where it peaks, mm",
                                 "width_mm": "full width at half the peak, mm",
                                 "direction": "0: both directions; +1 or -1: only when approached from that "
                                              "side, 1",
                                 "skew": "as local_defect's, 1", "growth_per_h": "as local_defect's, 1/h"},
    lambda p, x, d, t, w: defect(p, x, d, t),
    defaults={"direction": 0.0, "skew": 0.0, "growth_per_h": 0.0}, choices={"direction": DIRECTIONS},
    limits={"skew": (-0.9, 0.9)}, positive=("width_mm",))

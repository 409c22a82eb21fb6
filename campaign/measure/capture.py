"""Capture: turn the readings taken at a target into one measured position.

Pure code. `capture_point` is the one capture of a plan's Capture step: the executor feeds it the
ticks of the running campaign, replay the ticks of a recorded raw stream. How each method captures
is the registry's (`campaign.capture_methods`: dwell, stable, and any registered one); this module
hands a step to its method.
"""

from __future__ import annotations

from campaign.capture_methods import (
    TICK_EPSILON_S,
    BeamLost,
    Captured,
    NotStable,
    Ticks,
    Window,
    capture_dwell,
    capture_stable,
    method,
)
from campaign.plan import Capture

__all__ = ["TICK_EPSILON_S", "BeamLost", "Captured", "NotStable", "capture_dwell", "capture_point",
           "capture_stable"]


def capture_point(step: Capture, deviation_scale: float, ticks: Ticks, start_s: float) -> Captured:
    """Capture `step` as its CaptureSpec's method says, from `ticks`: (time since arrival in s, the
    readings that arrived in that tick), the capture starting at `start_s` after arrival (the dwell
    method averages up to `step.window_s` after the start; the stable method captures at the first
    stable tick, up to `step.timeout_s` after the start). `deviation_scale`: deviation unit per axis
    unit (the spec's tolerances are in deviation unit). BeamLost or NotStable when it cannot capture."""
    window = Window(0.0, step.window_s, step.timeout_s)
    return method(step.spec.method).capture(step.spec, window, deviation_scale, ticks, start_s, step.point.index)

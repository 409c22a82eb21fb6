"""Capture: turn the readings taken at a target into one measured position.

Pure code. `capture_point` is the one capture of a plan's Capture step: the executor feeds it the
ticks of the running campaign, replay the ticks of a recorded raw stream.

- Fixed dwell (the paper's method): the mean of the readings over the capture window, which is the
  last part of the dwell.
- Stability trigger (a position trigger in laser software): capture as soon as the readings of a
  stability window stay within a band and no longer drift, with a timeout; the wait is recorded
  (see `capture_stable`).

Readings with the beam not OK are never averaged: in a dwell they fail the capture (BeamLost), in
the stable method they restart the stability window. Times are in s, positions in axis unit.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from statistics import fmean

import numpy as np

from campaign.plan import Capture
from protocols.hardware import ENV_FIELDS, Reading

TICK_EPSILON_S = 1e-9
"""Times closer than this are the same instant, s (far below any sample period)."""


class BeamLost(Exception):
    """The beam was not OK during the capture window."""


class NotStable(Exception):
    """The stability trigger timed out: the reading never stayed in the band long enough."""


@dataclass(frozen=True)
class Captured:
    """A captured position (axis unit, mean of `samples` readings), its wait after arrival (s),
    and the mean of each environment field present (None where no reading had it)."""

    position: float
    samples: int
    wait_s: float
    env: dict[str, float | None]


def _mean_env(readings: list[Reading]) -> dict[str, float | None]:
    env = {}
    for name in ENV_FIELDS:
        values = [getattr(r, name) for r in readings if getattr(r, name) is not None]
        env[name] = fmean(values) if values else None
    return env


def _captured(readings: list[Reading], wait_s: float) -> Captured:
    return Captured(fmean(r.position for r in readings), len(readings), wait_s, _mean_env(readings))


def capture_dwell(readings: list[Reading], wait_s: float) -> Captured:
    """The dwell method: every reading of the capture window, averaged. BeamLost when any reading
    has the beam not OK, or there is none."""
    if not readings or any(not r.signal_ok for r in readings):
        raise BeamLost("beam not OK during the capture window")
    return _captured(readings, wait_s)


def capture_stable(readings: list[Reading], window_s: float, tolerance: float, drift: float, wait_s: float,
                   ) -> Captured | None:
    """The stability trigger, applied to the readings since arrival (instrument times, s).

    It captures as soon as the last readings span at least `window_s` and are still:
    - band: max - min within `tolerance`, or within 4.5 times the reading noise when the noise is
      larger (the noise is the scatter about a line fitted through the window: a noisier laser
      gets a wider band instead of a timeout);
    - drift: the means of the window's two halves differ by at most `drift`, or by twice the
      noise's own uncertainty of that difference when that is larger. A settling axis still
      creeps: the band alone lets it through while its settling is visible (a bias toward the
      approach direction, like backlash), the drift test waits until the creep has died out.
    The captured position is the fitted line's value at the end of the window: the axis' position
    now, not the mean of a window it was still creeping through. Positions in axis unit; `wait_s`
    is the time since arrival now (s), recorded with the capture. None while not stable; the caller
    enforces the timeout.
    """
    start = 0
    for i, r in enumerate(readings):
        if not r.signal_ok:
            start = i + 1
    good = readings[start:]
    if len(good) < 4:
        return None
    end_t = good[-1].time_s
    if good[0].time_s > end_t - window_s + 1e-9:
        return None  # the good readings do not yet span a whole stability window
    window = [r for r in good if r.time_s >= end_t - window_s - 1e-9]
    if len(window) < 4:
        return None
    t = np.array([r.time_s for r in window]) - end_t
    x = np.array([r.position for r in window])
    slope, level = np.polyfit(t, x, 1)
    noise = float(np.sqrt(np.sum((x - (slope * t + level)) ** 2) / (len(x) - 2)))
    half = len(x) // 2
    if float(np.ptp(x)) > max(tolerance, 4.5 * noise):
        return None
    if abs(float(np.mean(x[half:]) - np.mean(x[:half]))) > max(drift, 2 * noise * np.sqrt(4 / len(x))):
        return None
    return Captured(float(level), len(window), wait_s, _mean_env(window))


def capture_point(step: Capture, deviation_scale: float, ticks: Iterable[tuple[float, list[Reading]]],
                  start_s: float) -> Captured:
    """Capture `step` as its CaptureSpec says, from `ticks`: (time since arrival in s, the readings
    that arrived in that tick), the capture starting at `start_s` after arrival. The dwell method
    averages every reading of the ticks up to `step.window_s` after the start; the stable method
    captures at the first stable tick, up to `step.timeout_s` after the start. `deviation_scale`:
    deviation unit per axis unit (the spec's tolerances are in deviation unit). BeamLost or
    NotStable when it cannot capture."""
    readings: list[Reading] = []
    if step.spec.method == "dwell":
        for wait_s, new in ticks:
            readings.extend(new)
            if wait_s >= start_s + step.window_s - TICK_EPSILON_S:
                return capture_dwell(readings, wait_s)
        raise BeamLost("the capture window ended before its time (no more readings)")
    tolerance = step.spec.stable_tolerance / deviation_scale
    drift = step.spec.stable_drift / deviation_scale
    for wait_s, new in ticks:
        readings.extend(new)
        got = capture_stable(readings, step.window_s, tolerance, drift, wait_s)
        if got is not None:
            return got
        if wait_s >= start_s + step.timeout_s - TICK_EPSILON_S:
            break
    if any(not r.signal_ok for r in readings):
        raise BeamLost("beam not OK long enough for a stable capture")
    raise NotStable(f"reading not stable within {step.timeout_s:g} s at point {step.point.index}")

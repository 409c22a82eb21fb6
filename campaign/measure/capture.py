"""Capture: turn the readings taken at a target into one measured position.

Pure code, used by the executor while a campaign runs and by replay on a recorded raw stream.

- Fixed dwell (the paper's method): the mean of the readings over the capture window, which is the
  last part of the dwell.
- Stability trigger (a position trigger in laser software): capture as soon as the readings have
  stayed within a tolerance band for a stability window, with a timeout; the wait is recorded.

Readings with the beam not OK are never averaged: in a dwell they fail the capture (BeamLost), in
the stable method they restart the stability window. Times are in s, positions in axis unit.
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import fmean

from protocols.hardware import ENV_FIELDS, Reading


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


def capture_stable(readings: list[Reading], window_s: float, tolerance: float, wait_s: float,
                   ) -> Captured | None:
    """The stability trigger, applied to the readings since arrival (instrument times, s).

    Returns the capture as soon as the last readings span at least `window_s` and stay within
    `tolerance` (axis unit, max - min); None while that has not happened yet. `wait_s` is the time
    since arrival now (s), recorded with the capture. The caller enforces the timeout.
    """
    start = 0
    for i, r in enumerate(readings):
        if not r.signal_ok:
            start = i + 1
    good = readings[start:]
    if len(good) < 2:
        return None
    end_t = good[-1].time_s
    if good[0].time_s > end_t - window_s + 1e-9:
        return None  # the good readings do not yet span a whole stability window
    window = [r for r in good if r.time_s >= end_t - window_s - 1e-9]
    positions = [r.position for r in window]
    if max(positions) - min(positions) > tolerance:
        return None
    return _captured(window, wait_s)

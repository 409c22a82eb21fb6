"""The capture methods: the one registry that says how a point's position is taken from the readings.

Every consumer reads it, never a method's name: the config's validation and docs (the choices of
`[capture] method`, `campaign.specs.CaptureSpec`), the plan (the settle and window of a Capture step,
`campaign.plan.capture_at`, or the scan's sweeps), the executor and replay (the capture from the
ticks, `campaign.measure.capture.capture_point`), the report (the sentence on how points were
captured), the program writer (the dwell written at a target) and the command line's choices
(`axiscal replay --capture`).

A method is one `CaptureMethod` object; `register` adds one. The methods shipped:

- dwell: the mean of the readings over the last `average_s` of a fixed dwell (the paper's method);
- stable: capture as soon as the readings of a stability window stay within a band and no longer
  drift, with a timeout (a position trigger in laser software), the wait recorded;
- scan: the axis moves at constant velocity through every target while both streams are recorded;
  the points come from the aligned profile (`campaign.stream.scan`), not from a stop;
- stream: the stream import's own (`axiscal import-stream`): the mean of the last `average_s` of
  each dwell found in a continuous position log; it is never run live.

Readings with the beam not OK are never averaged: in a dwell they fail the capture (BeamLost), in
the stable method they restart the stability window. Times are in s, positions in the axis unit,
tolerances (`stable_tolerance`, `stable_drift`) in the deviation unit (µm or arcsec).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from statistics import fmean
from typing import Protocol

import numpy as np

from protocols.hardware import ENV_FIELDS, Reading

TICK_EPSILON_S = 1e-9
"""Times closer than this are the same instant, s (far below any sample period)."""

Ticks = Iterable[tuple[float, list[Reading]]]
"""(time since arrival s, the readings that arrived in that tick), in order."""


class BeamLost(Exception):
    """The beam was not OK during the capture window."""


class NotStable(Exception):
    """The stability trigger timed out: the reading never stayed in the band long enough."""


@dataclass(frozen=True)
class Captured:
    """A captured position (axis unit, from `samples` readings), its wait after arrival (s),
    and the mean of each environment field present (None where no reading had it)."""

    position: float
    samples: int
    wait_s: float
    env: dict[str, float | None]


class CaptureSettings(Protocol):
    """What a method reads of the [capture] table (campaign.specs.CaptureSpec)."""

    @property
    def method(self) -> str: ...
    @property
    def average_s(self) -> float: ...
    @property
    def stable_tolerance(self) -> float: ...
    @property
    def stable_drift(self) -> float: ...
    @property
    def stable_window_s(self) -> float: ...
    @property
    def stable_timeout_s(self) -> float: ...
    @property
    def scan_velocity(self) -> float | None: ...
    @property
    def scan_window(self) -> float: ...


@dataclass(frozen=True)
class Window:
    """How a capture fits in a stop: the settle before it (s), its window (s: the averaging window,
    or the stability window) and the longest it may take after its start (s)."""

    settle_s: float
    window_s: float
    timeout_s: float


def mean_env(readings: list[Reading]) -> dict[str, float | None]:
    env = {}
    for name in ENV_FIELDS:
        values = [getattr(r, name) for r in readings if getattr(r, name) is not None]
        env[name] = fmean(values) if values else None
    return env


@dataclass(frozen=True)
class CaptureMethod:
    """One capture method and everything its consumers need of it.

    name: the value of `[capture] method`; summary: what it does (config docs, help).
    live: `axiscal run` (the executor) and replay capture with it; False: only a command of its
      own does (the stream import).
    sweeps: the axis moves through the targets at constant velocity (a scan): the plan is a set of
      sweeps, not stops, and the point table comes from the streams afterwards.
    iso_230_2: the axis stops at each target: an ISO 230-2 test (False: the verdict is indicative).
    fixed_dwell: the capture ends with the planned dwell (replay takes its window from the recorded
      end, the program writer writes the planned dwell); False: it decides when to capture.
    window(spec, dwell_s): the settle and window of a capture in a stop of `dwell_s` (s).
    capture(spec, window, deviation_scale, ticks, start_s, point): the position from the ticks
      (BeamLost or NotStable when it cannot), starting `start_s` after arrival; `point` names the
      point in messages; deviation_scale: deviation unit per axis unit.
    describe(spec, position_unit, deviation_unit): the report's sentence (units as written, e.g. mm, µm).
    step_label(window): (what the plan's step list says it does, how long).
    not_iso_why: why a method that is not iso_230_2 gives only indicative figures (the verdict's
      reason); empty for an ISO 230-2 method.
    options: the `[capture]` keys it reads (what a replay with another setting can change).
    value_at_end: the captured position is the axis' position at the capture's end (a line fitted
      through its window, taken at the window's end), not the window's mean: a model of what was
      captured (discovery) evaluates the error there, not over the window's samples.
    """

    name: str
    summary: str
    live: bool
    sweeps: bool
    iso_230_2: bool
    fixed_dwell: bool
    window: Callable[[CaptureSettings, float], Window]
    capture: Callable[[CaptureSettings, Window, float, Ticks, float, int], Captured]
    describe: Callable[[CaptureSettings, str, str], str]
    step_label: Callable[[Window], tuple[str, str]]
    not_iso_why: str = ""
    options: tuple[str, ...] = ()
    value_at_end: bool = False


METHODS: dict[str, CaptureMethod] = {}
"""Every capture method by name, in the order registered."""


def register(method: CaptureMethod) -> CaptureMethod:
    """Add `method`; every consumer sees it from now on. ValueError when its name is registered
    already (two methods of one name would make a recorded `capture:` ambiguous)."""
    if method.name in METHODS:
        raise ValueError(f"a capture method '{method.name}' is registered already")
    if not method.iso_230_2 and not method.not_iso_why:
        raise ValueError(f"capture method '{method.name}': not an ISO 230-2 capture, it must say why (not_iso_why)")
    METHODS[method.name] = method
    return method


def method(name: str) -> CaptureMethod:
    """The method called `name`; KeyError naming the registered ones otherwise."""
    try:
        return METHODS[name]
    except KeyError:
        raise KeyError(f"no capture method '{name}' (registered: {', '.join(METHODS)})") from None


def names(*, live: bool | None = None, sweeps: bool | None = None) -> tuple[str, ...]:
    """The registered names, optionally only those run live (or not) or sweeping (or not)."""
    return tuple(m.name for m in METHODS.values()
                 if (live is None or m.live == live) and (sweeps is None or m.sweeps == sweeps))


# --- dwell --------------------------------------------------------------------------------------

def capture_dwell(readings: list[Reading], wait_s: float) -> Captured:
    """The dwell method: every reading of the capture window, averaged. BeamLost when any reading
    has the beam not OK, or there is none."""
    if not readings or any(not r.signal_ok for r in readings):
        raise BeamLost("beam not OK during the capture window")
    return Captured(fmean(r.position for r in readings), len(readings), wait_s, mean_env(readings))


def _dwell_window(spec: CaptureSettings, dwell_s: float) -> Window:
    window = min(spec.average_s, dwell_s)
    return Window(max(dwell_s - window, 0.0), window, window)


def _dwell_capture(spec: CaptureSettings, w: Window, deviation_scale: float, ticks: Ticks, start_s: float,
                   point: int) -> Captured:
    readings: list[Reading] = []
    for wait_s, new in ticks:
        readings.extend(new)
        if wait_s >= start_s + w.window_s - TICK_EPSILON_S:
            return capture_dwell(readings, wait_s)
    raise BeamLost("the capture window ended before its time (no more readings)")


register(CaptureMethod(
    "dwell", "average the end of a fixed dwell", live=True, sweeps=False, iso_230_2=True, fixed_dwell=True,
    options=("average_s",),
    window=_dwell_window, capture=_dwell_capture,
    describe=lambda spec, pos, dev: f"fixed dwell, mean of the last {spec.average_s:g} s",
    step_label=lambda w: ("capture (average)", f"{w.window_s:g}")))


# --- stable -------------------------------------------------------------------------------------

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
    return Captured(float(level), len(window), wait_s, mean_env(window))


def _stable_capture(spec: CaptureSettings, w: Window, deviation_scale: float, ticks: Ticks, start_s: float,
                    point: int) -> Captured:
    readings: list[Reading] = []
    tolerance = spec.stable_tolerance / deviation_scale
    drift = spec.stable_drift / deviation_scale
    for wait_s, new in ticks:
        readings.extend(new)
        got = capture_stable(readings, w.window_s, tolerance, drift, wait_s)
        if got is not None:
            return got
        if wait_s >= start_s + w.timeout_s - TICK_EPSILON_S:
            break
    if any(not r.signal_ok for r in readings):
        raise BeamLost("beam not OK long enough for a stable capture")
    raise NotStable(f"reading not stable within {w.timeout_s:g} s at point {point}")


register(CaptureMethod(
    "stable", "capture when the reading is stable", live=True, sweeps=False, iso_230_2=True, fixed_dwell=False,
    value_at_end=True, options=("stable_tolerance", "stable_drift", "stable_window_s", "stable_timeout_s"),
    window=lambda spec, dwell_s: Window(0.0, spec.stable_window_s, spec.stable_timeout_s),
    capture=_stable_capture,
    describe=lambda spec, pos, dev: (f"stability trigger, {spec.stable_tolerance:g} {dev} band and "
                                     f"{spec.stable_drift:g} {dev} drift over {spec.stable_window_s:g} s"),
    step_label=lambda w: ("capture (when stable)", f"≤ {w.timeout_s:g}")))


# --- scan and the stream import: captured from a whole stream, not at a stop ---------------------

def _not_at_a_stop(name: str) -> Callable[[CaptureSettings, Window, float, Ticks, float, int], Captured]:
    def capture(spec: CaptureSettings, w: Window, deviation_scale: float, ticks: Ticks, start_s: float,
                point: int) -> Captured:
        raise ValueError(f"the {name} method does not capture at a stop (point {point})")
    return capture


SCAN = register(CaptureMethod(
    "scan", "move at scan_velocity through every target while both streams are recorded; a diagnostic, "
    "not an ISO 230-2 test (docs/scan.md)", live=True, sweeps=True, iso_230_2=False, fixed_dwell=False,
    window=lambda spec, dwell_s: Window(0.0, 0.0, 0.0), capture=_not_at_a_stop("scan"),
    options=("scan_velocity", "scan_window"),
    describe=lambda spec, pos, dev: (f"scan on the move at {spec.scan_velocity or 0:g} {pos}/s, clocks aligned "
                                     f"from the passes, a line through ±{spec.scan_window / 2:g} {pos} about each "
                                     "target (not an ISO 230-2 capture)"),
    step_label=lambda w: ("sweep", ""), not_iso_why="the axis never stops at a target"))
"""The scan method: its name is what a scan's table says it was captured with (`# capture:`)."""

register(CaptureMethod(
    "stream", "the stream import's own: the last average_s of each dwell found in a position log "
    "(axiscal import-stream)", live=False, sweeps=False, iso_230_2=True, fixed_dwell=True,
    window=_dwell_window, capture=_not_at_a_stop("stream"), options=("average_s",),
    describe=lambda spec, pos, dev: f"imported stream, mean of the last {spec.average_s:g} s of each dwell found",
    step_label=lambda w: ("capture (imported)", f"{w.window_s:g}")))

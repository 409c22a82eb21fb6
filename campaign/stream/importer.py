"""Turn a continuous position log from another program into a point table.

The stream (campaign/stream/reader.py) holds sample times (s) and readings in the axis unit (mm or
deg); its environment columns are averaged like the reading. Readings are taken as they are: no
air or material correction is applied.

1. Dwells: a sample is still when the reading is within `still_tolerance` of the reading a quarter
   of the planned dwell earlier; a dwell is a run of still samples (extended back by that quarter,
   joined across a noise spike of SPIKE_SAMPLES) that lasts at least half the planned dwell and
   does not begin at the start of the stream. This only bounds the search: the run may begin
   while the axis still creeps in (a loose tolerance) and ends only after the next move has begun.
   Within it (`settle`), the still part is the longest run of capture-window-long stretches whose
   fitted line shows no trend beyond the noise (campaign/stream/stillness.py): there the reading
   has stopped approaching. Its level, the first clear departure from that level after its last
   still window, and the onset of that departure (`onset`) give the dwell's end: a slow start of
   the next move does not enter the capture either. A dwell with no still stretch is followed
   along the trend of its slowest one.
2. Matching: the dwells are matched in order to the plan's move endpoints. Every measured point
   needs a dwell at its target; overrun stops may be missing (they are motion only); stops after the
   last point are ignored.
3. Capture: like the fixed-dwell method, the mean of the last `capture.average_s` of each dwell,
   never reaching before its still part. How still each capture window was (its trend and noise)
   goes into the point table; the points whose window still trends are named in a warning.

Everything per sample is vectorised numpy/pandas; only the dwells are walked in Python.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from campaign.config import Config
from campaign.errors import InputError
from campaign.plan import Plan, Point
from campaign.pointtable import PointTable
from campaign.stream.reader import Stream, locate
from campaign.stream.stillness import MIN_SAMPLES, LineFits, log_noise, sliding_fits, window_fits
from protocols.units import UNITS, unit_label

SCALE = {"mm": 1000.0, "deg": 3600.0}
"""Axis unit -> deviation unit factor (mm -> µm, deg -> arcsec)."""


@dataclass
class Dwells:
    """Dwells as sample index ranges [start, end] (inclusive) into the stream; `still`: where each
    one's reading stops approaching (its still part begins), the start until `settle` finds it."""

    start: np.ndarray
    end: np.ndarray
    still: np.ndarray


@dataclass
class StreamImport:
    """The result: the point table and what was found on the way."""

    table: PointTable
    dwells: int
    overrun_stops: int
    ignored_stops: int
    warnings: list[str]
    stillness: LineFits
    """Per point: the line fitted through its capture window (axis unit)."""
    noise: float
    """The log's reading noise (axis unit) the stillness is judged against."""


def sample_interval(time: np.ndarray) -> float:
    """The typical time between samples (s): the median over up to 100 000 evenly spread pairs."""
    if len(time) < 2:
        return 0.0
    pick = np.linspace(0, len(time) - 2, min(len(time) - 1, 100_000)).astype(int)  # distinct: spaced >= 1
    return float(np.median(time[pick + 1] - time[pick]))


def find_dwells(time: np.ndarray, reading: np.ndarray, tolerance: float, dwell_s: float) -> Dwells:
    """The dwells of a stream. A sample is still when it is within `tolerance` (axis unit) of the
    reading a quarter of `dwell_s` (s) earlier; a dwell is a run of still samples, extended back by
    that quarter, that lasts at least half of `dwell_s` and does not begin at the first sample."""
    dt = sample_interval(time) or 1e-9
    lag = int(min(len(time), max(1.0, np.ceil(dwell_s / 4 / dt))))  # samples
    still = np.zeros(len(time) + 2, dtype=np.int8)
    with np.errstate(all="ignore"):
        still[lag + 1:-1] = np.abs(reading[lag:] - reading[:-lag]) <= tolerance
    edges = np.diff(still)
    first = np.flatnonzero(edges == 1)
    last = np.flatnonzero(edges == -1) - 1
    # a noise spike beyond the tolerance breaks a dwell for a sample (at the spike and a lag later);
    # a move, even out to an overrun and straight back, breaks it for longer
    if len(first):
        gap = first[1:] - last[:-1] - 1  # samples
        joined = np.concatenate([[True], (gap > SPIKE_SAMPLES) | (time[first[1:]] - time[last[:-1]] > dwell_s / 20)])
        group = np.flatnonzero(joined)  # the first run of each group of runs joined across short gaps
        first, last = first[group], last[np.concatenate([group[1:] - 1, [len(last) - 1]])]
    long = time[last] - time[first] >= dwell_s / 4 - dt  # drops noise flickers at a dwell's edges
    first, last = first[long], last[long]
    start = first - lag
    start[1:] = np.maximum(start[1:], last[:-1] + 1)  # a run may reach back into the previous one
    keep = (start > 0) & (time[last] - time[np.maximum(start, 0)] >= dwell_s / 2 - dt / 2)
    return Dwells(start[keep], last[keep], start[keep])


SPIKE_SAMPLES = 2
"""A dwell broken for at most this many samples (and a twentieth of the dwell) is one dwell: a
noise spike beyond the still tolerance, not a move."""


def onset(time: np.ndarray, y: np.ndarray) -> int:
    """Where a reading that is flat and then leaves it (a slow start, then the move) begins to
    leave: the index c that minimises the residual of y = L + k·(t - t_c)² after t_c (L before),
    by least squares over every c at once (sums of powers of t from the end)."""
    t = time - time[0]
    y = y - np.median(y)

    def from_end(v: np.ndarray) -> np.ndarray:
        return np.cumsum(v[::-1])[::-1]

    tk = [from_end(t**k) for k in range(5)]
    yk = [from_end(y * t**k) for k in range(3)]
    c = np.arange(1, len(y) - 1)
    tc = t[c]
    s1 = tk[2][c] - 2 * tc * tk[1][c] + tc**2 * tk[0][c]
    s2 = tk[4][c] - 4 * tc * tk[3][c] + 6 * tc**2 * tk[2][c] - 4 * tc**3 * tk[1][c] + tc**4 * tk[0][c]
    y1 = yk[2][c] - 2 * tc * yk[1][c] + tc**2 * yk[0][c]
    n, y0 = len(y), float(y.sum())
    with np.errstate(all="ignore"):
        explained = (s2 * y0**2 - 2 * s1 * y0 * y1 + n * y1**2) / (n * s2 - s1**2)
    explained[~np.isfinite(explained)] = -np.inf
    return int(c[np.argmax(explained)])


def longest_run(flags: np.ndarray) -> tuple[int, int]:
    """The first and last index of the longest run of True in `flags` (the earliest of equals)."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    firsts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(ends - firsts))
    return int(firsts[longest]), int(ends[longest]) - 1


def settle(time: np.ndarray, reading: np.ndarray, dwells: Dwells, dwell_s: float, samples: int,
           noise: float) -> Dwells:
    """The dwells from where the reading stops approaching to where it begins to leave (see the
    module text); `samples`: the capture window's length in samples; `noise`: the log's reading
    noise (axis unit, `log_noise`). The search runs from each dwell's start to a quarter of
    `dwell_s` (s) past its end, and at least a window and two groups of SMOOTH samples."""
    dt = sample_interval(time) or 1e-9
    lag = int(max(1.0, np.ceil(dwell_s / 4 / dt)))
    n = max(MIN_SAMPLES, samples)
    parts = []
    for start, end in zip(dwells.start.tolist(), dwells.end.tolist()):
        b = min(end + max(lag, n + 2 * SMOOTH), len(reading) - 1)
        fits, step = sliding_fits(time[start:b + 1], reading[start:b + 1], n)
        still = fits.still(noise)
        if still.any():
            first, last = (start + step * p for p in longest_run(still))
            parts.append((first, last + n, last, b, False))
        elif len(still):  # it never stops moving: from its slowest window, along that window's trend
            first = start + step * int(np.argmin(np.abs(fits.trend)))
            parts.append((first, first + n, first, b, True))
        else:  # too short for one window: a quarter dwell in
            a = min(start + lag, end)
            parts.append((a, min(a + lag, end) + 1, a, b, False))
    limit = max(DEPART_SE * noise / np.sqrt(SMOOTH), 1e-12)  # axis unit
    firsts, ends = [], []
    for (first, level_end, search, b, moving), end in zip(parts, dwells.end.tolist(), strict=True):
        firsts.append(first)
        ends.append(max(end, first))
        if b - search < 2 * SMOOTH:  # the end of the log: up to the end of the still part
            ends[-1] = max(first, min(end, level_end - 1))
            continue
        y = reading[first:b + 1]
        if moving:  # take the window's own trend out: what is left is flat until the move begins
            t = time[first:b + 1] - time[first]
            y = y - np.polyval(np.polyfit(t[:level_end - first], y[:level_end - first], 1), t)
        level = float(np.median(y[:level_end - first:max(1, (level_end - first) // LEVEL_SAMPLES)]))
        means = np.convolve(y[search - first:], np.ones(SMOOTH) / SMOOTH, mode="valid")  # from search + j
        away = np.abs(means - level) > limit
        if not away.any():
            continue
        leave = search + int(np.argmax(away)) + SMOOTH - 1  # the last sample of the first group that left
        fit = max(first, search - n)  # a still stretch before the departure, past any creep left
        if leave - fit >= 3 * SMOOTH:
            ends[-1] = fit + onset(time[fit:leave + 1], y[fit - first:leave - first + 1])
            if abs(y[ends[-1] - first] - level) > ONSET_SIGMA * noise:  # the move began between two samples
                ends[-1] = max(first, ends[-1] - 1)
        else:  # it leaves at once: too few samples to fit, end before the group that left
            ends[-1] = max(first, leave - SMOOTH)
    return Dwells(dwells.start, np.array(ends, dtype=int), np.array(firsts, dtype=int))


LEVEL_SAMPLES = 1000
"""About how many evenly spread samples of a still part give its level (their median)."""


DEPART_SE = 8.0
"""Standard errors of a SMOOTH-sample mean by which the reading must leave a dwell's level before
`settle` looks for where it began to leave."""


SMOOTH = 5
"""Samples averaged when looking for the end of a dwell (`settle`)."""

ONSET_SIGMA = 4.0
"""The onset sample is left out of the dwell when it is this many times the reading noise away
from the level: the move began between it and the sample before (noise alone does so for about
one point in 16 000)."""


def _window_means(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Mean of values[lo:hi] for each pair (hi > lo), vectorised."""
    bounds = np.column_stack([lo, hi]).ravel()
    with np.errstate(all="ignore"):  # absurd readings overflow to inf, which matches no target
        sums = np.add.reduceat(values, bounds[:-1] if bounds[-1] == len(values) else bounds)[::2]
        return sums / (hi - lo)


def capture_windows(stream: Stream, dwells: Dwells, average_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample index ranges [lo, hi) of the last `average_s` (s) of each dwell."""
    hi = dwells.end + 1
    half = sample_interval(stream.time) / 2  # s
    lo = np.searchsorted(stream.time, stream.time[dwells.end] - average_s + half, side="left")
    return np.clip(lo, dwells.still, dwells.end), hi  # at least the last sample


def plan_stops(plan: Plan) -> list[tuple[float, Point | None]]:
    """The plan's move endpoints in order: (position, the point measured there or None)."""
    stops: list[tuple[float, Point | None]] = []
    for stop in plan.stops():
        if stops and stops[-1] == (stop.position, None):
            stops.pop()  # a zero-length move after an overrun stop: one stop
        stops.append((stop.position, stop.point))
    return stops


def match_tolerance(stops: list[tuple[float, Point | None]]) -> float:
    """A quarter of the smallest distance between two planned stop positions (axis unit)."""
    positions = np.unique([p for p, _ in stops])
    return float(np.min(np.diff(positions))) / 4 if len(positions) > 1 else float("inf")


def _describe(point: Point | None, unit: str, total: int) -> str:
    if point is None:
        return "an overrun (no point)"
    sign = "+" if point.direction > 0 else "-"
    return (f"point {point.index + 1} of {total} (run {point.run}, direction {sign}, "
            f"target {point.target:g} {unit})")


def assign_dwells(stream: Stream, dwells: Dwells, positions: np.ndarray, plan: Plan, unit: str,
                  ) -> tuple[list[int], int, int]:
    """Match dwells to the plan: (dwell index per point, overrun stops seen, stops ignored)."""
    stops = plan_stops(plan)
    tol = match_tolerance(stops)
    total = len(plan.points)
    assigned: list[int] = []
    overruns = 0
    j = 0
    for d, pos in enumerate(positions):
        while j < len(stops) and stops[j][1] is None and abs(pos - stops[j][0]) > tol:
            j += 1  # an overrun without a stop
        if j == len(stops):
            return assigned, overruns, len(positions) - d
        target, point = stops[j]
        if not abs(pos - target) <= tol:
            where = locate(stream.source, int(dwells.start[d]), stream.time)
            raise InputError(f"{where}: dwell {d + 1} of {len(positions)} is at {pos:.4f} {unit}, "
                             f"but the plan expects {_describe(point, unit, total)}; "
                             f"the stream has {len(positions)} dwells for {total} points")
        if point is None:
            overruns += 1
        else:
            assigned.append(d)
        j += 1
    if len(assigned) < total:
        missing = plan.points[len(assigned)]
        after = ("" if not assigned else
                 f" after the dwell at {locate(stream.source, int(dwells.end[assigned[-1]]), stream.time)}")
        none = (" (a dwell is a still stop of at least half of plan.dwell_s: a campaign that captured when the "
                "reading was stable stops for less)" if not len(positions) else "")
        raise InputError(f"{stream.source}: the stream has {len(positions)} dwells{none} "
                         f"({len(assigned)} match the plan) for {total} points; "
                         f"{_describe(missing, unit, total)} has no dwell{after}")
    return assigned, overruns, 0


def stillness_warnings(table: PointTable, fits: LineFits, noise: float, samples: np.ndarray, plan: Plan,
                       unit: str) -> list[str]:
    """The warnings on capture windows that still trend beyond `noise` (axis unit), or hold too few
    samples to tell."""
    scale = SCALE[unit]  # deviation unit per axis unit
    total = len(plan.points)
    dev = unit_label(table.deviation_unit)
    judged = samples >= MIN_SAMPLES
    trending = np.flatnonzero(judged & ~fits.still(noise))
    warnings = []
    if len(trending):
        named = [f"{i + 1} {fits.trend[i] * scale:+.2g} {dev}" for i in trending[:MAX_NAMED]]
        more = f" and {len(trending) - MAX_NAMED} more" if len(trending) > MAX_NAMED else ""
        approaching = int(np.sum(np.sign(fits.trend[trending]) == table.direction[trending]))
        warnings.append(f"{len(trending)} of {total} points were captured while the reading still moved, "
                        f"a trend over the capture window beyond the reading noise of {noise * scale:.2g} {dev} "
                        f"(points {', '.join(named)}{more}; "
                        f"{approaching} of them still approaching their target). Their deviations are biased "
                        f"by the approach, and so are A, B and the means at their targets: the log holds no "
                        f"still reading for them (columns capture_trend_{table.deviation_unit} and capture_still "
                        f"of the point table; docs/import-stream.md says what to do)")
    short = np.flatnonzero(~judged)
    if len(short):
        warnings.append(f"the capture windows of {len(short)} of {total} points hold fewer than {MIN_SAMPLES} "
                        f"samples: how still they were cannot be told (a log sampled faster, or a longer "
                        f"capture.average_s, can)")
    return warnings


MAX_NAMED = 5
"""Points named in the warning on trending capture windows; the table has them all."""


def extract_points(stream: Stream, plan: Plan, config: Config, still_tolerance: float) -> StreamImport:
    """Segment the stream, match it to the plan and capture each point. `still_tolerance` in the
    deviation unit (µm or arcsec): it bounds the search for the dwells, not their capture."""
    unit, kind = config.axis.unit, config.axis.kind
    tolerance = still_tolerance / SCALE[unit]  # axis unit
    dwells = find_dwells(stream.time, stream.reading, tolerance, config.plan.dwell_s)
    samples = round(config.capture.average_s / (sample_interval(stream.time) or 1e-9))
    noise = log_noise(stream.reading, dwells.start, dwells.end + 1)  # axis unit
    dwells = settle(stream.time, stream.reading, dwells, config.plan.dwell_s, samples, noise)
    lo, hi = capture_windows(stream, dwells, config.capture.average_s)
    positions = _window_means(stream.reading, lo, hi) if len(lo) else np.zeros(0)
    assigned, overruns, ignored = assign_dwells(stream, dwells, positions, plan, unit)
    pick = np.array(assigned, dtype=int)
    points = plan.points
    target = np.array([p.target for p in points])
    optional = {"time_s": stream.time[dwells.end[pick]]}
    for name, values in stream.env.items():
        optional[name] = _window_means(values, lo, hi)[pick]
    optional["reading"] = positions[pick]
    optional["samples"] = (hi - lo)[pick].astype(float)
    fits = window_fits(stream.time, stream.reading, lo[pick], hi[pick])
    suffix = UNITS[kind][1]  # um or arcsec
    optional[f"capture_trend_{suffix}"] = fits.trend * SCALE[unit]
    optional[f"capture_scatter_{suffix}"] = fits.scatter * SCALE[unit]
    optional["capture_still"] = (((hi - lo)[pick] >= MIN_SAMPLES) & fits.still(noise)).astype(float)
    meta = {"machine": config.campaign.machine, "axis": config.axis.name,
            "plan_seed": str(plan.seed), "source": stream.source,
            f"reading_noise_{suffix}": f"{noise * SCALE[unit]:.4g}"}
    table = PointTable(kind=kind, run=np.array([p.run for p in points]),
                       direction=np.array([p.direction for p in points]), target=target,
                       deviation=(positions[pick] - target) * SCALE[unit], optional=optional, meta=meta,
                       source=stream.source)
    warnings = stream.warnings + stillness_warnings(table, fits, noise, (hi - lo)[pick], plan, unit)
    return StreamImport(table, len(dwells.start), overruns, ignored, warnings, fits, noise)

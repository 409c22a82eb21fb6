"""A scan's results: the dense deviation profile, the point table at the plan's targets, and the
timing budget that says how fast a scan may go.

The clocks are aligned first (`campaign.stream.align`); then each instrument sample gets the
controller's position at its aligned time, and the deviation is reading − that position (µm, or
arcsec on a rotary axis; the ISO 230-2 sign). Only samples at the move's constant velocity enter
the profile: the ends' ramps serve the alignment, and the axis at rest between passes is not
scanned.

- profile: per sample, the position (axis unit), direction (+1/-1), pass (1, 2, ...), deviation
  and the controller time (s). `profile.csv` holds it.
- point table: at each target, per pass and direction, the deviation a line through the samples
  within ± half the window gives at the target (run = pass). Its metadata says it is a scan, with
  `purpose: diagnostic`: a scan is not an ISO 230-2 test (the axis never stops at a target), so the
  verdict gives no pass/fail (`campaign.verdict.purpose_reason`).
- timing budget: the deviation a timing uncertainty u_t makes at velocity v is v·u_t; u_t is the
  alignment's uncertainty (offset, rate, wander) and, averaged over a window's samples, the
  instrument's sample jitter seen in the profile's scatter. `speed_limit` solves for the velocity
  at which that stays within a wanted deviation uncertainty; `scan_warnings` says when a scan was
  faster, or its ramps reach into the targets' windows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from campaign.errors import InputError
from campaign.pointtable import PointTable, write_points_text
from campaign.stream.align import Alignment, ControllerStream, InstrumentStream, Move, align, find_moves
from protocols.units import DEVIATION_SCALE, UNITS, unit_label

PROFILE_COLUMNS = ("position", "direction", "pass", "deviation", "time_s")
"""profile.csv's columns; position and deviation carry the unit in their names (position_mm,
deviation_um; position_deg, deviation_arcsec)."""


@dataclass(frozen=True)
class Profile:
    """The dense deviation profile: one element per instrument sample at constant velocity."""

    kind: str
    position: np.ndarray
    direction: np.ndarray
    pass_: np.ndarray
    deviation: np.ndarray
    time_s: np.ndarray

    def __len__(self) -> int:
        return len(self.position)

    def csv_text(self) -> str:
        pos_unit, dev_unit = UNITS[self.kind]
        lines = [f"position_{pos_unit},direction,pass,deviation_{dev_unit},time_s\n"]
        lines += [f"{p:.6f},{'+' if d > 0 else '-'},{int(k)},{e:.4f},{t:.6f}\n"
                  for p, d, k, e, t in zip(self.position.tolist(), self.direction.tolist(), self.pass_.tolist(),
                                           self.deviation.tolist(), self.time_s.tolist())]
        return "".join(lines)


@dataclass(frozen=True)
class TimingBudget:
    """The timing part of a scan's deviation uncertainty at its velocity (axis unit/s).

    alignment_s: the alignment's standard uncertainty (worst over the scan), s; jitter_s: the
    instrument's sample jitter seen in the profile, s (RMS per sample); samples_per_window: samples
    a target's window holds per pass. deviation_u: the resulting standard uncertainty of one
    target's value per pass, deviation unit."""

    velocity: float
    alignment_s: float
    jitter_s: float
    samples_per_window: float
    deviation_u: float


@dataclass
class ScanResult:
    """Everything a scan gives: the alignment, the moves, the profile, the point table, the
    timing budget and the warnings."""

    alignment: Alignment
    moves: list[Move]
    profile: Profile
    table: PointTable
    budget: TimingBudget
    wanted_u: float
    speed_limit: float
    warnings: list[str] = field(default_factory=list)


def profile(ctrl: ControllerStream, inst: InstrumentStream, alignment: Alignment, moves: list[Move],
            kind: str = "linear") -> Profile:
    """The deviation at every instrument sample taken at a move's constant velocity."""
    unit = UNITS[kind][0]
    scale = DEVIATION_SCALE[unit]
    t = alignment.controller_time(inst.time_s)
    cols: list[list[np.ndarray]] = [[], [], [], [], []]
    passes = {1: 0, -1: 0}
    for m in moves:
        passes[m.direction] += 1
        (_, cruise_from), (cruise_to, _) = m.ramps
        sel = (t >= cruise_from) & (t <= cruise_to)
        ts = t[sel]
        x = np.interp(ts, ctrl.time_s, ctrl.position)
        cols[0].append(x)
        cols[1].append(np.full(len(ts), m.direction))
        cols[2].append(np.full(len(ts), passes[m.direction]))
        cols[3].append((inst.reading[sel] - x) * scale)
        cols[4].append(ts)
    pos, direction, pass_, dev, times = (np.concatenate(c) if c else np.array([]) for c in cols)
    return Profile(kind, pos, direction.astype(int), pass_.astype(int), dev, times)


def point_table(prof: Profile, targets: tuple[float, ...] | list[float], window: float,
                meta: dict[str, str] | None = None) -> PointTable:
    """The point table at `targets` (axis unit): per pass, direction and target, the value at the
    target of a line through the profile within ± window/2 (the mean when fewer than 3 samples
    span it). A target with no sample in its window in a pass and direction is left out."""
    rows: list[tuple[int, int, float, float, float, int]] = []
    half = window / 2
    for k in sorted(set(prof.pass_.tolist())):
        for d in (1, -1):
            mine = (prof.pass_ == k) & (prof.direction == d)
            if not mine.any():
                continue
            x_all, e_all, t_all = prof.position[mine], prof.deviation[mine], prof.time_s[mine]
            for target in targets:
                near = np.abs(x_all - target) <= half
                if not near.any():
                    continue
                x, e = x_all[near] - target, e_all[near]
                if len(x) >= 3 and np.ptp(x) > 0:
                    value = float(np.polyval(np.polyfit(x, e, 1), 0.0))
                else:
                    value = float(np.mean(e))
                rows.append((k, d, float(target), value, float(np.mean(t_all[near])), int(near.sum())))
    if not rows:
        raise InputError("no target lies within the scanned travel")
    rows.sort(key=lambda r: (r[0], -r[1], r[2] if r[1] > 0 else -r[2]))
    arr = np.array(rows, dtype=float)
    return PointTable(kind=prof.kind, run=arr[:, 0].astype(int), direction=arr[:, 1].astype(int),
                      target=arr[:, 2], deviation=arr[:, 3], optional={"time_s": arr[:, 4]},
                      meta=dict(meta or {}), extra={"samples": arr[:, 5]})


def sample_jitter_s(prof: Profile, speed: float, noise: float) -> float:
    """The sample jitter the profile shows, s: its sample-to-sample scatter (differences of
    neighbours, which the smooth machine error hardly changes) beyond the instrument's `noise`
    (deviation unit, RMS), divided by the speed (converted to the deviation unit per s)."""
    scale = DEVIATION_SCALE[UNITS[prof.kind][0]]
    diffs = []
    for k in set(prof.pass_.tolist()):
        for d in (1, -1):
            e = prof.deviation[(prof.pass_ == k) & (prof.direction == d)]
            if len(e) > 2:
                diffs.append(np.diff(e))
    if not diffs:
        return 0.0
    scatter2 = float(np.mean(np.concatenate(diffs) ** 2)) / 2
    excess = scatter2 - noise**2
    return math.sqrt(excess) / (speed * scale) if excess > 0 else 0.0


def timing_budget(alignment: Alignment, moves: list[Move], jitter_s: float, rate_hz: float, window: float,
                  kind: str = "linear", velocity_: float | None = None) -> TimingBudget:
    """The timing part of one target's per-pass uncertainty at `velocity_` (axis unit/s; default
    the scan's): v·√(u_align² + jitter²/n), n the samples a window holds per pass at `rate_hz`.
    The alignment's uncertainty is the largest over the scan's moves."""
    v = velocity_ if velocity_ is not None else float(np.median([m.speed for m in moves]))
    scale = DEVIATION_SCALE[UNITS[kind][0]]
    times = np.array([t for m in moves for t in (m.start_s, m.end_s)])
    u_align = float(np.max(alignment.timing_uncertainty_s(times)))
    n = max(window / v * rate_hz, 1.0)
    u = v * scale * math.sqrt(u_align**2 + jitter_s**2 / n)
    return TimingBudget(v, u_align, jitter_s, n, u)


def speed_limit(alignment: Alignment, moves: list[Move], jitter_s: float, rate_hz: float, window: float,
                wanted_u: float, kind: str = "linear") -> float:
    """The highest velocity (axis unit/s) at which the timing budget stays within `wanted_u`
    (deviation unit), with this scan's alignment and jitter. The alignment's uncertainty is taken
    as it is at this scan's speed (a faster scan's ramps align somewhat better: the limit is on the
    safe side)."""
    lo, hi = 0.0, 1e4
    for _ in range(100):
        mid = (lo + hi) / 2
        if timing_budget(alignment, moves, jitter_s, rate_hz, window, kind, mid).deviation_u <= wanted_u:
            lo = mid
        else:
            hi = mid
    return lo


def scan_warnings(budget: TimingBudget, limit: float, wanted_u: float, moves: list[Move], targets: tuple[float, ...] |
                  list[float], window: float, unit_label: str) -> list[str]:
    """What makes this scan's result less than it should be, one sentence each."""
    out = []
    if budget.velocity > limit:
        out.append(f"too fast: at {budget.velocity:g} /s the timing alone gives {budget.deviation_u:.2f} {unit_label} "
                   f"per target and pass (alignment {budget.alignment_s * 1e6:.1f} µs, sample jitter "
                   f"{budget.jitter_s * 1e6:.1f} µs over {budget.samples_per_window:.0f} samples), more than the "
                   f"wanted {wanted_u:g} {unit_label}; scan at most {limit:.3g} /s")
    for m in moves:
        (_, cruise_from), (cruise_to, _) = m.ramps
        ramp_up = m.speed * (cruise_from - m.start_s) / 2
        ramp_down = m.speed * (m.end_s - cruise_to) / 2
        first = m.start_position + m.direction * ramp_up
        last = m.end_position - m.direction * ramp_down
        lo, hi = sorted((first, last))
        outside = [t for t in targets if not lo + window / 2 <= t <= hi - window / 2]
        if outside:
            out.append(f"the targets {', '.join(f'{t:g}' for t in outside)} are not at constant velocity over their "
                       f"window in the move from {m.start_position:g} to {m.end_position:g}: lengthen the overrun "
                       f"or lower the velocity")
            break
    return out


def analyse_scan(ctrl: ControllerStream, inst: InstrumentStream, targets: tuple[float, ...] | list[float],
                 rate_hz: float, window: float = 1.0, wanted_u: float = 0.2, noise: float = 0.0,
                 kind: str = "linear", meta: dict[str, str] | None = None) -> ScanResult:
    """Align, profile and tabulate a scan. rate_hz: the instrument's nominal sample rate, Hz;
    window: the window around each target, axis unit; wanted_u: the wanted standard uncertainty of a
    target's value per pass from timing, deviation unit; noise: the instrument's own reading noise,
    deviation unit RMS (what the profile's scatter is beyond timing; 0 when unknown: all scatter is
    then taken as jitter, on the safe side)."""
    alignment = align(ctrl, inst)
    moves = find_moves(ctrl)
    order = np.argsort(inst.time_s, kind="stable")
    inst = InstrumentStream(inst.time_s[order], inst.reading[order])
    prof = profile(ctrl, inst, alignment, moves, kind)
    v = float(np.median([m.speed for m in moves]))
    jitter = sample_jitter_s(prof, v, noise)
    budget = timing_budget(alignment, moves, jitter, rate_hz, window, kind)
    limit = speed_limit(alignment, moves, jitter, rate_hz, window, wanted_u, kind)
    unit = UNITS[kind][1]
    label = unit_label(unit)
    warnings = scan_warnings(budget, limit, wanted_u, moves, targets, window, label)
    a = alignment.as_dict()
    table_meta = {"purpose": "diagnostic", "capture": "scan",
                  "scan": f"{len(moves)} moves at {v:g} {UNITS[kind][0]}/s, window {window:g} {UNITS[kind][0]}",
                  "clock_offset_ms": f"{a['offset_ms']} ± {a['offset_uncertainty_ms']}",
                  "clock_rate_error_ppm": f"{a['rate_error_ppm']} ± {a['rate_uncertainty_ppm']}",
                  "timing_u": f"{budget.deviation_u:.3f} {label} per target and pass at {v:g}/s",
                  "speed_limit": f"{limit:.3g} {UNITS[kind][0]}/s for {wanted_u:g} {label}",
                  **(meta or {})}
    for i, w in enumerate(warnings, 1):
        table_meta[f"warning_{i}"] = w
    table = point_table(prof, targets, window, table_meta)
    return ScanResult(alignment, moves, prof, table, budget, wanted_u, limit, warnings)


def table_text(result: ScanResult) -> str:
    """The point table's CSV text, as analyze reads it."""
    return write_points_text(result.table)

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

from campaign import capture_methods
from campaign.errors import InputError
from campaign.plan import timing_speed_limit, timing_u
from campaign.pointtable import PointTable, write_points_text
from campaign.stream.align import (
    Alignment,
    ControllerStream,
    InstrumentStream,
    Move,
    align,
    find_moves,
    in_order,
    velocity,
)
from protocols.units import DEVIATION_SCALE, UNITS, unit_label


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
    rest: dict[int, RestStep]
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


class TableError(InputError):
    """The profile gives no point table at the targets (an alignment succeeded; the table did not)."""


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
        raise TableError("no target lies within the scanned travel")
    rows.sort(key=lambda r: (r[0], -r[1], r[2] if r[1] > 0 else -r[2]))
    arr = np.array(rows, dtype=float)
    return PointTable(kind=prof.kind, run=arr[:, 0].astype(int), direction=arr[:, 1].astype(int),
                      target=arr[:, 2], deviation=arr[:, 3], optional={"time_s": arr[:, 4]},
                      meta=dict(meta or {}), extra={"samples": arr[:, 5]})


@dataclass(frozen=True)
class RestStep:
    """What stopping changes, per direction of arrival (+1/-1): the deviation on the move at the
    end of a pass minus the deviation at rest there at the end of the dwell, mean over the ends
    arrived at in that direction (deviation unit), its standard uncertainty and the ends counted.
    `u` is the larger of the ends' own (each end's deceleration fit and rest mean, from their samples'
    scatter) and of their scatter about the mean: a scan has two or three ends a direction, whose
    scatter alone is a poor estimate. bench/scan_rest_step.py (100 drawn scans, 200 steps at each number
    of passes, the axis coming to rest within 0.05 µm RMS of where it should): beyond 2u 20, 9 and 5 of
    200 at one, two and three passes (a normal error: 9). One end a direction (one pass) has only its
    own, which leaves out where the axis comes to rest each time: with the axis coming to rest exactly,
    6 of 200 beyond 2u at one pass. analyse_scan warns of it, and the metadata says so with the step.
    The samples' noise is taken as independent (the simulator's is); a real interferometer's slow noise
    would make u too small, at one end and at several."""

    direction: int
    step: float
    u: float
    ends: int


def rest_steps(ctrl: ControllerStream, inst: InstrumentStream, alignment: Alignment, moves: list[Move],
               prof: Profile, average_s: float = 1.0) -> dict[int, RestStep]:
    """The rest step per direction (see RestStep). At each end the axis rests until the next move:
    its deviation at rest is the mean over the last `average_s` s of that rest (as a dwell capture
    takes it; the rest must last at least twice that), its deviation on the move from the aligned
    samples of the move's deceleration, where it ends (at the end position, at zero velocity:
    no extrapolation over the ramp, which a screw's periodic error would bend, and no timing error).
    Directions without such an end are left out."""
    scale = DEVIATION_SCALE[UNITS[prof.kind][0]]
    t = alignment.controller_time(inst.time_s)
    v_ctrl = velocity(ctrl)
    steps: dict[int, list[float]] = {1: [], -1: []}
    within: dict[int, list[float]] = {1: [], -1: []}
    for i, m in enumerate(moves):
        rest_to = moves[i + 1].start_s if i + 1 < len(moves) else float(ctrl.time_s[-1])
        if rest_to - m.end_s < 2 * average_s:
            continue
        at_rest = (t >= rest_to - average_s) & (t < rest_to)
        # on the move: the deceleration, fitted by a constant, a slope in position (the machine's
        # error along the ramp) and a term in velocity (a timing error left), taken where it ends:
        # at the end position, at zero velocity, where a timing error changes nothing
        arriving = (t > m.ramps[1][0]) & (t < m.end_s)
        x = position_between_cycles(ctrl, t[arriving])
        v = np.abs(np.interp(t[arriving], ctrl.time_s, v_ctrl))
        e = (inst.reading[arriving] - x) * scale
        if at_rest.sum() < 2 or len(x) < 4:
            continue
        design = np.column_stack([np.ones(len(x)), x - m.end_position, v])
        coef, *_ = np.linalg.lstsq(design, e, rcond=None)
        moving = float(coef[0])
        ctrl_rest = (ctrl.time_s >= rest_to - average_s) & (ctrl.time_s < rest_to)
        where = float(np.median(ctrl.position[ctrl_rest])) if ctrl_rest.any() else m.end_position
        rest_readings = inst.reading[at_rest] * scale
        resting = float(np.mean(rest_readings)) - where * scale
        steps[m.direction].append(moving - resting)
        within[m.direction].append(_end_u(design, e, coef, rest_readings))
    out = {}
    for d, values in steps.items():
        if values:
            n = len(values)
            own = math.sqrt(sum(u * u for u in within[d])) / n  # each end's own noise, averaged over the ends
            between = float(np.std(values, ddof=1)) / math.sqrt(n) if n > 1 else 0.0
            out[d] = RestStep(d, float(np.mean(values)), max(own, between), n)
    return out


UNEVEN_CYCLES = 2.0
"""Neighbouring cycle intervals that differ by more than this factor (a dropped sample) take the
straight line: a parabola through very uneven nodes amplifies the positions' own rounding."""


def position_between_cycles(ctrl: ControllerStream, t: np.ndarray) -> np.ndarray:
    """The controller's position at times `t` (s) between its samples (axis unit), by the parabola
    through the three samples nearest each time. On a ramp the position is a parabola in time: a
    straight line between two samples falls short of it by up to a·h²/8 (0.05 µm at 420 mm/s² and a
    1 ms cycle), which biased the rest step by 0.02 µm on average (up to 0.05 µm); the parabola leaves
    what the jumps in acceleration make where a ramp starts and ends. Outside the samples, and where
    the intervals either side differ by more than UNEVEN_CYCLES, the straight line (np.interp);
    InputError with fewer than three samples."""
    times, x = ctrl.time_s, ctrl.position
    if len(times) < 3:
        raise InputError("the controller stream has fewer than 3 samples")
    t = np.asarray(t, dtype=float)
    line = np.interp(t, times, x)
    nearest = np.rint(np.interp(t, times, np.arange(len(times)))).astype(int)
    i = np.clip(nearest, 1, len(times) - 2)  # the middle of the three, kept one in from the ends
    t0, t1, t2 = times[i - 1], times[i], times[i + 1]
    x0, x1, x2 = x[i - 1], x[i], x[i + 1]
    parabola = (x0 * (t - t1) * (t - t2) / ((t0 - t1) * (t0 - t2)) + x1 * (t - t0) * (t - t2) / ((t1 - t0) * (t1 - t2))
                + x2 * (t - t0) * (t - t1) / ((t2 - t0) * (t2 - t1)))
    even = np.maximum(t1 - t0, t2 - t1) <= UNEVEN_CYCLES * np.minimum(t1 - t0, t2 - t1)
    inside = (t >= times[0]) & (t <= times[-1])
    return np.where(even & inside, parabola, line)


def _end_u(design: np.ndarray, e: np.ndarray, coef: np.ndarray, rest_readings: np.ndarray) -> float:
    """One end's rest step's standard uncertainty from its own samples (deviation unit): the standard
    error of the deceleration fit's value at the end and of the rest's mean. The samples on the move
    are the same instrument's as those at rest: their scatter is taken as the larger of the fit's
    residual scatter and the rest's. The rest has hundreds of samples; a ramp at 250 Hz has ten, whose
    residual scatter, on 7 degrees of freedom, can come out at a third of the noise."""
    rest_variance = float(np.var(rest_readings, ddof=1))  # 2 or more, as rest_steps keeps
    fit_variance = float(np.sum((e - design @ coef) ** 2)) / (len(e) - design.shape[1])  # rest_steps keeps 4 or more
    cov = np.linalg.pinv(design.T @ design) * max(fit_variance, rest_variance)
    return math.sqrt(max(float(cov[0, 0]), 0.0) + rest_variance / len(rest_readings))


def at_rest(prof: Profile, steps: dict[int, RestStep]) -> Profile:
    """The profile with each direction's rest step removed: what the axis would show stopped there,
    if stopping changes the deviation by the same everywhere."""
    shift = np.zeros(len(prof))
    for d, st in steps.items():
        shift[prof.direction == d] = st.step
    return Profile(prof.kind, prof.position, prof.direction, prof.pass_, prof.deviation - shift, prof.time_s)


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


def _alignment_u_s(alignment: Alignment, moves: list[Move]) -> float:
    """The alignment's standard uncertainty, s: the largest over the scan's moves' ends."""
    times = np.array([t for m in moves for t in (m.start_s, m.end_s)])
    return float(np.max(alignment.timing_uncertainty_s(times)))


def timing_budget(alignment: Alignment, moves: list[Move], jitter_s: float, rate_hz: float, window: float,
                  kind: str = "linear", velocity_: float | None = None) -> TimingBudget:
    """The timing part of one target's per-pass uncertainty at `velocity_` (axis unit/s; default
    the scan's): `timing_u` with the alignment's uncertainty, the largest over the scan's moves."""
    v = velocity_ if velocity_ is not None else float(np.median([m.speed for m in moves]))
    u_align = _alignment_u_s(alignment, moves)
    u, n = timing_u(v, u_align, jitter_s, rate_hz, window, kind)
    return TimingBudget(v, u_align, jitter_s, n, u)


def speed_limit(alignment: Alignment, moves: list[Move], jitter_s: float, rate_hz: float, window: float,
                wanted_u: float, kind: str = "linear") -> float:
    """The highest velocity (axis unit/s) at which the timing budget stays within `wanted_u`
    (deviation unit), with this scan's alignment and jitter (`timing_speed_limit`). The alignment's
    uncertainty is taken as it is at this scan's speed (a faster scan's ramps align somewhat better:
    the limit is on the safe side)."""
    return timing_speed_limit(_alignment_u_s(alignment, moves), jitter_s, rate_hz, window, wanted_u, kind)


def scan_warnings(budget: TimingBudget, limit: float, wanted_u: float, moves: list[Move], targets: tuple[float, ...] |
                  list[float], window: float, kind: str = "linear") -> list[str]:
    """What makes this scan's result less than it should be, one sentence each."""
    out = []
    speed_unit, dev_unit = f"{UNITS[kind][0]}/s", unit_label(UNITS[kind][1])
    if budget.velocity > limit:
        out.append(f"too fast: at {budget.velocity:.3g} {speed_unit} the timing alone gives {budget.deviation_u:.2f} "
                   f"{dev_unit} per target and pass (alignment {budget.alignment_s * 1e6:.1f} µs, sample jitter "
                   f"{budget.jitter_s * 1e6:.1f} µs over {budget.samples_per_window:.0f} samples), more than the "
                   f"wanted {wanted_u:g} {dev_unit}; scan at most {limit:.3g} {speed_unit}")
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
                 kind: str = "linear", meta: dict[str, str] | None = None, rest_reference: bool = True,
                 average_s: float = 1.0, rate: bool = True) -> ScanResult:
    """Align, profile and tabulate a scan. rate_hz: the instrument's nominal sample rate, Hz;
    window: the window around each target, axis unit; wanted_u: the wanted standard uncertainty of a
    target's value per pass from timing, deviation unit; noise: the instrument's own reading noise,
    deviation unit RMS (what the profile's scatter is beyond timing; 0 when unknown: all scatter is
    then taken as jitter, on the safe side). rest_reference: when the axis rested at the ends (at
    least 2 × `average_s`), remove each direction's rest step (`rest_steps`) from the profile and
    the table, so that they compare with a stop-and-go campaign; the steps are in the metadata.
    rate: estimate the clocks' rate ratio (False: the offset only)."""
    alignment = align(ctrl, inst, rate=rate)
    moves = find_moves(ctrl)
    inst = in_order(inst)
    prof = profile(ctrl, inst, alignment, moves, kind)
    v = float(np.median([m.speed for m in moves]))
    jitter = sample_jitter_s(prof, v, noise)
    steps = rest_steps(ctrl, inst, alignment, moves, prof, average_s) if rest_reference else {}
    if steps:
        prof = at_rest(prof, steps)
    budget = timing_budget(alignment, moves, jitter, rate_hz, window, kind)
    limit = speed_limit(alignment, moves, jitter, rate_hz, window, wanted_u, kind)
    warnings = scan_warnings(budget, limit, wanted_u, moves, targets, window, kind)
    for d, st in steps.items():
        if st.ends == 1:
            warnings.append(f"{'+' if d > 0 else '-'} direction: one end only rests long enough ({2 * average_s:g} s "
                            "or more) to give a rest step: its uncertainty leaves out where the axis comes to rest each "
                            "time (its positioning scatter), which one end cannot show; scan more passes or rest longer "
                            "at the ends")
    a = alignment.as_dict()
    pos, dev = UNITS[kind][0], unit_label(UNITS[kind][1])
    rest = "; ".join(f"{'+' if d > 0 else '-'}: {st.step:.3f} ± {st.u:.3f} {dev} over "
                     + (f"{st.ends} ends" if st.ends > 1 else "1 end, u without the positioning scatter")
                     for d, st in steps.items())
    table_meta = {"purpose": "diagnostic", "capture": capture_methods.SCAN.name,
                  "scan": f"{len(moves)} moves at {v:g} {pos}/s, window {window:g} {pos}",
                  "clock_offset_ms": f"{a['offset_ms']} ± {a['offset_uncertainty_ms']}",
                  "clock_rate_error_ppm": f"{a['rate_error_ppm']} ± {a['rate_uncertainty_ppm']}",
                  "clock_reference_s": f"{a['t_ref_s']} (the controller time the offset is given at)",
                  "timing_u": f"{budget.deviation_u:.3f} {dev} per target and pass at {v:g} {pos}/s",
                  "speed_limit": f"{limit:.3g} {pos}/s for {wanted_u:g} {dev}",
                  "deviation": (f"on the move, less each direction's rest step ({rest})" if steps
                                else "on the move (no rest at the ends to refer it to)"),
                  **(meta or {})}
    for i, w in enumerate(warnings, 1):
        table_meta[f"warning_{i}"] = w
    table = point_table(prof, targets, window, table_meta)
    return ScanResult(alignment, moves, prof, steps, table, budget, wanted_u, limit, warnings)


def table_text(result: ScanResult) -> str:
    """The point table's CSV text, as analyze reads it."""
    return write_points_text(result.table)


def write_profile(path: str, result: ScanResult) -> None:
    """profile.csv: the scan's metadata as `# key: value` comments (as a point table carries them),
    then the profile."""
    meta = "".join(f"# {k}: {v}\n" for k, v in result.table.meta.items())
    with open(path, "w", encoding="utf-8") as f:
        f.write(meta + result.profile.csv_text())


def sine_fit(prof: Profile, period_min: float, period_max: float, steps: int = 400) -> tuple[float, float]:
    """(period, amplitude) of the sinusoid that best fits the profile, with one constant per direction
    and one slope beside it (axis unit, deviation unit): the period by least squares over a grid
    of `steps` periods in [period_min, period_max], then over a grid as fine again around the best,
    refined by a parabola through the best three. The search runs on the profile's means over bins
    of period_min/50 per direction; the amplitude comes from every sample."""
    width = period_min / 50
    xs, es, ds = [], [], []
    for d in (1, -1):
        mine = prof.direction == d
        if not mine.any():
            continue
        bins = np.floor(prof.position[mine] / width).astype(int)
        keys, where, counts = np.unique(bins, return_inverse=True, return_counts=True)
        xs.append(np.bincount(where, prof.position[mine]) / counts)
        es.append(np.bincount(where, prof.deviation[mine]) / counts)
        ds.append(np.full(len(keys), d))
    binned = (np.concatenate(xs), np.concatenate(es), np.concatenate(ds))

    def fit(period: float, data: tuple[np.ndarray, np.ndarray, np.ndarray] = binned) -> tuple[float, float]:
        """(sum of squared residuals, amplitude) of the fit at `period` to (position, deviation, direction)."""
        x, e, direction = data
        base = [(direction == d).astype(float) for d in (1, -1) if np.any(direction == d)]
        w = 2 * math.pi / period
        design = np.column_stack([*base, x - np.mean(x), np.sin(w * x), np.cos(w * x)])
        coef, *_ = np.linalg.lstsq(design, e, rcond=None)
        res = e - design @ coef
        return float(res @ res), float(math.hypot(coef[-2], coef[-1]))

    def best_of(periods: np.ndarray) -> tuple[float, float]:
        """The best period of the grid, refined by a parabola, and the grid's step."""
        cost = np.array([fit(float(p))[0] for p in periods])
        k = int(np.clip(np.argmin(cost), 1, len(periods) - 2))
        c0, c1, c2 = cost[k - 1:k + 2]
        h = float(periods[1] - periods[0])
        denom = c0 - 2 * c1 + c2
        return float(periods[k] + (0.5 * h * (c0 - c2) / denom if denom > 0 else 0.0)), h

    coarse, h = best_of(np.linspace(period_min, period_max, steps))
    best, _ = best_of(np.linspace(coarse - 2 * h, coarse + 2 * h, steps))
    return best, fit(best, (prof.position, prof.deviation, prof.direction))[1]

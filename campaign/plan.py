"""The test plan: a list of immutable steps that the executor interprets. A dry run walks the list.

The linear cycle (Li et al. 2022, ISO 230-2): from the start move to -L1 (overrun), visit 0, L ... nL,
then nL+L1 (overrun), then come back down through nL ... 0 to -L1; repeat for N cycles. Overrun
moves are motion only. The pilgrim (step) cycle visits one target at a time: from below (+), then
from above (-), N times, before going on to the next target.

Positions are in the axis unit (mm or deg), velocities in axis unit/s, times in s.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from campaign import capture_methods
from campaign.config import Config, capture_spec
from campaign.errors import InputError, SafetyError
from campaign.specs import AxisSpec, CaptureSpec, PlanSpec
from protocols.units import DEVIATION_SCALE, UNITS

GOLDEN = (math.sqrt(5) - 1) / 2


@dataclass(frozen=True)
class Point:
    """One measured point: run >= 1, direction ±1, target index and target position (axis unit)."""

    index: int
    run: int
    direction: int
    target_index: int
    target: float


@dataclass(frozen=True)
class Move:
    """Move to `position` at `velocity`. `overrun` moves are motion only."""

    position: float
    velocity: float
    overrun: bool = False


@dataclass(frozen=True)
class Settle:
    """Wait `seconds` after arrival before capture starts."""

    seconds: float


@dataclass(frozen=True)
class Capture:
    """Capture `point` as `spec` says: the dwell method averages the last `window_s`; the stable
    method waits at most `timeout_s` for a stable reading. The executor and replay capture from
    the step alone (campaign.measure.capture.capture_point)."""

    point: Point
    window_s: float
    timeout_s: float
    spec: CaptureSpec = field(default_factory=CaptureSpec)


@dataclass(frozen=True)
class Checkpoint:
    """Record the captured point durably (append + fsync) before going on."""

    point: Point


Step = Move | Settle | Capture | Checkpoint


@dataclass(frozen=True)
class Stop:
    """One move of the plan and what happens where it ends: the plan walker's unit.

    step: index of the Move in `Plan.steps`; move: that Move. For a measured stop also the point,
    the Settle before its capture (`settle_s`, 0 when there is none), the Capture step and the
    index of the Capture and Checkpoint steps; an overrun stop (motion only) has none of them.
    """

    step: int
    move: Move
    point: Point | None = None
    settle_s: float = 0.0
    capture: Capture | None = None
    capture_step: int | None = None
    checkpoint_step: int | None = None

    @property
    def position(self) -> float:
        return self.move.position

    @property
    def dwell_s(self) -> float:
        """Time planned at the target, s: the settle plus the capture window (with the stable
        method the window is only the stability window; the wait is found while measuring)."""
        return self.settle_s + (self.capture.window_s if self.capture else 0.0)


@dataclass(frozen=True)
class Visit:
    """A measured stop (see `Stop`): the move to the target, the point, the settle before its capture
    (s), the Capture and the index of the Move, Capture and Checkpoint steps."""

    step: int
    move: Move
    point: Point
    settle_s: float
    capture: Capture
    capture_step: int
    checkpoint_step: int | None

    @property
    def position(self) -> float:
        return self.move.position

    @property
    def dwell_s(self) -> float:
        """Time planned at the target, s (see `Stop.dwell_s`)."""
        return self.settle_s + self.capture.window_s


@dataclass(frozen=True)
class Plan:
    """The steps, the targets (axis unit) and the offsets applied to the nominal grid."""

    steps: tuple[Step, ...]
    targets: tuple[float, ...]
    offsets: tuple[float, ...]
    seed: int

    @cached_property
    def _stops(self) -> tuple[Stop, ...]:
        stops: list[Stop] = []
        for i, step in enumerate(self.steps):
            if isinstance(step, Move):
                stops.append(Stop(i, step))
            elif not stops:
                raise ValueError(f"plan step {i} ({type(step).__name__}) comes before the first move")
            elif isinstance(step, Settle):
                stops[-1] = replace(stops[-1], settle_s=stops[-1].settle_s + step.seconds)
            elif isinstance(step, Capture):
                stops[-1] = replace(stops[-1], point=step.point, capture=step, capture_step=i)
            elif isinstance(step, Checkpoint):
                stops[-1] = replace(stops[-1], checkpoint_step=i)
        return tuple(stops)

    def stops(self) -> tuple[Stop, ...]:
        """Every move of the plan in order, with what happens at its end: the one walker every
        consumer of a plan uses (executor resume, replay, simulation, import, duration, ends)."""
        return self._stops

    @cached_property
    def _visits(self) -> tuple[Visit, ...]:
        return tuple(Visit(s.step, s.move, s.point, s.settle_s, s.capture, s.capture_step, s.checkpoint_step)
                     for s in self._stops
                     if s.point is not None and s.capture is not None and s.capture_step is not None)

    def visits(self) -> tuple[Visit, ...]:
        """The measured stops only, in point order (`visits()[i].point.index == i`)."""
        return self._visits

    @property
    def points(self) -> list[Point]:
        return [v.point for v in self._visits]

    @cached_property
    def sweeps(self) -> bool:
        """The plan is a scan: its points are sweeps of the travel (campaign.capture_methods)."""
        return any(capture_methods.method(v.capture.spec.method).sweeps for v in self._visits)

    def ends(self) -> tuple[float, float]:
        """The lowest and highest position the plan moves to (overruns included), axis unit."""
        positions = [s.position for s in self._stops]
        return min(positions), max(positions)

    def travel(self, start: float | None = None) -> float:
        """Total distance of all moves, axis unit (from `start`, default the first move's end)."""
        here = self._stops[0].position if start is None else start
        total = 0.0
        for s in self._stops:
            total += abs(s.position - here)
            here = s.position
        return total


def nominal_targets(spec: PlanSpec) -> list[float]:
    """The targets before offsets, axis unit: the explicit list, or `count` from `start` over `length`."""
    if spec.targets is not None:
        return list(spec.targets)
    if spec.length is None or spec.count is None:
        raise ValueError("a plan spec without targets needs length and count (campaign.config checks it)")
    return [float(t) for t in np.linspace(spec.start, spec.start + spec.length, spec.count)]


def target_offsets(nominal: list[float], kind: str, fraction: float, seed: int) -> list[float]:
    """Per-target offsets r_i (axis unit) so that periodic lead errors are sampled (ISO 230-2).
    The first target keeps r = 0 (the reference point). `random`: uniform in ±fraction·spacing,
    seeded; `golden`: the golden-ratio phase sequence mapped to ±fraction·spacing."""
    n = len(nominal)
    if kind == "none" or n < 2:
        return [0.0] * n
    spacing = min(b - a for a, b in itertools.pairwise(nominal))
    if kind == "random":
        phases = np.random.default_rng(seed).uniform(0, 1, n)
    else:
        phases = (np.arange(n, dtype=float) * GOLDEN + (seed % 1000) * GOLDEN / 1000) % 1.0
    offsets = (2 * phases - 1) * fraction * spacing
    offsets[0] = 0.0
    return [float(round(o, 6)) for o in offsets]


def capture_at(point: Point, dwell_s: float, spec: CaptureSpec) -> tuple[float, Capture]:
    """How `point` is captured in a dwell of `dwell_s` (s) with `spec`: (the settle before the
    capture, s; the Capture step), as its method says (campaign.capture_methods: the dwell method
    averages the last `average_s` of the dwell, at most the dwell; the stable method starts at
    arrival and waits at most `stable_timeout_s`)."""
    w = capture_methods.method(spec.method).window(spec, dwell_s)
    return w.settle_s, Capture(point, w.window_s, w.timeout_s, spec)


def build_plan(config: Config) -> Plan:
    """The plan for a config (its plan and capture specs). Does not check limits: see `check_plan`.
    A scan's window is checked against the plan's targets (`check_scan_window`): InputError naming
    the config's file and key."""
    plan = make_plan(config.plan, config.capture)
    if plan.sweeps:
        check_scan_window(config.capture.scan_window, plan, config, f"{config.source}: key 'capture.scan_window'")
    return plan


def check_scan_window(window: float, plan: Plan, config: Config, option: str) -> None:
    """A scan's window about each target (axis unit) holds samples and only its own: at least one
    sample spacing at the scan's velocity (capture.scan_velocity / instrument.rate_hz), at most the
    smallest spacing of the plan's targets, offsets included (a wider window takes its neighbour's
    samples). The config's window, and replay's --scan-window against the recorded plan, alike.
    InputError starting with `option` (what names the value: a config's file and key, an option)."""
    velocity, rate_hz, unit = config.capture.scan_velocity or 0.0, config.instrument.rate_hz, config.axis.unit
    spacing = velocity / rate_hz
    if window < spacing * (1 - 1e-9):
        raise InputError(f"{option}: {window:g} {unit} is shorter than the spacing of the samples at scan_velocity "
                         f"{velocity:g} {unit}/s and instrument.rate_hz {rate_hz:g} ({spacing:g} {unit}): a target "
                         f"could get no sample; make it at least {spacing:g} {unit}")
    gaps = [b - a for a, b in itertools.pairwise(sorted(plan.targets)) if b > a]
    if gaps and window > min(gaps) * (1 + 1e-9):
        raise InputError(f"{option}: {window:g} {unit} is wider than the targets' spacing ({min(gaps):g} {unit}, "
                         "offsets included): a target's window would take its neighbour's samples")


def make_plan(p: PlanSpec, capture: CaptureSpec) -> Plan:
    """The plan of the test cycle `p`, every capture step carrying `capture`. Does not check limits.
    InputError for a capture method that is not run live (the stream import's own)."""
    if not capture_methods.method(capture.method).live:
        raise InputError(f"capture.method = \"{capture.method}\" is not run by axiscal itself (the stream import's "
                         f"own: axiscal import-stream); axiscal runs {', '.join(capture_methods.names(live=True))}")
    nominal = nominal_targets(p)
    offsets = target_offsets(nominal, p.offsets, p.offset_fraction, p.seed)
    targets = [round(t + o, 9) for t, o in zip(nominal, offsets)]
    if capture_methods.method(capture.method).sweeps:
        return Plan(scan_steps(p, capture, targets), tuple(targets), tuple(offsets), p.seed)
    v, l1 = p.velocity, p.overrun
    dwell_rng = np.random.default_rng([p.seed, 1])  # its own stream: the offsets do not change
    steps: list[Step] = []
    index = 0

    def visit(run: int, direction: int, i: int) -> None:
        nonlocal index
        point = Point(index, run, direction, i, targets[i])
        dwell = p.dwell_s * (1 + dwell_rng.uniform(-1, 1) * p.dwell_jitter) if p.dwell_jitter else p.dwell_s
        settle_s, step = capture_at(point, dwell, capture)
        steps.extend([Move(targets[i], v), *([Settle(settle_s)] if settle_s > 0 else []), step, Checkpoint(point)])
        index += 1

    low, high = targets[0] - l1, targets[-1] + l1
    for run in range(1, p.cycles + 1):
        if p.cycle == "linear":
            steps.append(Move(low, v, overrun=True))
            for i in range(len(targets)):
                visit(run, +1, i)
            steps.append(Move(high, v, overrun=True))
            for i in reversed(range(len(targets))):
                visit(run, -1, i)
    if p.cycle == "linear":
        steps.append(Move(low, v, overrun=True))
    else:
        for i, t in enumerate(targets):
            for run in range(1, p.cycles + 1):
                steps.append(Move(t - l1, v, overrun=True))
                visit(run, +1, i)
                steps.append(Move(t + l1, v, overrun=True))
                visit(run, -1, i)
    return Plan(tuple(steps), tuple(targets), tuple(offsets), p.seed)


def scan_steps(p: PlanSpec, capture: CaptureSpec, targets: list[float]) -> tuple[Step, ...]:
    """A scan's steps: to the low end of the travel (the first target less the overrun) at the plan's
    velocity and a rest there, then `cycles` passes, each a sweep up to the high end and one back
    down at `capture.scan_velocity`, each sweep followed by a rest of `dwell_s` at its end (the rests
    refer the moving deviation to the one at rest, docs/scan.md). A sweep is a plan point: its
    Capture step (method scan) and Checkpoint record the sweep (resume continues at the next); the
    point table at the targets comes from the streams afterwards."""
    if capture.scan_velocity is None:
        raise ValueError("a scan needs capture.scan_velocity (campaign.config checks it)")
    low, high = targets[0] - p.overrun, targets[-1] + p.overrun
    steps: list[Step] = [Move(low, p.velocity, overrun=True), Settle(p.dwell_s)]
    index = 0
    for run in range(1, p.cycles + 1):
        for direction, end, target_index in ((+1, high, len(targets) - 1), (-1, low, 0)):
            point = Point(index, run, direction, target_index, end)
            steps += [Move(end, capture.scan_velocity), Settle(p.dwell_s), Capture(point, 0.0, 0.0, capture),
                      Checkpoint(point)]
            index += 1
    return tuple(steps)


def check_motion(position: float, velocity: float, axis: AxisSpec) -> None:
    """Refuse (SafetyError, exit 2) a motion outside the soft limits or above the velocity limit.
    Called before every motion is sent, and for the whole plan before anything moves."""
    lo, hi, unit = axis.soft_limit_min, axis.soft_limit_max, axis.unit
    if not (math.isfinite(position) and lo <= position <= hi):
        side = (f"below axis.soft_limit_min = {lo:g} {unit}" if math.isfinite(position) and position < lo else
                f"above axis.soft_limit_max = {hi:g} {unit}" if math.isfinite(position) else "not a number")
        raise SafetyError(f"motion to {position:g} {unit} is outside the soft limits [{lo:g}, {hi:g}] {unit}: {side}")
    if not (math.isfinite(velocity) and 0 < velocity <= axis.max_velocity):
        raise SafetyError(f"velocity {velocity:g} {unit}/s is outside (0, {axis.max_velocity:g}] {unit}/s "
                          "(axis.max_velocity)")


def check_plan(plan: Plan, axis: AxisSpec) -> None:
    """Check every move of the plan against the axis' limits before anything is commanded."""
    for step in plan.steps:
        if isinstance(step, Move):
            try:
                check_motion(step.position, step.velocity, axis)
            except SafetyError as exc:
                if "soft limits" not in str(exc):  # the velocity: its key is said already
                    raise
                if not step.overrun:
                    raise SafetyError(f"{exc} (a target of the plan: plan.start, plan.length or plan.targets, "
                                      "with its offset)") from None
                raise SafetyError(f"{exc} (the overrun beyond the end target: plan.overrun)") from None


def move_time_s(distance: float, velocity: float, acceleration: float) -> float:
    """Duration of a trapezoidal (or triangular) move, s."""
    distance = abs(distance)
    if distance == 0:
        return 0.0
    ramp = velocity * velocity / acceleration
    if distance >= ramp:
        return distance / velocity + velocity / acceleration
    return 2 * math.sqrt(distance / acceleration)


def estimate_duration_s(plan: Plan, axis: AxisSpec, start: float | None = None) -> float:
    """Estimated campaign duration, s: moves (at the axis' acceleration), settles and capture windows
    (stable: its window)."""
    accel = axis.max_acceleration
    total, here = 0.0, start
    for stop in plan.stops():
        if here is not None:
            total += move_time_s(stop.position - here, stop.move.velocity, accel)
        here = stop.position
        total += stop.dwell_s
    return total


PLAN_FORMAT = "axiscal plan"
"""The `format` of the header record of a recorded plan (plan.jsonl)."""

PLAN_VERSION = 2
"""Version 2: the header holds the campaign's whole validated config (`config`, as in meta.json) and
every capture record its CaptureSpec (`capture`), so the file alone describes the campaign (replay
and resume run from it). Version 1 (no `version`): neither; the capture spec comes from the config."""


def plan_records(plan: Plan, config: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """The plan as JSON-ready records: a header (version, targets, offsets, seed, counts and the
    campaign's config sections `config`, see campaign.config.recorded_sections), then one record per
    step in order, a capture with its spec. Floats survive a JSON round trip exactly, so the plan
    read back is equal."""
    header: dict[str, Any] = {"format": PLAN_FORMAT, "version": PLAN_VERSION, "targets": list(plan.targets),
                              "offsets": list(plan.offsets), "seed": plan.seed, "steps": len(plan.steps),
                              "points": len(plan.points)}
    if config is not None:
        header["config"] = config
    records = [header]
    for step in plan.steps:
        if isinstance(step, Move):
            records.append({"step": "move", "position": step.position, "velocity": step.velocity,
                            "overrun": step.overrun})
        elif isinstance(step, Settle):
            records.append({"step": "settle", "seconds": step.seconds})
        elif isinstance(step, Capture):
            records.append({"step": "capture", "point": asdict(step.point), "window_s": step.window_s,
                            "timeout_s": step.timeout_s,
                            "capture": {k: v for k, v in asdict(step.spec).items() if v is not None}})
        else:
            records.append({"step": "checkpoint", "point": step.point.index})
    return records


def plan_header(records: list[dict[str, Any]], where: str) -> dict[str, Any]:
    """The header record of a recorded plan; InputError naming `where` when there is none."""
    if not records or not isinstance(records[0], dict) or records[0].get("format") != PLAN_FORMAT:
        raise InputError(f"{where}: not a recorded axiscal plan (no '{PLAN_FORMAT}' header)")
    version = records[0].get("version", 1)
    if version not in (1, PLAN_VERSION):
        raise InputError(f"{where}: plan format version {version!r}; this axiscal reads 1 and {PLAN_VERSION}")
    return records[0]


def plan_from_records(records: list[dict[str, Any]], where: str, capture: CaptureSpec | None = None) -> Plan:
    """The plan `plan_records` wrote; InputError naming `where` and the record when it is not one.
    `capture`: the capture spec of a version 1 plan, whose records do not hold it (required then)."""
    header, number = plan_header(records, where), 1
    if header.get("version", 1) == 1 and capture is None:
        raise InputError(f"{where}: a version 1 plan does not say how its points were captured: "
                         "the campaign's config.toml is needed")
    steps: list[Step] = []
    points: dict[int, Point] = {}
    try:
        for number, r in enumerate(records[1:], start=2):
            kind = r.get("step")
            if kind == "move":
                steps.append(Move(float(r["position"]), float(r["velocity"]), bool(r["overrun"])))
            elif kind == "settle":
                steps.append(Settle(float(r["seconds"])))
            elif kind == "capture":
                p = r["point"]
                point = Point(int(p["index"]), int(p["run"]), int(p["direction"]), int(p["target_index"]),
                              float(p["target"]))
                points[point.index] = point
                spec = capture_spec(r["capture"], f"{where}: line {number}") if "capture" in r else capture
                if spec is None:
                    raise KeyError("capture")
                steps.append(Capture(point, float(r["window_s"]), float(r["timeout_s"]), spec))
            elif kind == "checkpoint":
                steps.append(Checkpoint(points[int(r["point"])]))
            else:
                raise ValueError(f"unknown step '{kind}'")
        plan = Plan(tuple(steps), tuple(float(t) for t in header["targets"]),
                    tuple(float(o) for o in header["offsets"]), int(header["seed"]))
        plan.stops()
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"{where}: line {number}: not a plan record ({exc})") from None
    if len(steps) != header.get("steps") or len(plan.points) != header.get("points"):
        raise InputError(f"{where}: holds {len(steps)} steps and {len(plan.points)} points, its header "
                         f"{header.get('steps')} and {header.get('points')} (a torn file?)")
    return plan


EXPECTED_TIMING_U_S = 25e-6
"""The timing uncertainty a scan is expected to leave before it ran, s: the worst the simulated
machine's bench scans stated (7-25 µs at 10 and 25 mm/s: the alignment's offset and rate, 2-7 µs,
with the laser clock's wander and sample jitter; bench/results/scan.json). `axiscal plan`'s speed
limit and a follow-up scan's speed assume it; a scan states its own after it ran."""


def planned_timing(velocity: float, wanted_u: float, kind: str = "linear") -> tuple[float, float]:
    """Before a scan ran: the highest velocity (axis unit/s) whose timing stays within `wanted_u`
    (deviation unit) with EXPECTED_TIMING_U_S, and the timing's part at `velocity` (deviation unit)."""
    limit = timing_speed_limit(EXPECTED_TIMING_U_S, 0.0, 1.0, 1.0, wanted_u, kind)
    return limit, timing_u(velocity, EXPECTED_TIMING_U_S, 0.0, 1.0, 1.0, kind)[0]


def timing_u(velocity: float, alignment_s: float, jitter_s: float, rate_hz: float, window: float,
             kind: str = "linear") -> tuple[float, float]:
    """The timing part of one target's per-pass uncertainty at `velocity` (axis unit/s), deviation
    unit: v·√(u_align² + jitter²/n), with `alignment_s` the alignment's standard uncertainty and
    `jitter_s` the sample jitter (s), n the samples a `window` (axis unit) holds per pass at
    `rate_hz`; and n."""
    scale = DEVIATION_SCALE[UNITS[kind][0]]
    n = max(window / velocity * rate_hz, 1.0) if velocity > 0 else math.inf
    return velocity * scale * math.sqrt(alignment_s**2 + jitter_s**2 / n), n


def timing_speed_limit(alignment_s: float, jitter_s: float, rate_hz: float, window: float, wanted_u: float,
                       kind: str = "linear") -> float:
    """The highest velocity (axis unit/s) at which `timing_u` stays within `wanted_u` (deviation
    unit). A scan's own limit (`speed_limit`, from its alignment and jitter) and the limit
    `axiscal plan` predicts (from an expected alignment) both come from here."""
    lo, hi = 0.0, 1e4
    for _ in range(100):
        mid = (lo + hi) / 2
        if timing_u(mid, alignment_s, jitter_s, rate_hz, window, kind)[0] <= wanted_u:
            lo = mid
        else:
            hi = mid
    return lo

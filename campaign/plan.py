"""The test plan: a list of immutable steps that the executor interprets. A dry run walks the list.

The linear cycle (seed 000, ISO 230-2): from the start move to -L1 (overrun), visit 0, L ... nL,
then nL+L1 (overrun), then come back down through nL ... 0 to -L1; repeat for N cycles. Overrun
moves are motion only. The pilgrim (step) cycle visits one target at a time: from below (+), then
from above (-), N times, before going on to the next target.

Positions are in the axis unit (mm or deg), velocities in axis unit/s, times in s.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from campaign.config import Config
from campaign.errors import SafetyError

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
    """Capture `point`: the dwell method averages the last `window_s`; the stable method waits at
    most `timeout_s` for a stable reading."""

    point: Point
    window_s: float
    timeout_s: float


@dataclass(frozen=True)
class Checkpoint:
    """Record the captured point durably (append + fsync) before going on."""

    point: Point


Step = Move | Settle | Capture | Checkpoint


@dataclass(frozen=True)
class Plan:
    """The steps, the targets (axis unit) and the offsets applied to the nominal grid."""

    steps: tuple[Step, ...]
    targets: tuple[float, ...]
    offsets: tuple[float, ...]
    seed: int

    @property
    def points(self) -> list[Point]:
        return [s.point for s in self.steps if isinstance(s, Checkpoint)]

    def travel(self, start: float | None = None) -> float:
        """Total distance of all moves, axis unit (from `start`, default the first move's end)."""
        moves = [s.position for s in self.steps if isinstance(s, Move)]
        here = moves[0] if start is None else start
        total = 0.0
        for p in moves:
            total += abs(p - here)
            here = p
        return total


def nominal_targets(config: Config) -> list[float]:
    plan = config["plan"]
    if plan["targets"] is not None:
        return list(plan["targets"])
    return [float(t) for t in np.linspace(plan["start"], plan["start"] + plan["length"], plan["count"])]


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
        phases = (np.arange(n) * GOLDEN + (seed % 1000) * GOLDEN / 1000) % 1.0
    offsets = (2 * phases - 1) * fraction * spacing
    offsets[0] = 0.0
    return [float(round(o, 6)) for o in offsets]


def build_plan(config: Config) -> Plan:
    """The plan for a config. Does not check limits: see `check_plan`."""
    p = config["plan"]
    nominal = nominal_targets(config)
    offsets = target_offsets(nominal, p["offsets"], p["offset_fraction"], p["seed"])
    targets = [round(t + o, 9) for t, o in zip(nominal, offsets)]
    v, l1 = p["velocity"], p["overrun"]
    capture = config["capture"]
    dwell_rng = np.random.default_rng([p["seed"], 1])  # its own stream: the offsets do not change
    steps: list[Step] = []
    index = 0

    def visit(run: int, direction: int, i: int) -> None:
        nonlocal index
        point = Point(index, run, direction, i, targets[i])
        dwell = p["dwell_s"] * (1 + dwell_rng.uniform(-1, 1) * p["dwell_jitter"]) if p["dwell_jitter"] else p["dwell_s"]
        if capture["method"] == "dwell":
            window = min(capture["average_s"], dwell)
            before = [Settle(dwell - window)] if dwell > window else []
            timeout = window
        else:
            window, before, timeout = capture["stable_window_s"], [], capture["stable_timeout_s"]
        steps.extend([Move(targets[i], v), *before, Capture(point, window, timeout), Checkpoint(point)])
        index += 1

    low, high = targets[0] - l1, targets[-1] + l1
    for run in range(1, p["cycles"] + 1):
        if p["cycle"] == "linear":
            steps.append(Move(low, v, overrun=True))
            for i in range(len(targets)):
                visit(run, +1, i)
            steps.append(Move(high, v, overrun=True))
            for i in reversed(range(len(targets))):
                visit(run, -1, i)
    if p["cycle"] == "linear":
        steps.append(Move(low, v, overrun=True))
    else:
        for i, t in enumerate(targets):
            for run in range(1, p["cycles"] + 1):
                steps.append(Move(t - l1, v, overrun=True))
                visit(run, +1, i)
                steps.append(Move(t + l1, v, overrun=True))
                visit(run, -1, i)
    return Plan(tuple(steps), tuple(targets), tuple(offsets), p["seed"])


def check_motion(position: float, velocity: float, config: Config) -> None:
    """Refuse (SafetyError, exit 2) a motion outside the soft limits or above the velocity limit.
    Called before every motion is sent, and for the whole plan before anything moves."""
    axis = config["axis"]
    lo, hi, unit = axis["soft_limit_min"], axis["soft_limit_max"], axis["unit"]
    if not (math.isfinite(position) and lo <= position <= hi):
        raise SafetyError(f"motion to {position:g} {unit} is outside the soft limits [{lo:g}, {hi:g}] {unit}")
    if not (math.isfinite(velocity) and 0 < velocity <= axis["max_velocity"]):
        raise SafetyError(f"velocity {velocity:g} {unit}/s is outside (0, {axis['max_velocity']:g}] {unit}/s "
                          "(axis.max_velocity)")


def check_plan(plan: Plan, config: Config) -> None:
    """Check every move of the plan before anything is commanded."""
    for step in plan.steps:
        if isinstance(step, Move):
            check_motion(step.position, step.velocity, config)


def move_time_s(distance: float, velocity: float, acceleration: float) -> float:
    """Duration of a trapezoidal (or triangular) move, s."""
    distance = abs(distance)
    if distance == 0:
        return 0.0
    ramp = velocity * velocity / acceleration
    if distance >= ramp:
        return distance / velocity + velocity / acceleration
    return 2 * math.sqrt(distance / acceleration)


def estimate_duration_s(plan: Plan, config: Config, start: float | None = None) -> float:
    """Estimated campaign duration, s: moves, settles and capture windows (stable: its window)."""
    accel = config["axis"]["max_acceleration"]
    total, here = 0.0, start
    for step in plan.steps:
        if isinstance(step, Move):
            if here is not None:
                total += move_time_s(step.position - here, step.velocity, accel)
            here = step.position
        elif isinstance(step, Settle):
            total += step.seconds
        elif isinstance(step, Capture):
            total += step.window_s
    return total

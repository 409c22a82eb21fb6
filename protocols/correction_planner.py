"""Motion-planned correction (the 2024 motion-planning patent): the applied compensation follows its desired value with a
bounded rate and a bounded acceleration, one control cycle at a time.

The planner works on a sampled grid. Its state is the applied value y (axis unit) and the change
in the last cycle, the *step* d = y_k - y_(k-1) (axis unit per cycle). The bounds, per cycle:

- rate:         |d_k| <= max_step = max_rate * dt                      (max_rate: axis unit/s)
- acceleration: |d_k - d_(k-1)| <= accel_step = max_accel * dt**2      (max_accel: axis unit/s²)

Every cycle it takes the largest step towards the desired value from which it can still stop on
that value without passing it (decelerating at accel_step per cycle), limited by the two bounds.
That is the time-optimal policy on the grid: accelerate, cruise, decelerate, land exactly, and
then stay (no chattering). When the desired value jumps behind a moving correction, it brakes at
the full bound, passes the value (the only way, for a mass that cannot stop at once) and comes
back. The algorithm is documented in docs/correction-planner.md and mirrored line for line in
protocols/st/FB_AxiscalCompensation.st (M_PlanCycle and M_StoppingStep).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SLACK = 1.0 + 1e-9
"""Braking and the last step onto the desired value may exceed the acceleration bound by this
factor (one part in 1e9). It absorbs the rounding of value + step, which would otherwise leave an
overshoot of a few ulp at the end of a long braking phase and one more cycle."""


@dataclass(frozen=True)
class PlannerLimits:
    """Bounds of the planned correction. max_rate: axis unit/s (> 0). max_accel: axis unit/s²
    (> 0). cycle_s: the control cycle dt, s (> 0)."""

    max_rate: float
    max_accel: float
    cycle_s: float

    def __post_init__(self) -> None:
        for name in ("max_rate", "max_accel", "cycle_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value}")

    @property
    def max_step(self) -> float:
        """Largest change of the correction in one cycle, axis unit."""
        return self.max_rate * self.cycle_s

    @property
    def accel_step(self) -> float:
        """Largest change of the step from one cycle to the next, axis unit."""
        return self.max_accel * self.cycle_s**2


@dataclass(frozen=True)
class PlannerState:
    """value: the applied correction, axis unit. step: its change in the last cycle, axis unit."""

    value: float = 0.0
    step: float = 0.0


def stopping_step(remaining: float, accel_step: float) -> float:
    """The largest step (axis unit per cycle) after which a distance of `remaining` (axis unit,
    >= 0) can still be covered exactly, braking by `accel_step` per cycle and stopping at its end.

    With m further braking steps the steps are d, d-a, ..., d-m*a (then 0), which covers
    (m+1)*(d - a*m/2). The smallest m for which the braking fits is the smallest m >= 0 with
    a*(m+1)*(m+2)/2 >= remaining; the square root gives it up to rounding, which the three
    checks correct.
    """
    if remaining <= 0.0:
        return 0.0
    m = math.trunc(max(0.0, min(math.sqrt(2.0 * remaining / accel_step + 0.25) - 1.5, 2.0e9)))
    for _ in range(3):
        if accel_step * (m + 1) * (m + 2) / 2.0 < remaining:
            m += 1
    return remaining / (m + 1) + accel_step * m / 2.0


def plan_cycle(state: PlannerState, desired: float, limits: PlannerLimits) -> PlannerState:
    """One control cycle: the applied correction moved towards `desired` (axis unit)."""
    max_step = limits.max_step
    accel_step = limits.accel_step
    gap = desired - state.value
    sign = 1.0 if gap > 0.0 or (gap == 0.0 and state.step >= 0.0) else -1.0
    toward = sign * state.step  # last step, positive when it went towards desired
    wanted = stopping_step(abs(gap), accel_step)
    step = min(max(wanted, toward - accel_step * SLACK), toward + accel_step)
    step = min(max(step, -max_step), max_step)
    reach = abs(gap)
    if step >= reach and toward - accel_step * SLACK <= reach <= accel_step * SLACK:
        return PlannerState(desired, gap)  # land exactly on the desired value, then stop
    return PlannerState(state.value + sign * step, sign * step)


def plan(desired: np.ndarray | list[float], limits: PlannerLimits,
         start: PlannerState = PlannerState()) -> np.ndarray:
    """The applied correction (axis unit) after each cycle, for the desired value of each cycle."""
    state = start
    out = np.empty(len(desired))
    for k, value in enumerate(desired):
        state = plan_cycle(state, float(value), limits)
        out[k] = state.value
    return out


def minimum_time(distance: float, max_rate: float, max_accel: float) -> float:
    """Shortest time (s) in continuous time to move a correction by `distance` (axis unit) from
    rest to rest with rate <= max_rate (axis unit/s) and acceleration <= max_accel (axis unit/s²):
    a triangle profile when the rate bound is never reached, a trapezoid otherwise."""
    distance = abs(distance)
    if distance * max_accel <= max_rate**2:
        return 2.0 * math.sqrt(distance / max_accel)
    return distance / max_rate + max_rate / max_accel

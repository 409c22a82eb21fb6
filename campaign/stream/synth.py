"""A synthetic continuous stream for a plan, as another program would log it: trapezoidal moves between
the plan's endpoints, a dwell at each target, noise. Used by the import-stream tests and bench.

Positions in the axis unit (mm or deg), times in s. The machine error is a scale error
(`ppm` of the position), a reversal value (`backlash` in the axis unit, split ± by approach
direction) and a per-visit scatter; the readings add white noise of `noise` (axis unit).

Two ways a real axis is not still where a controller's dwell begins or ends can be added: a slow
final approach (the move stops short and the axis creeps in, its speed decaying exponentially from
`approach_speed`; the controller starts its dwell timer when the creep is within `in_position` of
the stop) and a slow start (the axis creeps toward the next stop over the end of the dwell).
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from campaign.config import Config
from campaign.plan import Plan, move_time_s

if TYPE_CHECKING:
    import pandas as pd


def _stops(plan: Plan, config: Config, overrun_dwell_s: float, skip_point: int | None) -> list[list[float]]:
    """(position, dwell s, point index or -1) per move endpoint; `skip_point` gets no stop at all."""
    dwell = config.plan.dwell_s
    stops = [[s.position, dwell, s.point.index] if s.point else [s.position, overrun_dwell_s, -1]
             for s in plan.stops()]
    return [s for s in stops if s[2] != skip_point or skip_point is None]


def _trapezoid(tau: np.ndarray, distance: np.ndarray, velocity: float, accel: float) -> np.ndarray:
    """Distance covered `tau` s into a trapezoidal (or triangular) move of `distance`."""
    ramp = np.minimum(velocity / accel, np.sqrt(distance / accel))
    peak = accel * ramp
    total = distance / np.maximum(peak, 1e-12) + ramp
    return np.where(tau < ramp, accel * tau**2 / 2,
                    np.where(tau < total - ramp, accel * ramp**2 / 2 + peak * (tau - ramp),
                             distance - accel * np.maximum(total - tau, 0) ** 2 / 2))


def synthetic_stream(plan: Plan, config: Config, rate_hz: float, seed: int = 0, noise: float = 0.3e-3,
                     ppm: float = -12.0, backlash: float = 2e-3, scatter: float = 0.5e-3,
                     overrun_dwell_s: float = 0.0, skip_point: int | None = None, creep_s: float = 0.0,
                     creep: float = 0.0, approach: float = 0.0, approach_speed: float = 0.2,
                     in_position: float = 1e-3) -> tuple[pd.DataFrame, np.ndarray]:
    """The stream (columns time_s and reading_mm or reading_deg) and the true error of each plan
    point (axis unit; NaN for a skipped point). The stream starts moving at t = 0 from the first
    target.

    `creep_s`, `creep`: a slow start, as a real axis shows: over the last `creep_s` s of each dwell
    the axis already creeps `creep` (axis unit, growing with the square of time) toward the next
    stop; the move then makes up the difference.

    `approach`, `approach_speed`, `in_position`: a slow final approach. Each move's trapezoid
    stops `approach` (axis unit) short of the stop, from where the axis creeps in at
    `approach_speed` (axis unit/s), decaying exponentially (time constant approach /
    approach_speed, s). The dwell (`plan.dwell_s`, at whose end a controller captures) begins when
    the creep is within `in_position` (axis unit) of the stop; the creep goes on decaying through
    the dwell. The next move starts from the stop itself (the creep left at the dwell's end,
    in_position · exp(-dwell / time constant), is dropped)."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    velocity, accel = config.plan.velocity, config.axis.max_acceleration
    stops = _stops(plan, config, overrun_dwell_s, skip_point)
    positions = np.array([plan.targets[0]] + [s[0] for s in stops])
    short = np.minimum(approach, np.abs(np.diff(positions)) / 2)  # creep-in distance per move, axis unit
    tau = short / approach_speed if approach > 0 else np.zeros(len(stops))  # s
    settle = np.where(short > in_position, tau * np.log(np.maximum(short, in_position) / in_position), 0.0)  # s
    moves = np.array([move_time_s(abs(b - a) - c, velocity, accel)
                      for (a, b), c in zip(itertools.pairwise(positions), short)])
    dwells = np.array([s[1] for s in stops])
    direction = np.sign(np.diff(positions))
    error = positions[1:] * ppm * 1e-6 + direction * backlash / 2 + rng.normal(0, scatter, len(stops))
    # segment k: move to `short` before stop k during [ends_k - moves_k, ends_k), creep in until
    # arrive_k, then dwell until leave_k
    leave = np.cumsum(moves + settle + dwells)
    arrive = leave - dwells
    ends = arrive - settle
    t = np.arange(1, int(leave[-1] * rate_hz) + 1) / rate_hz
    k = np.minimum(np.searchsorted(leave, t, side="right"), len(stops) - 1)
    start = np.concatenate([[positions[0]], positions[1:-1] + error[:-1]])
    travel = positions[1:] + error - start
    trapezoid = np.abs(travel) - short  # axis unit
    covered = _trapezoid(np.clip(t - (ends[k] - moves[k]), 0, moves[k]), trapezoid[k], velocity, accel)
    if approach > 0:
        since = np.maximum(t - ends[k], 0)  # s
        covered = covered + short[k] * (1 - np.exp(-since / np.maximum(tau[k], 1e-12)))
    reading = start[k] + np.sign(travel[k]) * covered + rng.normal(0, noise, len(t))
    if creep_s > 0 and creep:
        ahead = np.sign(travel[np.minimum(k + 1, len(stops) - 1)])  # the next move's direction
        early = np.clip((t - (leave[k] - creep_s)) / creep_s, 0, 1) ** 2 * (k + 1 < len(stops))
        left = 1 - covered / np.maximum(np.abs(travel[k]), 1e-12)  # of this move (it began creeping)
        came = np.concatenate([[0.0], np.sign(travel[1:])])[k] * (k > 0)
        reading += ahead * creep * early * (t >= arrive[k]) + came * creep * left * (t < arrive[k])
    truth = np.full(len(plan.points), np.nan)
    measured = np.array([s[2] for s in stops])
    truth[measured[measured >= 0]] = error[measured >= 0]
    column = "reading_mm" if config.axis.unit == "mm" else "reading_deg"
    return pd.DataFrame({"time_s": t, column: reading}), truth

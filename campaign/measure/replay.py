"""Replay: re-run a recorded campaign's timeline offline from its raw stream.

Every raw sample carries the plan step and the point it belongs to, so the samples of each point's
approach, settle and capture are known. Replay feeds them, tick by tick, through the same capture
code (campaign.measure.capture) and the same corrections (campaign.measure.deviation.point_deviation) as the live
campaign. With the recorded capture settings it reproduces the recorded point table; with other
settings it shows what would change. Times in s, positions in axis unit, deviations in µm
(arcsec for a rotary axis).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from campaign import capture_methods
from campaign.config import capture_spec
from campaign.measure.capture import BeamLost, Captured, NotStable, capture_point
from campaign.measure.deviation import point_deviation
from campaign.measure.env_guard import EnvironmentGuard
from campaign.plan import Capture, Plan, capture_at
from campaign.record import load_raw, open_campaign
from campaign.specs import CaptureSpec
from protocols.hardware import Reading
from protocols.units import DEVIATION_SCALE

if TYPE_CHECKING:
    import pandas as pd

TICK_EPSILON_S = 1e-6
"""Recorded times closer than this are the same tick, s (far below the sample period)."""



@dataclass
class ReplayedPoint:
    """One point replayed: its deviation (None when it could not be captured, see `reason`)."""

    index: int
    run: int
    direction: int
    target: float
    deviation: float | None
    wait_s: float | None
    samples: int
    time_s: float | None
    reason: str = ""


def _readings(rows: pd.DataFrame) -> list[Reading]:
    import pandas as pd

    def value(v: Any) -> float | None:  # a cell of raw.csv: a number or NA
        return None if pd.isna(v) else float(v)

    def number(v: Any) -> float:
        return float(v)

    return [Reading(number(r.instrument_time_s), number(r.reading), bool(r.signal_ok), value(r.signal_pct), value(r.air_temp_c),
                    value(r.air_pressure_hpa), value(r.humidity_pct), value(r.material_temp_c))
            for r in rows.itertuples(index=False)]


def _ticks(rows: pd.DataFrame, arrival: float) -> Iterator[tuple[float, list[Reading]]]:
    """Recorded samples as capture ticks: (time since arrival s, the readings of that tick)."""
    for t_s, tick in rows.groupby("t_s", sort=True):
        yield float(t_s) - arrival, _readings(tick)  # type: ignore[arg-type]  # the float column t_s


def _capture(step: Capture, deviation_scale: float, rows: pd.DataFrame, capture_step: int, arrival: float,
             ) -> Captured:
    """Capture one point from its samples after arrival (`rows`) with capture_point, as the executor
    did. A dwell capture ends where the recorded capture window (`capture_step`'s samples) ended and
    averages the last `step.window_s` before it."""
    if not capture_methods.method(step.spec.method).fixed_dwell:
        return capture_point(step, deviation_scale, _ticks(rows, arrival), 0.0)
    recorded = rows[rows.step == capture_step]
    if recorded.empty:
        raise BeamLost("no capture-window samples recorded")
    end = float(recorded.t_s.max())
    if end - arrival < step.window_s - TICK_EPSILON_S:
        raise BeamLost(f"the recording holds only {end - arrival:.2f} s after arrival")
    start_s = end - arrival - step.window_s
    window = rows[(rows.t_s > end - step.window_s + TICK_EPSILON_S) & (rows.t_s <= end + TICK_EPSILON_S)]
    return capture_point(step, deviation_scale, _ticks(window, arrival), start_s)


def replay(directory: str | Path, capture_overrides: dict[str, Any] | None = None, speed: float | None = None,
           ) -> tuple[CaptureSpec, Plan, list[ReplayedPoint]]:
    """Replay `directory` from its recorded plan (each capture step's CaptureSpec), with the keys
    in `capture_overrides` replaced (validated as the [capture] table). Returns the capture spec of
    the replay (that of the first point), the plan and the points. `speed`: pace the timeline at N
    times real time (None: as fast as possible). Needs no config.toml when plan.jsonl describes the
    campaign (plan format 2)."""
    path = Path(directory)
    campaign = open_campaign(path)
    config = campaign.config()
    plan = campaign.plan_for(config)  # its step indices are those in raw.csv
    scale = DEVIATION_SCALE[config.axis.unit]
    raw = load_raw(path)
    guard = EnvironmentGuard()
    results: list[ReplayedPoint] = []
    last_t = 0.0
    used: CaptureSpec | None = None
    for visit in plan.visits():
        point, move_step, capture_step = visit.point, visit.step, visit.capture_step
        recorded = visit.capture.spec
        given = {k: v for k, v in asdict(recorded).items() if v is not None}  # None: a key not given
        spec = capture_spec({**given, **(capture_overrides or {})}, "replay") \
            if capture_overrides else recorded
        used = used or spec
        # a dwell capture's dwell is the recorded one; a stable capture's steps do not hold it
        dwell_s = visit.dwell_s if capture_methods.method(recorded.method).fixed_dwell else config.plan.dwell_s
        _, step = capture_at(point, dwell_s, spec)
        rows = raw[raw.point == point.index]
        moves = rows[rows.step == move_step]
        if moves.empty:
            results.append(ReplayedPoint(point.index, point.run, point.direction, point.target, None, None, 0,
                                         None, "not recorded"))
            continue
        arrival = float(moves.t_s.max())
        after = rows[(rows.t_s > arrival + TICK_EPSILON_S) & (rows.step != move_step)]
        if speed:
            time.sleep(max(0.0, arrival - last_t) / speed)
            last_t = arrival
        try:
            got = _capture(step, scale, after, capture_step, arrival)
        except (BeamLost, NotStable) as exc:  # as the live campaign's fault, said for this point
            results.append(ReplayedPoint(point.index, point.run, point.direction, point.target, None, None,
                                         len(after), None, str(exc)))
            continue
        env, _ = guard.check(got.env, arrival + got.wait_s)  # as the live campaign does
        deviation, _, _ = point_deviation(config.environment, config.axis.unit, point.target, replace(got, env=env))
        results.append(ReplayedPoint(point.index, point.run, point.direction, point.target, deviation,
                                     got.wait_s, got.samples, arrival + got.wait_s))
    return used or config.capture, plan, results

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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from campaign.config import Config, load_config
from campaign.measure.capture import BeamLost, Captured, capture_dwell, capture_stable
from campaign.measure.deviation import point_deviation
from campaign.measure.env_guard import EnvironmentGuard
from campaign.plan import Plan
from campaign.record.directory import load_raw, open_campaign
from protocols.hardware import Reading
from protocols.units import DEVIATION_SCALE

if TYPE_CHECKING:
    import pandas as pd

TICK_EPSILON_S = 1e-6
"""Times closer than this are the same tick, s (far below the sample period)."""


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


def _capture(config: Config, rows: pd.DataFrame, capture_step: int, arrival: float, dwell_s: float) -> Captured:
    """Capture one point from its samples after arrival, with `config`'s capture settings."""

    c = config["capture"]
    if c["method"] == "dwell":
        recorded = rows[rows.step == capture_step]
        if recorded.empty:
            raise BeamLost("no capture-window samples recorded")
        end = float(recorded.t_s.max())
        average_s = min(c["average_s"], dwell_s)  # as campaign.plan.build_plan
        if end - arrival < average_s - TICK_EPSILON_S:
            raise BeamLost(f"the recording holds only {end - arrival:.2f} s after arrival")
        window = rows[rows.t_s > end - average_s + TICK_EPSILON_S]
        return capture_dwell(_readings(window), end - arrival)
    tolerance = c["stable_tolerance"] / DEVIATION_SCALE[config["axis"]["unit"]]
    drift = c["stable_drift"] / DEVIATION_SCALE[config["axis"]["unit"]]
    readings: list[Reading] = []
    for t_s, tick in rows.groupby("t_s", sort=True):
        t = float(t_s)  # type: ignore[arg-type]  # the group key of the float column t_s
        if t - arrival > c["stable_timeout_s"] + TICK_EPSILON_S:
            break
        readings.extend(_readings(tick))
        got = capture_stable(readings, c["stable_window_s"], tolerance, drift, t - arrival)
        if got is not None:
            return got
    raise BeamLost("never stable within the recorded samples and the timeout")


def replay(directory: str | Path, capture_overrides: dict | None = None, speed: float | None = None,
           ) -> tuple[Config, Plan, list[ReplayedPoint]]:
    """Replay `directory` with its recorded config, the [capture] keys in `capture_overrides`
    replaced. `speed`: pace the timeline at N times real time (None: as fast as possible)."""
    path = Path(directory)
    campaign = open_campaign(path)
    config = load_config(path / "config.toml")
    plan = campaign.plan_for(config)  # its step indices are those in raw.csv
    recorded_dwell = config["capture"]["method"] == "dwell"  # else the steps do not hold the dwell
    config.sections["capture"] = {**config["capture"], **(capture_overrides or {})}
    raw = load_raw(path)
    guard = EnvironmentGuard()
    results: list[ReplayedPoint] = []
    last_t = 0.0
    for visit in plan.visits():
        point, move_step, capture_step = visit.point, visit.step, visit.capture_step
        rows = raw[raw.point == point.index]
        dwell_s = visit.dwell_s if recorded_dwell else config["plan"]["dwell_s"]
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
            got = _capture(config, after, capture_step, arrival, dwell_s)
        except BeamLost as exc:
            results.append(ReplayedPoint(point.index, point.run, point.direction, point.target, None, None,
                                         len(after), None, str(exc)))
            continue
        env, _ = guard.check(got.env, arrival + got.wait_s)  # as the live campaign does
        deviation, _, _ = point_deviation(config, point.target, replace(got, env=env))
        results.append(ReplayedPoint(point.index, point.run, point.direction, point.target, deviation,
                                     got.wait_s, got.samples, arrival + got.wait_s))
    return config, plan, results

"""The guided session's setup checklist: what `axiscal guide` checks before and after it asks to move.

Before any motion: the soft limits with a plan preview (no hardware needed), then the controller
(reachable, axis enabled and homed, no error), the interferometer signal and the environment sensors.
After the operator's confirmation: the laser alignment check, which moves the axis to both ends of
the plan (each move checked with `check_motion` first) and compares signal and reading with the
axis position. Positions in the axis unit (mm or deg), times in s.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from statistics import median

from rich.table import Table

from campaign.config import Config
from campaign.errors import SafetyError
from campaign.guide.dashboard import error_id_text
from campaign.measure import Control, move_and_wait
from campaign.plan import Plan, check_motion, check_plan, estimate_duration_s
from protocols.hardware import AxisError, Hardware, InstrumentError, Reading
from protocols.units import counted

SAMPLE_S = 1.0
"""How long the signal and environment are sampled at rest, s."""

PLAUSIBLE = {
    "air_temp_c": ("air temperature", "°C", 10.0, 35.0),
    "air_pressure_hpa": ("air pressure", "hPa", 800.0, 1100.0),
    "humidity_pct": ("humidity", "% RH", 5.0, 95.0),
    "material_temp_c": ("material temperature", "°C", 10.0, 35.0),
}
"""Environment field -> (name, unit, lowest and highest plausible value)."""

ALIGNMENT_MISMATCH = {"mm": 0.5, "deg": 0.05}
"""Largest |interferometer reading - axis position| at either end of the plan, axis unit. Catches a
laser not zeroed at the start, a reversed direction or a wrong scale, not the cosine error."""


@dataclass
class CheckItem:
    """One checklist line: what was checked, OK (True), FAIL (False) or not needed (None), and the
    value found, with units."""

    name: str
    ok: bool | None
    value: str


def failures(items: list[CheckItem]) -> list[CheckItem]:
    return [item for item in items if item.ok is False]


def soft_limit_item(plan: Plan, config: Config) -> CheckItem:
    axis = config.axis
    unit, (lo, hi) = axis.unit, plan.ends()
    limits = f"[{axis.soft_limit_min:g}, {axis.soft_limit_max:g}] {unit}"
    try:
        check_plan(plan, axis)
    except SafetyError as exc:
        return CheckItem("soft limits", False, f"{exc}")
    return CheckItem("soft limits", True, f"plan {lo:g} to {hi:g} {unit} at {config.plan.velocity:g} "
                                          f"{unit}/s, inside {limits}")


def record_item(directory: Path) -> CheckItem:
    """The campaign directory must not hold a campaign already (checked before anything moves)."""
    points = directory / "points.csv"
    if points.exists() and points.stat().st_size:
        return CheckItem("record directory", False, f"{directory} already holds a campaign: use another --out")
    return CheckItem("record directory", True, f"{directory}")


def plan_preview(plan: Plan, config: Config, speed: float | None) -> Table:
    """Targets, points, travel and estimated duration (machine time; real time at --speed N)."""
    unit, runs = config.axis.unit, config.plan.cycles
    targets = ", ".join(f"{t:g}" for t in plan.targets)
    duration_s = estimate_duration_s(plan, config.axis, config.plan.start)
    duration = f"{duration_s / 60:.1f} min"
    if config.controller.type == "sim" and speed:
        duration += f" of machine time, about {duration_s / speed / 60:.1f} min at --speed {speed:g}"
    table = Table(title="Plan", show_header=False)
    table.add_column(style="bold")
    table.add_column()
    table.add_row("targets", f"{targets} {unit}")
    table.add_row("points", f"{len(plan.points)} ({len(plan.targets)} targets × {counted(runs, 'run')} × 2 directions)")
    table.add_row("cycle", f"{config.plan.cycle}, dwell {config.plan.dwell_s:g} s, overrun "
                           f"{config.plan.overrun:g} {unit}")
    table.add_row("travel", f"{plan.travel():.1f} {unit}")
    table.add_row("estimated duration", duration)
    return table


def sample_readings(hw: Hardware, seconds: float, rate_hz: float) -> list[Reading]:
    """The readings that arrive over `seconds` (machine time), polled at the instrument rate."""
    readings: list[Reading] = []
    for _ in range(max(1, round(seconds * rate_hz))):
        hw.clock.sleep(1.0 / rate_hz)
        readings.extend(hw.interferometer.poll())
    return readings


def controller_item(hw: Hardware, unit: str) -> CheckItem:
    try:
        status = hw.axis.status()
    except AxisError as exc:
        return CheckItem("controller", False, f"not reachable: {exc}")
    ok = status.enabled and status.homed and not status.error
    yes = {True: "yes", False: "NO"}
    error = f"ERROR: controller error id {error_id_text(status.error_id)}" if status.error else "no error"
    return CheckItem("controller", ok, f"reachable, axis enabled {yes[status.enabled]}, homed "
                                       f"{yes[status.homed]}, {error}, at {status.actual_position:.3f} {unit}")


def signal_item(readings: list[Reading]) -> CheckItem:
    if not readings:
        return CheckItem("interferometer signal", False, f"no reading in {SAMPLE_S:g} s")
    bad = sum(not r.signal_ok for r in readings)
    levels = [r.signal_pct for r in readings if r.signal_pct is not None]
    level = f"lowest {min(levels):.0f} %, " if levels else ""
    return CheckItem("interferometer signal", bad == 0,
                     f"{level}{len(readings) - bad} of {len(readings)} readings with the beam OK")


def environment_items(readings: list[Reading], config: Config) -> list[CheckItem]:
    """One item per environment field: the sensor's median, else the config's value."""
    env = config.environment
    air = env.air_correction == "edlen"
    needed = {"air_temp_c": air, "air_pressure_hpa": air, "humidity_pct": air, "material_temp_c": env.normalise_to_20c}
    items = []
    for field, (name, unit, lo, hi) in PLAUSIBLE.items():
        values = [getattr(r, field) for r in readings if getattr(r, field) is not None]
        value, source = (median(values), "sensor") if values else (getattr(env, field, None), "config")
        if value is None:
            why = "needed for the correction" if needed[field] else "not needed"
            items.append(CheckItem(name, False if needed[field] else None, f"not measured ({why})"))
            continue
        ok = lo <= value <= hi
        items.append(CheckItem(name, ok, f"{value:.1f} {unit} ({source}; plausible {lo:g} to {hi:g} {unit})"))
    return items


def hardware_items(hw: Hardware, config: Config) -> list[CheckItem]:
    """Controller, signal and environment checks; nothing moves."""
    try:
        readings = sample_readings(hw, SAMPLE_S, config.instrument.rate_hz)
    except InstrumentError as exc:
        return [controller_item(hw, config.axis.unit), CheckItem("interferometer signal", False, str(exc))]
    return [controller_item(hw, config.axis.unit), signal_item(readings),
            *environment_items(readings, config)]


def move_and_sample(hw: Hardware, config: Config, position: float, velocity: float,
                    control: Control) -> tuple[float, list[Reading], list[Reading]]:
    """Move to `position` (checked against the limits first), then sample at rest. Returns (axis
    position, readings on the way, readings at rest). Halts the axis and raises KeyboardInterrupt
    when an abort is requested; AxisError on an axis error or a timeout."""
    rate = config.instrument.rate_hz
    on_the_way: list[Reading] = []

    def tick() -> None:
        if control.abort_requested():
            raise KeyboardInterrupt
        hw.clock.sleep(1.0 / rate)
        on_the_way.extend(hw.interferometer.poll())

    try:
        status = move_and_wait(hw.axis, hw.clock, tick, position, velocity, config.axis,
                               config.controller.move_timeout_s)
    except SafetyError:
        raise  # refused before anything was sent: nothing to halt
    except BaseException:
        try:
            hw.axis.halt()
        except AxisError:
            pass  # the connection is gone: the controller stops the axis on its own
        raise
    return status.actual_position, on_the_way, sample_readings(hw, SAMPLE_S, rate)


def alignment_item(hw: Hardware, plan: Plan, config: Config, control: Control) -> CheckItem:
    """Move to the high end of the plan, then to the low end (where the campaign starts), and
    compare the signal and the reading with the axis position at both ends."""
    unit, limit = config.axis.unit, ALIGNMENT_MISMATCH[config.axis.unit]
    lo, hi = plan.ends()
    ok, parts, travel = True, [], []
    try:
        for end in (hi, lo):
            actual, on_the_way, at_rest = move_and_sample(hw, config, end, config.plan.velocity, control)
            travel += on_the_way
            if not at_rest or any(not r.signal_ok for r in at_rest):
                ok = False
                parts.append(f"at {actual:.3f} {unit}: beam NOT OK")
                continue
            mismatch = median(r.position for r in at_rest) - actual
            levels = [r.signal_pct for r in at_rest if r.signal_pct is not None]
            signal = f"signal {min(levels):.0f} %, " if levels else ""
            ok = ok and abs(mismatch) <= limit
            parts.append(f"at {actual:.3f} {unit}: {signal}reading - axis {mismatch:+.4f} {unit}")
    except (AxisError, InstrumentError) as exc:
        return CheckItem("laser alignment", False, f"{'; '.join(parts + [str(exc)])}")
    lost = sum(not r.signal_ok for r in travel)
    ok = ok and lost == 0
    parts.append(f"beam {'OK' if lost == 0 else f'LOST in {lost} readings'} over the travel "
                 f"(limit |reading - axis| {limit:g} {unit})")
    return CheckItem("laser alignment", ok, "; ".join(parts))


def checklist_table(items: list[CheckItem]) -> Table:
    table = Table(title="Setup checklist", header_style="bold")
    table.add_column("check")
    table.add_column("result")
    table.add_column("found")
    marks = {True: "[green]OK[/]", False: "[bold red]FAIL[/]", None: "[dim]n/a[/]"}
    for item in items:
        table.add_row(item.name, marks[item.ok], item.value)
    return table


DATUM_CHANGE = {"mm": 0.05, "deg": 0.005}
"""Largest change of (reading - axis position) between the stop and a resume, axis unit: more
means the laser was re-zeroed or moved, and the old and new points would not share a datum."""


def datum_item(hw: Hardware, config: Config, recorded_offset: float | None) -> CheckItem:
    """At rest: is the laser's reading still where it was relative to the axis when the campaign
    stopped? A laser re-zeroed (or knocked) since then would shift every new point."""
    unit = config.axis.unit
    if recorded_offset is None:
        return CheckItem("laser datum", None, "no reading with the axis position was recorded before the stop")
    try:
        status = hw.axis.status()
        readings = [r for r in sample_readings(hw, SAMPLE_S, config.instrument.rate_hz) if r.signal_ok]
    except (AxisError, InstrumentError) as exc:
        return CheckItem("laser datum", False, str(exc))
    if not readings:
        return CheckItem("laser datum", False, "no reading with the beam OK")
    now = median(r.position for r in readings) - status.actual_position
    change = now - recorded_offset
    limit = DATUM_CHANGE[unit]
    ok = abs(change) <= limit
    verdict = "" if ok else "; the laser was re-zeroed or moved: set it back as it was, or start a new campaign"
    return CheckItem("laser datum", ok, f"reading - axis {now:+.4f} {unit} now, {recorded_offset:+.4f} {unit} at the stop "
                                        f"(change {change:+.4f} {unit}, limit {limit:g} {unit}){verdict}")


def reapproach_item(plan: Plan, config: Config, todo: list[int], again: list[int]) -> CheckItem:
    """Where the axis goes first, and what is left: the first missing point, re-approached from the
    overrun in its own direction (checked against the limits)."""
    unit = config.axis.unit
    point = plan.points[todo[0]]
    start = point.target - point.direction * config.plan.overrun
    try:
        check_motion(start, config.plan.velocity, config.axis)
    except SafetyError as exc:
        return CheckItem("re-approach", False, str(exc))
    skipped = f"; {len(again)} skipped earlier, measured again first" if again else ""
    return CheckItem("re-approach", True, f"point {point.index + 1} of {len(plan.points)} (run {point.run}, "
                                          f"{'+' if point.direction > 0 else '-'}) at {point.target:g} {unit}, from "
                                          f"the overrun at {start:g} {unit}; {len(todo)} points to measure{skipped}")

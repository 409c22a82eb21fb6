"""`axiscal plan CONFIG [--json]`: print the plan without moving anything."""

from __future__ import annotations

import argparse
from typing import Literal

from rich.table import Table

from campaign import capture_methods
from campaign.capture_methods import Window
from campaign.commands import SUMMARY
from campaign.config import Config, load_config
from campaign.plan import (
    Capture,
    Move,
    Plan,
    Settle,
    build_plan,
    check_plan,
    estimate_duration_s,
    plan_records,
)
from campaign.views import make_console, print_json
from protocols.units import UNITS, counted, unit_label


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("plan", help=SUMMARY["plan"],
                       description="Print the plan of a campaign config and check it against the limits.")
    p.add_argument("config", help="campaign TOML (see docs/config.md)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--steps", action="store_true", help="also list every step (a table; with --json, records)")
    p.set_defaults(func=run)


def summary(config: Config, plan: Plan) -> dict:
    a = config.axis
    return {"points": len(plan.points), "runs": config.plan.cycles, "targets": list(plan.targets),
            "offsets": list(plan.offsets), "seed": plan.seed, "unit": a.unit,
            "travel": round(plan.travel(), 6), "estimated_duration_s": round(estimate_duration_s(plan, config.axis), 1),
            "moves": len(plan.stops()), "cycle": config.plan.cycle,
            "soft_limits": [a.soft_limit_min, a.soft_limit_max], "max_velocity": a.max_velocity}


def planned_speed_limit(config: Config) -> dict:
    """A scan's speed against its timing budget before it runs: the highest velocity at which the
    timing keeps within capture.scan_wanted_u per target and pass with the timing uncertainty a scan
    is expected to leave (`campaign.plan.planned_timing`, as a follow-up scan's speed); the
    timing's part at capture.scan_velocity and a warning when that is above the limit (axis unit/s,
    deviation unit). The scan states its own limit after it ran, from its own alignment."""
    from campaign.plan import EXPECTED_TIMING_U_S, planned_timing

    c, kind = config.capture, config.axis.kind
    velocity = c.scan_velocity or 0.0
    limit, u = planned_timing(velocity, c.scan_wanted_u, kind)
    pos, dev = UNITS[kind][0], unit_label(UNITS[kind][1])
    assumed = (f"assuming a timing uncertainty of {EXPECTED_TIMING_U_S * 1e6:.3g} µs, the worst the simulated "
               f"machine's scans left; the scan states its own limit after it ran")
    warning = None
    if velocity > limit * (1 + 1e-9):
        warning = (f"capture.scan_velocity = {velocity:g} {pos}/s is too fast: the timing alone gives {u:.2g} {dev} "
                   f"per target and pass, more than capture.scan_wanted_u = {c.scan_wanted_u:g} {dev}; scan at "
                   f"most {limit:.3g} {pos}/s ({assumed})")
    return {"velocity": velocity, "speed_limit": round(limit, 6), "timing_u": round(u, 6),
            "wanted_u": c.scan_wanted_u, "assumed_timing_u_s": EXPECTED_TIMING_U_S, "warning": warning,
            "text": f"{limit:.3g} {pos}/s keeps the timing within {c.scan_wanted_u:g} {dev} per target and pass "
                    f"({u:.2g} {dev} at {velocity:g} {pos}/s; {assumed})"}


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    plan = build_plan(config)
    check_plan(plan, config.axis)
    info = summary(config, plan)
    speed = planned_speed_limit(config) if plan.sweeps else None
    if speed is not None:
        info["scan"] = {k: v for k, v in speed.items() if k != "text"}
    if args.json:
        if args.steps:
            info["steps"] = plan_records(plan)[1:]
        print_json(info)
        return 0
    console = make_console()
    u = info["unit"]
    table = Table(title=f"Plan: {args.config}", show_header=False)
    if plan.sweeps:
        v = config.capture.scan_velocity
        table.add_row("scan", f"{info['points']} sweeps ({info['runs']} {'pass' if info['runs'] == 1 else 'passes'} up and down at {v:g} {u}/s, "
                              f"a rest of {config.plan.dwell_s:g} s at each end); the table at {len(plan.targets)} "
                              "targets × 2 directions per pass comes from the streams: a diagnostic (docs/scan.md)")
        table.add_row("speed limit", speed["text"] if speed else "")
    else:
        table.add_row("points", f"{info['points']} ({len(plan.targets)} targets × 2 directions × "
                                f"{counted(info['runs'], 'run')})" if info["cycle"] == "linear" else str(info["points"]))
    table.add_row("targets", ", ".join(f"{t:g}" for t in plan.targets) + f" {u}")
    table.add_row("travel", f"{info['travel']:.1f} {u}")
    table.add_row("estimated duration", f"{info['estimated_duration_s'] / 60:.1f} min")
    table.add_row("soft limits", f"[{info['soft_limits'][0]:g}, {info['soft_limits'][1]:g}] {u}; "
                                 f"max velocity {info['max_velocity']:g} {u}/s — plan within limits")
    console.print(table)
    if speed and speed["warning"]:
        console.print(f"[yellow]warning:[/] {speed['warning']}", highlight=False)
    if args.steps:
        console.print(steps_table(plan, config))
    return 0


def steps_table(plan: Plan, config: Config) -> Table:
    """Every step of the plan as a table: what it does, where, how fast, for which point (counted
    from 1, as on the dashboard; plan index = point - 1) and how long."""
    unit = config.axis.unit
    table = Table(title="Steps", header_style="bold")
    columns: tuple[tuple[str, Literal["left", "center", "right"]], ...] = (
        ("step", "right"), ("action", "left"), (f"position {unit}", "right"), (f"speed {unit}/s", "right"),
        ("point", "right"), ("run", "right"), ("dir", "center"), ("time s", "right"))
    for head, justify in columns:
        table.add_column(head, justify=justify)
    for i, step in enumerate(plan.steps):
        if isinstance(step, Move):
            table.add_row(str(i), "move to overrun" if step.overrun else "move to target", f"{step.position:.3f}",
                          f"{step.velocity:g}", "", "", "", "")
        elif isinstance(step, Settle):
            table.add_row(str(i), "settle", "", "", "", "", "", f"{step.seconds:g}")
        elif isinstance(step, Capture):
            p = step.point
            how, time = capture_methods.method(step.spec.method).step_label(
                Window(0.0, step.window_s, step.timeout_s))
            table.add_row(str(i), how, f"{p.target:.3f}", "", str(p.index + 1), str(p.run),
                          "+" if p.direction > 0 else "-", time)
        else:
            table.add_row(str(i), "record the point", "", "", str(step.point.index + 1), "", "", "")
    return table

"""`axiscal program CONFIG --dialect linuxcnc|fanuc|siemens|heidenhain -o FILE`: the campaign's
plan as a part program for a controller axiscal does not drive (docs/part-programs.md)."""

from __future__ import annotations

import argparse
import hashlib
import json
from datetime import date

from campaign import __version__, capture_methods
from campaign.commands import SUMMARY
from campaign.config import Config, load_config
from campaign.convert import write_whole
from campaign.errors import InputError
from campaign.plan import Plan, build_plan, check_plan, plan_records
from campaign.views import make_console
from protocols.nc import DIALECTS, NcMove, NcProgram, render

SUFFIX = {"linuxcnc": ".ngc", "fanuc": ".nc", "siemens": ".mpf", "heidenhain": ".h"}
"""The usual file name ending per dialect (said in the help, not enforced)."""


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("program", help=SUMMARY["program"],
                       description="Write the config's plan (the overrun, every target in order, a dwell at "
                                   "each, the plan's feed) as a part program, for a controller axiscal does "
                                   "not drive; the laser software captures at the dwells.")
    p.add_argument("config", help="campaign TOML")
    p.add_argument("--dialect", required=True, choices=DIALECTS,
                   help="linuxcnc (.ngc), fanuc (.nc), siemens (.mpf) or heidenhain (.h)")
    p.add_argument("-o", "--output", required=True, help="the program file to write")
    p.set_defaults(func=run)


def campaign_id(config: Config, plan: Plan) -> str:
    """MACHINE-AXIS-<8 hex of the plan>: the same plan gives the same id."""
    digest = hashlib.sha256(json.dumps(plan_records(plan), sort_keys=True).encode()).hexdigest()[:8]
    return f"{config.campaign.machine or 'machine'}-{config.axis.name}-{digest}"


def nc_program(config: Config, plan: Plan) -> NcProgram:
    """The plan as moves: each stop of the plan in order, the feed from its velocity (per
    minute), at a target the dwell: the planned dwell with the dwell capture, the config's
    dwell_s with the stable one (the laser software decides when to capture)."""
    fixed = capture_methods.method(config.capture.method).fixed_dwell
    moves, last = [], None
    for stop in plan.stops():
        comment = ""
        if stop.point is None:
            comment = "overrun"
        elif (stop.point.run, stop.point.direction) != last:
            last = (stop.point.run, stop.point.direction)
            comment = f"run {stop.point.run} {'+' if stop.point.direction > 0 else '-'}"
        dwell = (stop.dwell_s if fixed else config.plan.dwell_s) if stop.point is not None else 0.0
        moves.append(NcMove(stop.position, stop.move.velocity * 60.0, dwell, comment))
    ident = campaign_id(config, plan)
    p = config.plan
    header = (f"axiscal ISO 230-2 campaign {ident}",
              (f"machine {config.campaign.machine}, axis {config.axis.name}, {len(plan.targets)} targets, "
              f"{p.cycles} cycles, dwell {p.dwell_s:g} s, overrun {p.overrun:g} {config.axis.unit}"),
              f"written by axiscal {__version__} on {date.today().isoformat()}, capture at each dwell")
    return NcProgram(config.axis.name, config.axis.unit, "AXISCAL", header, tuple(moves))


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    if capture_methods.method(config.capture.method).sweeps:
        raise InputError(f"{args.config}: capture.method = \"{config.capture.method}\": a scan is aligned with the "
                         "controller's time-stamped position stream, which axiscal takes only while it drives the "
                         "axis itself (axiscal run); a part program writes a stop-and-go plan")
    plan = build_plan(config)
    check_plan(plan, config.axis)
    program = nc_program(config, plan)
    write_whole(args.output, render(args.dialect, program))
    dwells = sum(1 for m in program.moves if m.dwell_s > 0)
    make_console().print(f"{args.output}: {args.dialect} program, {len(program.moves)} moves, {dwells} dwells "
                         f"({program.header[0]})")
    return 0

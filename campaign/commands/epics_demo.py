"""`axiscal demo --controller epics [--verify] [--inject ...] [--json]`: the demo campaign on the simulated
axis served as an EPICS motor record over Channel Access on loopback (docs/epics.md). With --verify the
closed loop through the IOC: the compensation table from the first campaign is written into the IOC's
compensation PVs, read back, enabled, and the axis measured again (a verification campaign that follows
the first)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from campaign.commands import hardware_opener
from campaign.commands.run import finish, run_config, with_on_fault
from campaign.compensation.corrections import corrections
from campaign.compensation.grid import POINT_LIMITS, resample
from campaign.config import Config, config_with, parse_config
from campaign.errors import InputError
from campaign.iso230 import evaluate
from campaign.measure import RichProgress, run_verification, start_campaign
from campaign.pointtable import read_points
from campaign.views import make_console, print_json

EPICS_DRIVER = '[axis_driver]\ntype = "epics"\npv = "SIM:M1"'


def epics_config(text: str) -> Config:
    """The demo config with the axis behind the simulated IOC's motor record SIM:M1."""
    old = '[axis_driver]\ntype = "sim"'
    if old not in text:
        raise InputError(f"demo.toml: '{old}' not found for the EPICS demo")
    return parse_config(text.replace(old, EPICS_DRIVER), "demo.toml (EPICS)")


def epics_demo(text: str, args: argparse.Namespace) -> int:
    config = epics_config(text)
    if not args.verify:
        if args.inject:
            from campaign.commands.demo import rehearse
            from campaign.faults import parse_inject

            faults = parse_inject(args.inject)
            text = text.replace('[axis_driver]\ntype = "sim"', EPICS_DRIVER)
            text += "\n[sim.faults]\n" + "".join(f"{name} = {{ at_s = {p['at_s']!r} }}\n"
                                                 for name, p in faults.items())
            return rehearse(parse_config(text, "demo.toml (EPICS)"), faults, args)
        return run_config(config, args)
    if args.inject:
        raise InputError("--inject and --verify: rehearse faults on one campaign at a time")
    config = with_on_fault(config, args)
    base = Path(args.out) if args.out else Path("runs") / f"epics-demo-{time.strftime('%Y%m%d-%H%M%S')}"
    with RichProgress(config.axis.unit) as observer:
        before = start_campaign(config, base / "before", opener=hardware_opener(), speed=args.speed,
                                observer=observer)
    if before.status != "completed":
        return finish(before, args, {"controller": "epics"})
    points = read_points(before.dir / "points.csv")
    table = resample(corrections(points, "auto", "inverse", "auto"), POINT_LIMITS["json"], None, None, 0.0)
    verification = config_with(config, {"campaign": {"purpose": "verification", "follows": str(before.dir)}})
    with RichProgress(config.axis.unit) as observer:
        after = run_verification(verification, table, base / "after", opener=hardware_opener(),
                                 baseline=before.dir, speed=args.speed, observer=observer)
    a_before = evaluate(points).summary["A"]
    a_after = evaluate(read_points(after.dir / "points.csv")).summary["A"] if after.points else None
    result = {"controller": "epics", "pv": config.controller.pv, "dir": str(base), "points": before.points,
              "points_after": after.points, "status_after": after.status, "A_before": a_before,
              "A_after": a_after, "unit": "um", "comp_file": str(after.dir / "plc-compensation.json")}
    if args.json:
        print_json(result)
    else:
        shown = "-" if a_after is None else f"{a_after:.3f}"
        make_console().print(f"EPICS ({config.controller.pv} on the simulated IOC): A {a_before:.3f} µm before, "
                             f"{shown} µm with the table written through Channel Access; campaigns in {base}")
    return 0 if after.status == "completed" else 3

"""`axiscal demo --controller linuxcnc [--verify] [--json]`: the demo campaign on a headless
LinuxCNC with the demo's axis limits (real time, so the plan is made quick: moves at the demo's
max_velocity, 0.3 s dwells), and with --verify the
closed loop through LinuxCNC's own compensation: compensate --format linuxcnc, restart LinuxCNC
with COMP_FILE, measure again (docs/linuxcnc.md)."""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

from campaign.commands import hardware_opener, stop_leftover_controller
from campaign.commands.run import finish, with_on_fault
from campaign.compensation.corrections import corrections
from campaign.compensation.grid import POINT_LIMITS, resample
from campaign.config import Config, parse_config
from campaign.convert import write_whole
from campaign.errors import InputError
from campaign.iso230 import evaluate
from campaign.measure import Outcome, RichProgress, start_campaign
from campaign.pointtable import read_points
from campaign.views import make_console, print_json
from protocols.tables import FormatOptions, render

INSTALL_HINT = ("LinuxCNC is not installed: apt-get install linuxcnc-uspace (Debian; tests/setup_system.sh "
                "installs it where apt is available)")
QUICK = (("dwell_s = 4.0", "dwell_s = 0.3"), ("average_s = 1.0", "average_s = 0.2"),
         ('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "linuxcnc"'),
         ('machine = "sim-press"', 'machine = "linuxcnc-sim"'))
"""The demo config made for LinuxCNC: it runs in real time, so short dwells, and (below) moves at the
demo's max_velocity. The [axis] limits stay the demo's: LinuxCNC's INI is generated from them."""
DEMO_VELOCITY = "velocity = 8.0"


def linuxcnc_config(text: str, comp_file: Path | None = None) -> Config:
    fastest = parse_config(text, "demo.toml").axis.max_velocity
    for old, new in (*QUICK, (DEMO_VELOCITY, f"velocity = {fastest!r}")):
        if old not in text:
            raise InputError(f"demo.toml: '{old}' not found for the LinuxCNC demo")
        text = text.replace(old, new)
    if comp_file is not None:
        text = text.replace('type = "linuxcnc"', f'type = "linuxcnc"\ncomp_file = "{comp_file}"')
    return parse_config(text, "demo.toml (LinuxCNC)")


def measure(config: Config, out: Path, args: argparse.Namespace) -> Outcome:
    config = with_on_fault(config, args)
    with RichProgress(config.axis.unit) as observer:
        return start_campaign(config, out, opener=hardware_opener(), observer=observer)


def comp_file_from(points: Path, out: Path) -> Path:
    """The LinuxCNC comp file (type 0) from a point table, as `compensate --format linuxcnc` makes it."""
    table = read_points(points)
    ctable = resample(corrections(table, "auto", "inverse", "auto"), POINT_LIMITS["linuxcnc"], None, None, 0.0)
    write_whole(out, render("linuxcnc", ctable, FormatOptions()).text)
    return out


def linuxcnc_demo(text: str, args: argparse.Namespace) -> int:
    if not (shutil.which("linuxcnc") and shutil.which("linuxcncrsh") and shutil.which("halcmd")):
        raise InputError(INSTALL_HINT)
    stop_leftover_controller(linuxcnc_config(text).driver, args.yes)
    base = Path(args.out) if args.out else Path("runs") / f"linuxcnc-demo-{time.strftime('%Y%m%d-%H%M%S')}"
    before = measure(linuxcnc_config(text), base / "before" if args.verify else base, args)
    if not args.verify or before.status != "completed":
        return finish(before, args, {"controller": "linuxcnc"})
    comp = comp_file_from(before.dir / "points.csv", base / "comp.txt")
    after = measure(linuxcnc_config(text, comp.resolve()), base / "after", args)
    a_before = evaluate(read_points(before.dir / "points.csv")).summary["A"]
    a_after = evaluate(read_points(after.dir / "points.csv")).summary["A"] if after.points else None
    result = {"controller": "linuxcnc", "dir": str(base), "points": before.points, "points_after": after.points,
              "status_after": after.status, "A_before": a_before, "A_after": a_after, "unit": "um",
              "comp_file": str(comp)}
    if args.json:
        print_json(result)
    else:
        make_console().print(f"LinuxCNC: A {a_before:.3f} µm before, "
                             f"{'-' if a_after is None else f'{a_after:.3f}'} µm with its COMP_FILE "
                             f"({comp}); campaigns in {base}")
    return 0 if after.status == "completed" else 3

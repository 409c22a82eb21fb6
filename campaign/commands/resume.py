"""`axiscal resume DIR [--speed N] [--json] [--plot OUT]`: continue an interrupted campaign."""

from __future__ import annotations

import json
from pathlib import Path

from campaign.commands import SUMMARY, hardware_opener, positive_number
from campaign.commands.run import finish
from campaign.measure.progress import RichProgress
from campaign.measure.session import resume_campaign
from campaign.plot import check_plot_path
from protocols.units import DEVIATION_SCALE


def register(sub) -> None:
    p = sub.add_parser("resume", help=SUMMARY["resume"],
                       description="Continue the campaign in DIR: re-approach the first missing point from "
                                   "the overrun in its direction, append to the same directory.")
    p.add_argument("dir", help="campaign directory")
    p.add_argument("--speed", type=positive_number, metavar="N", help="simulated machine: N times real time")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--plot", metavar="OUT", help="write the ISO 230-2 plot (.png or .svg)")
    p.set_defaults(func=run)


def read_meta_unit(directory: str) -> str:
    """The axis unit recorded in DIR/meta.json (mm when it cannot be read: resume then says why)."""
    try:
        unit = json.loads((Path(directory) / "meta.json").read_text(encoding="utf-8")).get("unit", "mm")
    except (OSError, ValueError):
        return "mm"
    return unit if unit in DEVIATION_SCALE else "mm"


def run(args) -> int:
    if args.plot:
        check_plot_path(args.plot)
    unit = read_meta_unit(args.dir)
    observer = RichProgress(unit)
    with observer:
        outcome = resume_campaign(args.dir, opener=hardware_opener(), speed=args.speed, observer=observer)
    return finish(outcome, args)

"""`axiscal refine POINTS.csv [--threshold T] [--max-per-interval K] [--config CONFIG -o NEW.toml] [--json]`:
propose extra targets where linear interpolation cannot follow the mean deviation."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.table import Table

from campaign.commands import SUMMARY, positive_integer, positive_number
from campaign.compensation.refine import follow_up_config, propose
from campaign.config import load_config, parse_config
from campaign.errors import InputError
from campaign.pointtable import read_points
from campaign.views import make_console, print_json
from protocols.units import unit_label


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("refine", help=SUMMARY["refine"],
                       description="Find the intervals where the mean deviation changes too fast for linear "
                                   "interpolation and propose extra targets there.")
    p.add_argument("file", help="point table CSV")
    p.add_argument("--threshold", type=positive_number, help="acceptable interpolation error, µm or arcsec "
                                                   "(default: the pooled s)")
    p.add_argument("--max-per-interval", type=positive_integer, default=3, help="most new targets in one interval (3)")
    p.add_argument("--config", help="the campaign config to turn into a follow-up config")
    p.add_argument("-o", "--output", help="with --config: write the follow-up config here")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.threshold is not None and not args.threshold > 0:
        raise InputError("--threshold: must be > 0")
    if not 1 <= args.max_per_interval <= 20:
        raise InputError("--max-per-interval: must be 1..20")
    if bool(args.config) != bool(args.output):
        raise InputError("--config and -o go together")
    table = read_points(args.file)
    proposal = propose(table, args.threshold, args.max_per_interval)
    written = None
    if args.config:
        config = load_config(args.config)
        if proposal.new:  # nothing to add: no follow-up config (it would repeat the campaign)
            text = follow_up_config(config.text, proposal.all_targets)
            parse_config(text, str(args.output))  # the follow-up config must be valid
            try:
                Path(args.output).write_text(text, encoding="utf-8")
            except OSError as exc:
                raise InputError(f"-o: {args.output}: cannot write ({exc.strerror})") from None
            written = str(args.output)
    unit = unit_label(table.deviation_unit)
    if args.json:
        print_json({"targets": proposal.targets, "new": proposal.new, "all": proposal.all_targets, "written": written,
                    "threshold": proposal.threshold, "unit": unit,
                    "intervals": [{"from": a, "to": b, "estimated_error": e, "new": n}
                                  for a, b, e, n in proposal.gaps]})
        return 0
    console = make_console()
    shown = Table(title=f"Interpolation error between targets (threshold {proposal.threshold:.3f} {unit})")
    for head in (f"from {table.position_unit}", f"to {table.position_unit}", f"estimated error {unit}", "new targets"):
        shown.add_column(head, justify="right")
    for a, b, e, n in proposal.gaps:
        shown.add_row(f"{a:g}", f"{b:g}", f"{e:.3f}", str(n) if n else "")
    console.print(shown)
    if proposal.new:
        console.print(f"{len(proposal.new)} new target(s): " + ", ".join(f"{t:g}" for t in proposal.new))
        if args.output:
            console.print(f"follow-up config written to {args.output} ({len(proposal.all_targets)} targets)")
    else:
        console.print("linear interpolation follows the mean deviation everywhere: no new targets"
                      + (f"; no follow-up config written ({args.output} not created)" if args.output else ""))
    return 0

"""`axiscal analyze FILE [--json] [--plot OUT] [--standard NAME]`: evaluate a point table."""

from __future__ import annotations

import sys

from campaign.commands import SUMMARY
from campaign.iso230 import evaluate, find_standard
from campaign.plot import check_plot_path, plot_evaluation
from campaign.pointtable import read_points
from campaign.views import print_evaluation, print_json


def register(sub) -> None:
    p = sub.add_parser("analyze", help=SUMMARY["analyze"],
                       description="Evaluate a point table (CSV) to ISO 230-2:2014, ISO 230-2:1988 or VDI/DGQ 3441.")
    p.add_argument("file", help="point table CSV (see docs/point-table.md)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    p.add_argument("--plot", metavar="OUT", help="write the deviation plot to OUT.png or OUT.svg")
    p.add_argument("--standard", default="ISO230-2:2014",
                   help="ISO230-2:2014 (default; aliases GB/T17421.2, JIS B 6190-2), ISO230-2:1988, VDI3441")
    p.set_defaults(func=run)


def run(args) -> int:
    standard = find_standard(args.standard)
    plot_path = check_plot_path(args.plot) if args.plot else None
    table = read_points(args.file)
    ev = evaluate(table, standard)
    if plot_path:
        plot_evaluation(table, ev, plot_path)
    if args.json:
        for warning in ev.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        print_json(ev.as_json())
    else:
        print_evaluation(ev)
        if plot_path:
            print(f"plot written to {plot_path}")
    return 0

"""`axiscal analyze DIR|FILE [--tolerance T] [--json] [--plot OUT] [--standard NAME]`: evaluate a
campaign or a point table to ISO 230-2, with its outliers, measurement uncertainty and verdict."""

from __future__ import annotations

import argparse
import sys

from campaign.commands import SUMMARY, positive_number


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("analyze", help=SUMMARY["analyze"],
                       description="Evaluate a campaign directory or a point table (CSV) to ISO 230-2:2014, "
                                   "ISO 230-2:1988 or VDI/DGQ 3441: the parameters, the outliers, the "
                                   "measurement uncertainty and the verdict. A campaign stopped early is "
                                   "evaluated as far as it goes.")
    p.add_argument("file", help="campaign directory, or point table CSV (see docs/point-table.md)")
    p.add_argument("--tolerance", type=positive_number, metavar="T",
                   help="tolerance on A, µm (arcsec on a rotary axis); default: the campaign's [campaign] tolerance")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    p.add_argument("--wide", action="store_true", help="the per-target statistics in one table, however wide")
    p.add_argument("--plot", metavar="OUT", help="write the deviation plot to OUT.png or OUT.svg")
    p.add_argument("--standard", default="ISO230-2:2014",
                   help="ISO230-2:2014 (default; aliases GB/T17421.2, JIS B 6190-2), ISO230-2:1988, VDI3441")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from campaign.assess import assess_path
    from campaign.iso230 import find_standard
    from campaign.plot import check_plot_path, plot_evaluation
    from campaign.views import make_console, print_assessment, print_json

    standard = find_standard(args.standard)
    plot_path = check_plot_path(args.plot) if args.plot else None
    a = assess_path(args.file, args.tolerance, standard)
    if plot_path:
        plot_evaluation(a.table, a.evaluation, plot_path)
    if args.json:
        for warning in a.evaluation.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        print_json(a.as_json())
    else:
        console = make_console()
        print_assessment(a, console, wide=args.wide)
        if plot_path:
            console.print(f"plot written to {plot_path}")
    return 0

"""`axiscal verify CONFIG --comp TABLE [--comp-format F] [--before DIR|POINTS] [--out DIR] ...`: measure again
with the compensation active and show the before and after."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.table import Table

from campaign.commands import SUMMARY, finite_number, hardware_opener, positive_number
from campaign.commands.run import add_run_options, finish, with_on_fault
from campaign.compensation.table_file import (
    read_comp_provenance,
    read_comp_table,
    table_identity,
    table_spikes,
    table_units_note,
)
from campaign.config import load_config
from campaign.errors import InputError
from campaign.measure import (
    SUMMARY_KEYS,
    RichProgress,
    baseline_points,
    default_out_dir,
    run_verification,
    table_fits,
    write_report,
)
from campaign.plan import build_plan, check_plan
from campaign.plot import check_plot_path
from campaign.views import fmt, make_console
from protocols.tables import FORMATS, FormatOptions


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("verify", help=SUMMARY["verify"],
                       description="Write the compensation table (any format `axiscal compensate` writes) "
                                   "into the PLC, run the campaign again and compare with the baseline.")
    p.add_argument("config", help="campaign TOML")
    p.add_argument("--comp", required=True, metavar="TABLE", help="table from axiscal compensate, any --format")
    p.add_argument("--comp-format", choices=FORMATS, help="the table's format (default: recognised from its text)")
    p.add_argument("--counts-per-unit", type=positive_number,
                   help="pmac and fanuc tables: encoder counts (detection units) per mm or degree")
    p.add_argument("--reference", type=finite_number, default=0.0,
                   help="fanuc tables: the reference position, mm or deg (default 0)")
    p.add_argument("--units", choices=("mm", "inch"),
                   help="a LinuxCNC table's unit: its machine's LINEAR_UNITS (default: mm, and said so)")
    p.add_argument("--before", metavar="DIR|POINTS.csv", help="the baseline campaign (before compensation)")
    p.add_argument("--max-rate", type=positive_number, metavar="UM_PER_S",
                   help="rate limit of the correction, µm/s (arcsec/s on a rotary axis)")
    p.add_argument("--max-accel", type=positive_number, metavar="UM_PER_S2",
                   help="acceleration limit of the correction, µm/s² (arcsec/s²)")
    p.add_argument("--force", action="store_true",
                   help="load a table made for another machine or axis, or for a much longer travel "
                        "(refused with exit 2 otherwise)")
    add_run_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    config = with_on_fault(config, args)
    options = FormatOptions(counts_per_unit=args.counts_per_unit, units=args.units or "mm")
    units_note = table_units_note(args.comp, args.comp_format, args.units)
    table = read_comp_table(args.comp, config.axis.kind, args.comp_format, options, args.reference)
    if args.plot:
        check_plot_path(args.plot)
    if table.kind != config.axis.kind:
        raise InputError(f"{args.comp}: a {table.kind} table does not fit the {config.axis.kind} axis")
    plan = build_plan(config)
    check_plan(plan, config.axis)
    baseline = Path(args.before) if args.before else None
    before = baseline_points(baseline, config) if baseline else None  # a wrong baseline is said first
    console = make_console(stderr=args.json)
    if units_note:
        console.print(f"note: {units_note}")
    for warning in [*table_fits(table, read_comp_provenance(args.comp), config, plan, args.comp, args.force),
                    *table_spikes(table, args.comp)]:
        console.print(f"[yellow]warning:[/] {warning}")
    out = Path(args.out) if args.out else default_out_dir(config)
    unit = config.axis.unit
    with RichProgress(unit) as observer:
        outcome = run_verification(config, table, out, opener=hardware_opener(), baseline=baseline if baseline and baseline.is_dir() else None,
                                   max_rate=args.max_rate, max_accel=args.max_accel, speed=args.speed,
                                   observer=observer, source=Path(args.comp),
                                   identity=table_identity(args.comp, args.comp_format))
    summaries = {}
    if outcome.points:
        from campaign.pointtable import read_points

        summaries = write_report(outcome.dir, read_points(outcome.dir / "points.csv"), before)
        if not args.json:
            shown = Table(title=f"Before and after compensation ({'µm' if unit == 'mm' else 'arcsec'})")
            shown.add_column("parameter")
            shown.add_column("meaning")
            for head in ("before", "after"):
                shown.add_column(head, justify="right")
            for key, name in SUMMARY_KEYS:
                b = summaries["before"].get(key) if summaries["before"] else None
                shown.add_row(key, name, fmt(b), fmt(summaries["after"].get(key)))
            console.print(shown)
            console.print(f"tables: {outcome.dir / 'verification.md'}; plot: {outcome.dir / 'verification.png'}")
    return finish(outcome, args, {"before": summaries.get("before")})

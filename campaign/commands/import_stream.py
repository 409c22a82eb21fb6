"""`axiscal import-stream STREAM.csv --config CONFIG -o POINTS.csv [--still-tolerance T]`: find the
dwells in another program's continuous log, match them to the plan and write the point table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from campaign.commands import SUMMARY, positive_number
from campaign.config import load_config
from campaign.errors import InputError
from campaign.plan import build_plan
from campaign.pointtable import PointTable, write_points
from campaign.stream.importer import extract_points
from campaign.stream.reader import read_stream
from protocols.units import unit_label


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("import-stream", help=SUMMARY["import-stream"],
                       description="Find the dwells in a continuous log (CSV with time_s and a reading), "
                                   "match them to the config's plan and write the point table.")
    p.add_argument("stream", help="CSV with time_s (s) and reading_mm / position_mm / reading / position "
                                  "(or _deg for a rotary axis); see docs/import-stream.md")
    p.add_argument("--config", required=True, help="the campaign config (TOML) the log was measured with")
    p.add_argument("-o", "--output", required=True, help="point table CSV to write")
    p.add_argument("--still-tolerance", type=positive_number, default=5.0, metavar="T",
                   help="band the reading stays in while the axis dwells, µm or arcsec (default 5); it "
                        "bounds the search for the dwells, not where they are captured")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if not args.still_tolerance > 0:
        raise InputError(f"--still-tolerance: must be a positive number, found {args.still_tolerance:g}")
    config = load_config(args.config)
    plan = build_plan(config)
    stream = read_stream(args.stream, config.axis.unit)
    result = extract_points(stream, plan, config, args.still_tolerance)
    out = Path(args.output)
    try:
        write_points(out, result.table)
    except OSError as exc:
        raise InputError(f"{out}: cannot write ({exc.strerror})") from None
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"{len(result.table)} points from {result.dwells} dwells in {args.stream} "
          f"(column '{stream.column}'); {result.overrun_stops} overrun stops skipped, "
          f"{result.ignored_stops} stops after the last point ignored")
    print(stillness_summary(result.table))
    print(f"point table written to {out}")
    return 0


def stillness_summary(table: PointTable) -> str:
    """One line on how still the capture windows were (docs/import-stream.md)."""
    unit, suffix = unit_label(table.deviation_unit), table.deviation_unit
    trend = table.optional[f"capture_trend_{suffix}"]
    still = int(np.sum(table.optional["capture_still"] == 1))
    worst = int(np.argmax(np.abs(trend)))
    noise = float(table.meta[f"reading_noise_{suffix}"])
    return (f"capture windows: {still} of {len(table)} still (no trend beyond the reading noise, "
            f"{noise:.2g} {unit}); largest trend {trend[worst]:+.2g} {unit} (point {worst + 1})")

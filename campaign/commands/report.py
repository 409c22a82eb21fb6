"""`axiscal report DIR [-o report.html] [--before DIR0]`: the self-contained HTML report of a campaign."""

from __future__ import annotations

from pathlib import Path

from campaign.commands import SUMMARY
from campaign.report.document import write_report


def register(sub) -> None:
    p = sub.add_parser("report", help=SUMMARY["report"],
                       description="Write a self-contained HTML report (plots embedded, works offline) of a "
                                   "campaign directory; with a baseline, before and after side by side.")
    p.add_argument("dir", help="campaign directory (config.toml, meta.json, points.csv)")
    p.add_argument("-o", "--output", help="HTML file to write (default DIR/report.html)")
    p.add_argument("--before", metavar="DIR0",
                   help="baseline campaign to compare with (default: meta.json's baseline_dir, if set)")
    p.set_defaults(func=run)


def run(args) -> int:
    out = Path(args.output) if args.output else Path(args.dir) / "report.html"
    path = write_report(args.dir, out, args.before)
    print(f"report written to {path}")
    return 0

"""`axiscal report DIR [-o report.html] [--before DIR0] [--pdf FILE]`: the self-contained HTML report of a campaign."""

from __future__ import annotations

import argparse
from pathlib import Path

from campaign.commands import SUMMARY, positive_number


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("report", help=SUMMARY["report"],
                       description="Write a self-contained HTML report (plots embedded, works offline) of a "
                                   "campaign directory or of a point table; with a baseline, before and after side by side.")
    p.add_argument("dir", help="campaign directory (config.toml, meta.json, points.csv), or a point table CSV")
    p.add_argument("-o", "--output", help="HTML file to write (default DIR/report.html, or beside the table)")
    p.add_argument("--tolerance", type=positive_number, metavar="T",
                   help="tolerance on A, µm (arcsec on a rotary axis); default: the campaign's [campaign] tolerance")
    p.add_argument("--before", metavar="DIR0",
                   help="baseline campaign to compare with (default: meta.json's baseline_dir, if set)")
    p.add_argument("--pdf", metavar="FILE",
                   help="also print the report to a PDF (A4, page numbers and the campaign id on every page; "
                        "needs headless Chromium)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from campaign.report.document import write_report

    source = Path(args.dir)
    out = Path(args.output) if args.output else (source / "report.html" if source.is_dir()
                                                  else source.with_suffix(".html"))
    path = write_report(args.dir, out, args.before, args.tolerance)
    print(f"report written to {path}")
    if args.pdf:
        from campaign.report.pdf import print_pdf

        print(f"PDF written to {print_pdf(path, Path(args.pdf))}")
    return 0

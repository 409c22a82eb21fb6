"""`axiscal convert IN -o OUT [--from F] [--to F] [--kind linear|rotary] [--json]`: another
program's measurement file to a point table, or back (Renishaw .rtl, ecmc *_ISO230.dat)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from campaign.assess import campaign_dir_of, completeness
from campaign.commands import SUMMARY
from campaign.convert import FORMATS, format_of, read_any, render_any, write_whole
from campaign.errors import InputError
from campaign.iso230 import evaluate
from campaign.pointtable import PointTable
from campaign.views import make_console, print_json
from protocols.units import counted, unit_label


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("convert", help=SUMMARY["convert"],
                       description="Read a measurement file (point table, Renishaw .rtl, ecmc ISO 230-2 .dat) "
                                   "and write it in another of these formats; see docs/convert.md.")
    p.add_argument("input", help="the file to read (.csv point table, .rtl, .dat)")
    p.add_argument("-o", "--output", required=True, help="the file to write (.csv, .rtl, .dat)")
    p.add_argument("--from", dest="source_format", choices=FORMATS, help="the input's format (default: its extension)")
    p.add_argument("--to", dest="target_format", choices=FORMATS, help="the output's format (default: its extension)")
    p.add_argument("--kind", choices=("linear", "rotary"),
                   help="the axis kind when the input does not say (.rtl: default linear)")
    p.add_argument("--json", action="store_true", help="print what was converted as JSON")
    p.set_defaults(func=run)


def campaign_started(path: str) -> str:
    """The day (YYYY-MM-DD) the campaign a point table comes from was started (its directory's
    meta.json `created`); "" for a bare table or a directory that does not say."""
    from campaign.record import open_campaign

    directory = campaign_dir_of(path)
    if directory is None:
        return ""
    try:
        return str(open_campaign(directory).meta.get("created", ""))[:10]
    except (InputError, OSError, ValueError):
        return ""


def what_the_output_loses(args: argparse.Namespace, table: PointTable, source: str, target: str
                          ) -> tuple[list[str], str | None]:
    """(what the output format has no place for, and when the verdict of the output read back
    alone differs from the input's: a sentence saying both verdicts and why, else None). The
    input is judged as `analyze` judges it (a campaign's points.csv with its campaign's config and
    tolerance), the output as the bare file it is."""
    from campaign.assess import assess, assess_path
    from campaign.convert import not_carried

    lost = not_carried(table, target)
    try:  # a campaign's points.csv is judged with its campaign; a directory that cannot say, as a bare table
        before = assess_path(args.input) if source == "points" else assess(table, source=str(args.input))
    except InputError:
        before = assess(table, source=str(args.input))
    after = assess(read_any(args.output, target, table.kind), source=str(args.output))
    if before.config is not None and before.tolerances.get("A"):
        lost.append(f"the campaign's tolerance on A ({before.tolerances['A']:g} {unit_label(table.deviation_unit)}, "
                    "in its config, not in the table: give analyze --tolerance)")
    if before.verdict.verdict == after.verdict.verdict:
        return lost, None
    why = "; ".join(after.verdict.reasons)
    return lost, (f"the verdict changes: {before.verdict.word} for {args.input}, {after.verdict.word} for "
                  f"{args.output} alone ({why})")


def run(args: argparse.Namespace) -> int:
    source, target = format_of(args.input, args.source_format), format_of(args.output, args.target_format)
    if Path(args.input).resolve() == Path(args.output).resolve():
        raise InputError(f"{args.output}: the output would overwrite the input")
    table = read_any(args.input, source, args.kind)
    undated = "date" not in table.meta
    if undated:
        measured = campaign_started(args.input)
        if measured:
            table = dataclasses.replace(table, meta={**table.meta, "date": measured})
            undated = False
    text = render_any(table, target)
    write_whole(args.output, text)
    from campaign.commands.history import record_after

    record_after(args.input, "convert", source)
    values = evaluate(table).summary
    missing = completeness(table, None)
    lost, changed = what_the_output_loses(args, table, source, target)
    summary = {"input": str(args.input), "from": source, "output": str(args.output), "to": target,
               "kind": table.kind, "points": len(table), "runs": int(table.run.max()),
               "targets": len(set(table.target.tolist())), "meta": table.meta,
               "missing": missing, "not_carried": lost, "verdict_change": changed,
               **{k: values.get(k) for k in ("A", "B", "R", "E", "M")},
               **{k: v for k, v in values.items() if k.endswith(("_up", "_down")) and v is not None}}
    if args.json:
        print_json(summary)
    else:
        unit = "µm" if table.kind == "linear" else "arcsec"
        keys = ("A", "B", "R") if values.get("A") is not None else ("A_up", "R_up", "A_down", "R_down")
        shown = ", ".join(f"{k.replace('_up', '↑').replace('_down', '↓')} {values[k]:.3f} {unit}"
                          for k in keys if values.get(k) is not None) or "no value (too few runs)"
        make_console().print(f"{args.output}: {len(table)} points, {counted(int(table.run.max()), 'run')}, {summary['targets']} "
                             f"targets ({source} → {target}); ISO 230-2: {shown}")
        if undated and target == "rtl":
            make_console().print(f"[yellow]warning:[/] {args.input}: no measurement date (no `# date:` comment and "
                                 "no campaign directory): the .rtl says 'Date: not recorded'")
        if lost:
            make_console().print(f"[yellow]note:[/] not carried by {target}: {'; '.join(lost)}", markup=True,
                                 highlight=False)
        if changed:
            make_console().print(f"[yellow]warning:[/] {changed}", highlight=False)
        for problem in missing:
            make_console().print(f"[yellow]warning:[/] {args.input}: incomplete: {problem}; the values above are "
                                 "from the points there are, and a verdict on them is not judged")
    return 0

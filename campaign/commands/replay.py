"""`axiscal replay DIR [--speed N] [--capture dwell|stable] [capture options] [--json]`."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from campaign import capture_methods
from campaign.commands import SUMMARY, positive_number
from campaign.config import Config
from campaign.errors import InputError
from campaign.iso230 import evaluate
from campaign.measure import ScanSettings, analyse_recorded_scan, replay_campaign, settings_of
from campaign.plan import Plan, check_scan_window
from campaign.pointtable import PointTable
from campaign.record import open_campaign, read_recorded_points
from campaign.views import fmt, make_console, print_json
from protocols.units import unit_label

DIGITS = 4
"""The point table records deviations to 1e-4 µm (arcsec): 'identical' means equal at that."""


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("replay", help=SUMMARY["replay"],
                       description="Replay DIR's raw stream through the capture and analysis code. With the "
                                   "recorded settings it reproduces the point table; with others it shows "
                                   "what would change.")
    p.add_argument("dir", help="campaign directory")
    p.add_argument("--speed", type=positive_number, metavar="N", help="pace the timeline at N times real time")
    p.add_argument("--capture", choices=capture_methods.names(live=True, sweeps=False),
                   help="capture method (default: as recorded)")
    p.add_argument("--average-s", type=positive_number, help="dwell: averaging window, s")
    p.add_argument("--stable-tolerance", type=positive_number, help="stable: band, µm (arcsec)")
    p.add_argument("--stable-drift", type=positive_number, help="stable: drift between the window's halves, µm (arcsec)")
    p.add_argument("--stable-window-s", type=positive_number, help="stable: window, s")
    p.add_argument("--stable-timeout-s", type=positive_number, help="stable: timeout after arrival, s")
    p.add_argument("--scan-window", type=positive_number, metavar="W",
                   help="scan: the stretch about each target a line is fitted through, axis unit")
    p.add_argument("--wanted-u", type=positive_number, help="scan: wanted timing uncertainty per target and pass, µm (arcsec)")
    p.add_argument("--moving", action="store_true",
                   help="scan: keep the deviation on the move (do not refer it to the rests at the ends)")
    p.add_argument("--offset-only", action="store_true",
                   help="scan: align the clocks by their offset only (as if they ran at the same rate)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.set_defaults(func=run)


def _overrides(args: argparse.Namespace) -> dict:
    out = {"method": args.capture} if args.capture else {}
    for key in ("average_s", "stable_tolerance", "stable_drift", "stable_window_s", "stable_timeout_s"):
        if getattr(args, key) is not None:
            out[key] = getattr(args, key)
    return out


def check_window(directory: Path, overrides: dict) -> None:
    """Each setting given must be one the replay's capture method reads (an --average-s on a stable
    capture changed nothing and said it reproduced the table), and a dwell capture averages within
    the dwell: an --average-s longer than the recorded dwell would silently average less than asked
    (the capture takes at most the dwell). InputError."""
    from campaign.record import open_campaign

    config = open_campaign(directory).config()
    method = overrides.get("method", config.capture.method)
    unread = [key for key in overrides if key != "method" and key not in capture_methods.method(method).options]
    if unread:
        options = ", ".join(f"--{key.replace('_', '-')}" for key in unread)
        raise InputError(f"{options}: not read by the {method} capture this replay uses ({directory}); give "
                         "--capture with the method that reads it")
    average = overrides.get("average_s")
    if average is None:
        return
    dwell = config.plan.dwell_s
    if capture_methods.method(method).fixed_dwell and average > dwell:
        raise InputError(f"--average-s {average:g}: longer than the recorded dwell of {dwell:g} s at each point "
                         f"({directory}): a dwell capture averages within the dwell (at most --average-s {dwell:g})")


def replay_scan(args: argparse.Namespace, directory: Path, config: Config, plan: Plan, recorded: PointTable) -> int:
    """A scan: its recorded streams aligned and tabulated again, with its settings (the table is
    reproduced) or others (--scan-window, --wanted-u, --moving)."""
    if args.capture or any(getattr(args, k) is not None for k in ("average_s", "stable_tolerance", "stable_drift",
                                                                   "stable_window_s", "stable_timeout_s")):
        raise InputError(f"{directory}: a scan is replayed with --scan-window, --wanted-u, --moving and --offset-only, not with "
                         "the options of a capture at rest")
    if args.scan_window is not None:  # as the config's window is checked: against the recorded plan's targets
        check_scan_window(args.scan_window, plan, config, "--scan-window")
    own = settings_of(config)
    settings = ScanSettings(args.scan_window or own.window, args.wanted_u or own.wanted_u, not args.moving,
                            not args.offset_only)
    got = analyse_recorded_scan(directory, config, plan, settings).table
    old = {(int(r), int(d), f"{t:.6f}"): float(v) for r, d, t, v in
           zip(recorded.run, recorded.direction, recorded.target, recorded.deviation)}
    new = {(int(r), int(d), f"{t:.6f}"): float(v) for r, d, t, v in
           zip(got.run, got.direction, got.target, got.deviation)}
    diffs: list[dict[str, Any]] = [{"run": k[0], "direction": "+" if k[1] > 0 else "-", "target": float(k[2]), "recorded": old.get(k),
              "replayed": new.get(k),
              "difference": None if k not in old or k not in new else round(new[k] - old[k], DIGITS)}
             for k in sorted(set(old) | set(new))
             if k not in old or k not in new or f"{old[k]:.{DIGITS}f}" != f"{new[k]:.{DIGITS}f}"]
    old_summary, new_summary = evaluate(recorded).summary, evaluate(got).summary
    meta = {k: v for k, v in got.meta.items()
            if k.startswith(("clock", "timing", "speed", "deviation", "warning", "left_out", "segments"))}
    result: dict[str, Any] = {"dir": str(directory), "capture": capture_methods.SCAN.name, "points": len(got), "recorded_points": len(recorded),
              "window": settings.window, "wanted_u": settings.wanted_u, "rest_reference": settings.rest_reference,
              "rate": settings.rate,
              "identical": not diffs, "differences": diffs, "summary_recorded": old_summary,
              "summary_replayed": new_summary, "meta": meta}
    if args.json:
        print_json(result)
        return 0
    console = make_console()
    for key, value in meta.items():
        console.print(f"{key}: {value}", markup=False, highlight=False)
    if not diffs:
        console.print(f"replay of the scan reproduces the recorded point table: {len(got)}/{len(recorded)} "
                      f"values identical to {DIGITS} decimals")
    else:
        console.print(f"{len(diffs)} of {len(recorded)} values change (window {settings.window:g}, "
                      f"{'at rest' if settings.rest_reference else 'on the move'}); largest "
                      f"{max(abs(d['difference'] or 0.0) for d in diffs):.4f} {unit_label(recorded.deviation_unit)}")
    print_summaries(console, f"ISO 230-2 summary ({unit_label(recorded.deviation_unit)}), indicative: a scan",
                    old_summary, new_summary)
    return 0


def run(args: argparse.Namespace) -> int:
    overrides = _overrides(args)
    directory = Path(args.dir)
    if not (directory / "meta.json").is_file():
        raise InputError(f"{directory}: not a campaign directory (no meta.json)")
    recorded = read_recorded_points(directory, partial=False)
    campaign = open_campaign(directory)
    config = campaign.config()
    plan = campaign.plan_for(config)
    if plan.sweeps:
        return replay_scan(args, directory, config, plan, recorded)
    if args.scan_window or args.wanted_u or args.moving or args.offset_only:
        raise InputError(f"{directory}: not a scan: --scan-window, --wanted-u, --moving and --offset-only replay a scan")
    check_window(directory, overrides)
    capture, _, points = replay_campaign(directory, overrides, args.speed)
    if "point" not in recorded.extra:
        raise InputError(f"{directory / 'points.csv'}: no 'point' column: not recorded by axiscal")
    rec_dev = {int(i): float(d) for i, d in zip(recorded.extra["point"], recorded.deviation)}
    diffs: list[dict[str, Any]] = []
    for p in points:
        before = rec_dev.get(p.index)
        same = before is not None and p.deviation is not None and \
            f"{before:.{DIGITS}f}" == f"{p.deviation:.{DIGITS}f}"
        if not same and (before is not None or p.deviation is not None):
            diffs.append({"point": p.index, "run": p.run, "direction": "+" if p.direction > 0 else "-",
                          "target": p.target, "recorded": before, "replayed": p.deviation,
                          "difference": None if before is None or p.deviation is None else p.deviation - before,
                          "wait_s": p.wait_s, "note": p.reason})
    got = [p for p in points if p.deviation is not None]
    new = PointTable(recorded.kind, np.array([p.run for p in got]), np.array([p.direction for p in got]),
                     np.array([p.target for p in got]),
                     np.array([round(d, DIGITS) for d in (p.deviation for p in got) if d is not None]))
    new_summary = evaluate(new).summary if got else {}
    old_summary = evaluate(recorded).summary
    result = {"dir": str(directory), "capture": capture.method, "points": len(got),
              "recorded_points": len(recorded), "identical": not diffs, "differences": diffs,
              "summary_recorded": old_summary, "summary_replayed": new_summary}
    if args.json:
        print_json(result)
        return 0
    console = make_console()
    if not diffs:
        console.print(f"replay with {capture.method} capture reproduces the recorded point table: "
                      f"{len(got)}/{len(recorded)} points identical to {DIGITS} decimals")
    else:
        table = Table(title=f"{len(diffs)} point(s) change with {capture.method} capture")
        for head in ("point", "run", "dir", "target", "recorded", "replayed", "difference", "wait s", "note"):
            table.add_column(head, justify="right")
        for d in diffs:
            table.add_row(str(d["point"]), str(d["run"]), d["direction"], f"{d['target']:g}", fmt(d["recorded"]),
                          fmt(d["replayed"]), fmt(d["difference"]), fmt(d["wait_s"], 2), d["note"])
        console.print(table)
    print_summaries(console, f"ISO 230-2 summary ({unit_label(recorded.deviation_unit)})", old_summary, new_summary)
    return 0


def print_summaries(console: Console, title: str, recorded: Mapping[str, Any], replayed: Mapping[str, Any]) -> None:
    """The recorded and the replayed ISO 230-2 parameters side by side."""
    summary = Table(title=title)
    for head in ("parameter", "recorded", "replayed"):
        summary.add_column(head, justify="right")
    for key in ("A", "E", "M", "B", "R"):
        summary.add_row(key, fmt(recorded.get(key)), fmt(replayed.get(key)))
    console.print(summary)

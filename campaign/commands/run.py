"""`axiscal run CONFIG [--out DIR] [--speed N] [--json] [--plot OUT]`: run a campaign."""

from __future__ import annotations

import argparse
from pathlib import Path

from campaign import capture_methods
from campaign.commands import SUMMARY, YES_HELP, hardware_opener, positive_number, stop_leftover_controller
from campaign.config import Config, config_with, load_config
from campaign.errors import InputError
from campaign.measure import Opener, Outcome, RichProgress, dry_run, start_campaign
from campaign.plot import check_plot_path, plot_evaluation
from campaign.record import open_campaign, scan_results_written
from campaign.views import make_console, print_evaluation, print_json
from protocols.hardware import AxisError, InstrumentError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("run", help=SUMMARY["run"],
                       description="Run the campaign of CONFIG, record it, then print the ISO 230-2 summary.")
    p.add_argument("config", help="campaign TOML (see docs/config.md)")
    add_run_options(p)
    p.add_argument("--dry-run", action="store_true",
                   help="talk to the controller read-only, walk the plan, command nothing "
                        "(also when axis_driver.read_only = true)")
    p.add_argument("--yes", action="store_true", help=YES_HELP)
    p.set_defaults(func=run)


def add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", metavar="DIR", help="campaign directory (default runs/MACHINE-AXIS-TIME)")
    p.add_argument("--speed", type=positive_number, metavar="N",
                   help="simulated machine: N times real time (default: as fast as possible)")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--plot", metavar="OUT", help="write the ISO 230-2 plot (.png or .svg)")
    add_on_fault_option(p)


def add_on_fault_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--on-fault", choices=("retry", "skip", "abort"),
                   help="after a fault: retry the point (up to [campaign] fault_retries times), skip it "
                        "(`axiscal resume` measures it later) or stop (default: the config's [campaign] on_fault)")


def with_on_fault(config: Config, args: argparse.Namespace) -> Config:
    """The config with --on-fault in place of its [campaign] on_fault (validated again)."""
    if getattr(args, "on_fault", None):
        return config_with(config, {"campaign": {"on_fault": args.on_fault}})
    return config


def finish(outcome: Outcome, args: argparse.Namespace, extra: dict | None = None) -> int:
    """Print the outcome (`print_outcome`), then record the campaign into the history store: the
    user sees the verdict first, whatever the store does. Exit 0 when completed (points skipped
    after faults included), 3 when interrupted."""
    from campaign.commands.history import record_after

    code = print_outcome(outcome, args, extra)
    record_after(outcome.dir, getattr(args, "command", None) or "run")
    return code


def print_outcome(outcome: Outcome, args: argparse.Namespace, extra: dict | None = None) -> int:
    """The ISO 230-2 summary so far, the outliers and the verdict (campaign/assess.py, the same as
    `analyze`, `report` and the guide), and the resume hint when points are missing; the exit status."""
    from campaign.assess import assess_path
    from campaign.views import outlier_lines, verdict_line

    result = {"dir": str(outcome.dir), "status": outcome.status, "points": outcome.points,
              "planned": outcome.planned, "duration_s": round(outcome.duration_s, 3), **(extra or {})}
    # a scan's points.csv is its table, written only once every pass is recorded (its sweeps are not points)
    plot_error = None
    scan = is_scan(outcome.dir)
    unfinished_scan = scan and not scan_results_written(outcome.dir)
    a = assess_path(outcome.dir) if outcome.points and not unfinished_scan else None
    if a is not None:
        ev = a.evaluation
        result.update(ev.summary)
        result.update(unit=ev.unit, verdict=a.verdict.verdict, reasons=a.verdict.reasons,
                      uncertainty=a.uncertainty.as_json(), outliers=[o.as_dict() for o in a.outliers.found])
        if args.plot:
            try:  # checked before the campaign; a disk that fails now must not lose its result
                plot_evaluation(a.table, ev, args.plot, title=f"{outcome.dir}")
            except OSError as exc:
                plot_error = f"{args.plot}: {exc.strerror or exc}"
                result["plot_error"] = plot_error
    else:
        result.update(verdict="not judged", reasons=["no point was recorded"])
    missing = outcome.planned - outcome.points
    if args.json:
        print_json(result)
        return 0 if outcome.status == "completed" else 3
    console = make_console()
    if a is not None:
        print_evaluation(a.evaluation, console, per_target=False)
        for line in outlier_lines(a.outliers, a.evaluation.unit):
            console.print(line, markup=False)
        console.print(verdict_line(a.verdict))
    counted_as = "sweeps" if scan else "points"
    console.print(f"campaign {outcome.status}: {outcome.points}/{outcome.planned} {counted_as} in "
                  f"{outcome.duration_s / 60:.1f} min (campaign time), recorded in {outcome.dir}")
    if outcome.status != "completed":
        console.print(f"[red]stopped:[/] {outcome.message}. Continue with: axiscal resume {outcome.dir}")
    elif missing:
        console.print(f"[yellow]{missing} {counted_as[:-1]}(s) skipped after faults[/]: measure them with: "
                      f"axiscal resume {outcome.dir}")
    if plot_error is not None:
        console.print(f"[yellow]warning:[/] the plot was not written ({plot_error})", markup=True)
    elif args.plot and a is not None:
        console.print(f"plot written to {args.plot}")
    return 0 if outcome.status == "completed" else 3


def is_scan(directory: Path) -> bool:
    """The campaign recorded in `directory` is a scan (its capture method sweeps): its points are sweeps."""
    return open_campaign(directory).meta.get("capture") in capture_methods.names(sweeps=True)


def run_config(config: Config, args: argparse.Namespace, extra: dict | None = None, opener: Opener | None = None,
               meta_extra: dict | None = None, durable: bool = True) -> int:
    """Run `config` on the machine `opener` opens (default: the one its [axis_driver] names),
    with `meta_extra` in meta.json; print the outcome. `durable` False: the recording is not
    fsynced per point (the fake machine's demo only)."""
    config = with_on_fault(config, args)
    if args.plot:
        check_plot_path(args.plot)
    stop_leftover_controller(config.driver, getattr(args, "yes", False))
    unit = config.axis.unit
    observer = RichProgress(unit)
    with observer:
        outcome = start_campaign(config, args.out, meta_extra, opener=opener or hardware_opener(), speed=args.speed,
                                 observer=observer, durable=durable)
    return finish(outcome, args, extra)


def dry_run_lines(report: dict, unit: str) -> list[str]:
    """What a dry run found, for people: each value rounded and with its unit."""
    yes = {True: "yes", False: "NO"}
    reading = report["reading"]
    error_id = int(report["axis_error_id"])
    error = f"ERROR: controller error id {error_id} (0x{error_id:04X})" if report["axis_error"] else "no error"
    return [(f"controller   read-only; axis enabled {yes[report['axis_enabled']]}, homed {yes[report['axis_homed']]}, "
            f"{error}, at {report['axis_position']:.4f} {unit}"),
            f"instrument   {report['readings']} readings, beam {'OK' if report['beam_ok'] else 'NOT OK'}"
            + (f", last reading {reading:.4f} {unit}" if reading is not None else ", no reading"),
            (f"plan         {report['points']} points, {report['moves']} moves, travel {report['travel']:.1f} {unit}, "
            f"estimated duration {report['estimated_duration_s'] / 60:.1f} min, within the soft limits")]


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    if args.dry_run or config.controller.read_only:
        try:
            report = dry_run(config, hardware_opener())
        except (AxisError, InstrumentError) as exc:  # a dry run changes nothing: a set-up problem, exit 2
            raise InputError(f"dry run: {exc}") from None
        report = {**report, "travel": round(report["travel"], 6),
                  "estimated_duration_s": round(report["estimated_duration_s"], 1)}
        if args.json:
            print_json(report)
        else:
            console = make_console()
            for line in dry_run_lines(report, config.axis.unit):
                console.print(line, markup=False, highlight=False)
            console.print("dry run: nothing was commanded")
        return 0
    return run_config(config, args)

"""`axiscal resume DIR [--yes] [--speed N] [--on-fault ...] [--json] [--plot OUT]`: continue an
interrupted campaign: the points it left out, those skipped after a fault included.

On a terminal it is the guided session of `axiscal guide`: the checklist (the controller, the
laser's signal and its datum against the one recorded at the stop, the environment, the limits,
the re-approach), a confirmation, the dashboard with its keys, the verdict. With --yes, or without
a terminal, it runs as a script with progress bars.
"""

from __future__ import annotations

import argparse
import sys

from campaign.commands import SUMMARY, hardware_opener, positive_number, stop_leftover_controller
from campaign.commands.run import add_on_fault_option, finish, with_on_fault
from campaign.measure import Resumption


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("resume", help=SUMMARY["resume"],
                       description="Continue the campaign in DIR: measure the points it left out (skipped "
                                   "after a fault, or not reached), each re-approached from the overrun in "
                                   "its own direction, appending to the same directory with its recorded plan. "
                                   "On a terminal: the guided checklist, a confirmation and the dashboard.")
    p.add_argument("dir", help="campaign directory")
    p.add_argument("--yes", action="store_true", help="no checklist or question: run as a script")
    p.add_argument("--speed", type=positive_number, metavar="N", help="simulated machine: N times real time")
    add_on_fault_option(p)
    p.add_argument("--json", action="store_true", help="print one JSON object at the end")
    p.add_argument("--plot", metavar="OUT", help="write the ISO 230-2 plot (.png or .svg)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from campaign.measure import continue_campaign, prepare_resume
    from campaign.plot import check_plot_path

    if args.plot:
        check_plot_path(args.plot)
    r = prepare_resume(args.dir)
    r.config = with_on_fault(r.config, args)
    if r.todo:  # a LinuxCNC the interrupted run started and left (it was killed): stopped when agreed or --yes
        try:
            stop_leftover_controller(r.config.driver, args.yes)
        except BaseException:
            r.close()
            raise
    if not args.yes and sys.stdin.isatty() and r.todo:
        return guided(r, args)
    from campaign.measure import RichProgress

    if not r.todo:
        return finish(continue_campaign(r), args)
    try:
        opened = r.open(hardware_opener(), args.speed)
    except BaseException:
        r.close()
        raise
    with RichProgress(r.config.axis.unit) as observer:
        outcome = continue_campaign(r, opened=opened, speed=args.speed, observer=observer)
    return finish(outcome, args)


def guided(r: Resumption, args: argparse.Namespace) -> int:
    """The guided resume: checklist, confirmation, dashboard, verdict (campaign/commands/guide.py)."""
    from rich.console import Console

    from campaign.commands.guide import (
        Setup,
        conclude,
        confirm,
        ctrl_c_held,
        on_dashboard,
        open_and_check,
        sigint_restored,
    )
    from campaign.guide import datum_item, reapproach_item, soft_limit_item
    from campaign.measure import continue_campaign
    from campaign.record import last_reading_offset
    from campaign.views import make_console

    console = Console(stderr=True) if args.json else make_console()
    config, plan = r.config, r.plan
    c = config.campaign
    console.print(f"[bold]axiscal resume[/]: {r.path}: machine {c.machine}, axis {config.axis.name}; "
                  f"{len(r.todo)} of {len(plan.points)} points to measure")
    offline = [soft_limit_item(plan, config), reapproach_item(plan, config, r.todo, r.again)]
    recorded_offset = last_reading_offset(r.path, plan)
    try:
        setup = Setup(config, plan, offline, lambda: r.open(hardware_opener(), args.speed))
        opened, _ = open_and_check(lambda: setup, console, True,
                                   more_items=lambda hw: [datum_item(hw, config, recorded_offset)])
    except BaseException:
        r.close()
        raise
    with sigint_restored():
        try:
            point = plan.points[r.todo[0]]
            start = point.target - point.direction * config.plan.overrun
            unit = config.axis.unit
            confirm(args, console, True, f"to the overrun at {start:g} {unit}, then {len(r.todo)} points")
            outcome = on_dashboard(config, plan, args, opened, console, True, r.path,
                                   lambda dashboard, control: continue_campaign(r, opened=opened, speed=args.speed,
                                                                                observer=dashboard, control=control),
                                   then=ctrl_c_held(console))
        except BaseException:
            r.close()  # not continued: the recorder is still ours (continue_campaign closes it otherwise)
            raise
        finally:
            opened[0].close()
        return conclude(outcome, config, args, console)

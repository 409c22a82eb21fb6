"""`axiscal guide [CONFIG] [--out DIR] [--speed N] [--yes] [--on-fault retry|skip|abort] [--json]`.

The guided session for a technician: a setup checklist, a confirmation before the axis moves, the
laser alignment check, the campaign on a live dashboard with keys, a prompt on faults, and at the
end the ISO 230-2 summary with pass or fail and the next steps. Without CONFIG: the embedded demo
on the simulated machine. For scripts every prompt has a flag (--yes, --on-fault); a failed check
ends with exit status 2 and one `error:` line. See docs/guide.md.
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any, NoReturn

from rich.console import Console

from campaign.commands import SUMMARY, hardware_opener, positive_number
from campaign.commands.demo import demo_config_text
from campaign.commands.run import with_on_fault
from campaign.config import Config, config_with, load_config, parse_config
from campaign.errors import BAD_INPUT, InputError
from campaign.guide import (
    CheckItem,
    CtrlC,
    Dashboard,
    Keys,
    alignment_item,
    checklist_table,
    failures,
    hardware_items,
    plan_preview,
    record_item,
    soft_limit_item,
)
from campaign.measure import (
    Control,
    Opened,
    Outcome,
    default_out_dir,
    start_campaign,
)
from campaign.plan import Plan, build_plan
from campaign.record import open_campaign, recorded_point_indices
from campaign.views import make_console, print_json, summary_table
from protocols.hardware import AxisError, Hardware, InstrumentError
from protocols.tables import FORMATS

COMPENSATE_FORMATS = ", ".join(FORMATS)
"""What `axiscal compensate --format` takes, for the next-step hint."""


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("guide", help=SUMMARY["guide"],
                       description="Check the set-up, ask before moving, run the campaign on a live "
                                   "dashboard (keys: p pause, r resume, a abort) and judge the result.")
    p.add_argument("config", nargs="?", help="campaign TOML (default: the embedded demo, simulated machine)")
    p.add_argument("--out", metavar="DIR", help="campaign directory (default runs/MACHINE-AXIS-TIME)")
    p.add_argument("--speed", type=positive_number, metavar="N", help="simulated machine: N times real time")
    p.add_argument("--yes", action="store_true", help="start the motion without asking (scripts)")
    p.add_argument("--on-fault", choices=("retry", "skip", "abort"),
                   help="answer every fault without asking; retry at most campaign.fault_retries times per "
                        "point (default: ask on a terminal, else the config's [campaign] on_fault)")
    p.add_argument("--operator", metavar="NAME", help="the operator's name (default: the config's; asked on a "
                                                     "terminal when it has none)")
    p.add_argument("--json", action="store_true", help="print one JSON object at the end (the rest to stderr)")
    p.set_defaults(func=run)


@dataclass(frozen=True)
class Setup:
    """What one setup check checks: the config as read now, its plan, the checks that need no
    hardware, and how to open the hardware it names."""

    config: Config
    plan: Plan
    offline: list[CheckItem]
    open: Callable[[], Opened]


def run(args: argparse.Namespace, on_hardware: Callable[[Hardware, Any], None] | None = None) -> int:
    """The whole session. `on_hardware(hw, sim)`: called right after the hardware is opened (tests
    use it to inject faults into the simulated machine)."""
    interactive = sys.stdin.isatty()
    console = Console(stderr=True) if args.json else make_console()
    operator: list[str] = []  # asked once, kept when the config is read again

    def prepare() -> Setup:
        """Read the config (again: each re-check sees the file as it is now), plan, offline checks."""
        config = load_config(args.config) if args.config else parse_config(demo_config_text(), "demo.toml")
        config = with_on_fault(config, args)  # --on-fault answers every fault: the executor's one policy
        if args.operator:
            config = config_with(config, {"campaign": {"operator": args.operator}})
        elif not config.campaign.operator and interactive:
            if not operator:
                operator.append(ask_operator(console))
            config = config_with(config, {"campaign": {"operator": operator[0]}})
        plan = build_plan(config)
        out = Path(args.out) if args.out else default_out_dir(config)
        return Setup(config, plan, [soft_limit_item(plan, config), record_item(out)],
                     lambda: hardware_opener()(config.driver, speed=args.speed))

    setup = prepare()
    introduce(setup, args, console)
    if failures(setup.offline) and not interactive:
        console.print(checklist_table(setup.offline))
        stop_on(failures(setup.offline)[0])
    opened, setup = open_and_check(prepare, console, interactive, on_hardware, first=setup,
                                   on_change=lambda changed: introduce(changed, args, console))
    config, plan = setup.config, setup.plan
    out = Path(args.out) if args.out else default_out_dir(config)
    with sigint_restored():
        try:
            lo, hi = plan.ends()
            unit = config.axis.unit
            confirm(args, console, interactive, f"alignment check to {hi:g} {unit} and back to {lo:g} {unit}, "
                                                f"then the campaign ({len(plan.points)} points)")
            outcome = on_dashboard(config, plan, args, opened, console, interactive, out,
                                   lambda dashboard, control: start_campaign(config, out, speed=args.speed,
                                                                             observer=dashboard, control=control,
                                                                             opened=opened),
                                   before=lambda control, keys: check_alignment(opened[0], plan, config, control,
                                                                               console, keys),
                                   then=ctrl_c_held(console))
        finally:
            opened[0].close()
        return conclude(outcome, config, args, console)


@contextmanager
def sigint_restored() -> Iterator[None]:
    """The SIGINT handler as it was, put back at the end (the dashboard's CtrlC leaves ctrl_c_held in place
    for the summary)."""
    original = signal.getsignal(signal.SIGINT)
    try:
        yield
    finally:
        if original is not None:
            signal.signal(signal.SIGINT, original)


def ctrl_c_held(console: Console) -> Callable[[int, FrameType | None], None]:
    """The SIGINT handler from the moment the campaign stops (the dashboard's CtrlC leaves it in place)
    until the summary is written: a Ctrl-C (one pressed too many while stopping) is said and ignored, so
    the summary and the resume line always come; the guide restores the handler before it after that."""
    def held(signum: int, frame: FrameType | None) -> None:
        console.print("Ctrl-C: the campaign has stopped and its record is closed; the summary follows.",
                      markup=False)
    return held


def introduce(setup: Setup, args: argparse.Namespace, console: Console) -> None:
    """The session's header and the plan preview (again when a re-check read a changed config)."""
    config = setup.config
    c = config.campaign
    console.print(f"[bold]axiscal guide[/]: machine {c.machine}, axis {config.axis.name}, "
                  f"operator {c.operator or '-'}, config {config.source}")
    console.print(plan_preview(setup.plan, config, args.speed))


def ask_operator(console: Console) -> str:
    """The operator's name, asked once when the config has none (recorded with the campaign)."""
    return console.input("Operator's name (recorded with the campaign; Enter to leave it empty): ").strip()


def stop_on(item: CheckItem) -> NoReturn:
    raise InputError(f"setup check failed: {item.name}: {item.value}")


def open_and_check(prepare: Callable[[], Setup], console: Console, interactive: bool,
                   on_hardware: Callable[[Hardware, Any], None] | None = None,
                   more_items: Callable[[Hardware], list[CheckItem]] | None = None, *,
                   first: Setup | None = None, on_change: Callable[[Setup], None] | None = None
                   ) -> tuple[Opened, Setup]:
    """Run the setup checklist until it passes: each check calls `prepare()` (the guide reads its
    config again, so a file fixed since the last check is what is checked; `first`: the setup read
    already), opens the hardware when it is not open or the config's hardware changed, and checks
    it. On a failure ask to retry (interactive) or stop with InputError (scripts). Nothing moves
    here. `more_items(hw)`: further checks; `on_change(setup)`: told when a re-check read a changed
    config. Returns the hardware and the setup that passed; the hardware is closed again when this
    ends without a pass."""
    hw: Hardware | None = None
    sim: Any = None
    opened_for: Setup | None = None
    setup: Setup | None = first
    try:
        while True:
            items: list[CheckItem] = []
            if setup is None:
                try:
                    setup = prepare()
                except InputError as exc:
                    items = [CheckItem("config", False, str(exc))]
                else:
                    if on_change is not None and opened_for is not None and \
                            setup.config.text != opened_for.config.text:
                        on_change(setup)
            if setup is not None:
                if hw is not None and opened_for is not None and setup.config.driver != opened_for.config.driver:
                    hw.close()  # the config now names other hardware: open that
                    hw = None
                if hw is None:
                    hw, sim, items = open_hardware(setup, on_hardware)
                    opened_for = setup
                if hw is not None:
                    items = hardware_items(hw, setup.config) + (more_items(hw) if more_items else [])
                items += setup.offline
            console.print(checklist_table(items))
            if hw is not None and setup is not None and not failures(items):
                return (hw, sim), setup
            answer = "q"
            if interactive:
                answer = console.input("Fix it, then press Enter to check again (q and Enter quits): ")
            if answer.strip().lower() in ("q", "quit"):
                stop_on(failures(items)[0])
            setup = None  # read it again
    except BaseException:
        if hw is not None:
            hw.close()
        raise


NOT_CHECKED = ("interferometer signal", "air temperature", "air pressure", "humidity", "material temperature")
"""The checklist's rows that need the hardware open: shown as not checked when it did not open."""


def open_hardware(setup: Setup, on_hardware: Callable[[Hardware, Any], None] | None
                  ) -> tuple[Hardware | None, Any, list[CheckItem]]:
    """Open the hardware the setup names: (hardware, parts, []) or (None, None, the checklist's
    rows saying why: a file the config names, the controller or the interferometer, and the rows
    not checked because of it)."""
    try:
        hw, sim = setup.open()
    except InputError as exc:  # a file the config names (the simulated machine's model, a serial port...)
        failed = CheckItem("config", False, str(exc))
    except InstrumentError as exc:
        failed = CheckItem("interferometer signal", False, f"cannot open the interferometer: {exc}")
    except (AxisError, *BAD_INPUT, OSError) as exc:
        failed = CheckItem("controller", False, f"cannot open the hardware: {exc}")
    else:
        if on_hardware:
            on_hardware(hw, sim)
        return hw, sim, []
    rows = [failed] + [CheckItem(name, None, "not checked: the hardware did not open")
                       for name in NOT_CHECKED if name != failed.name]
    if failed.name != "controller":
        rows.insert(1, CheckItem("controller", None, "not checked: the hardware did not open"))
    return None, None, rows


def confirm(args: argparse.Namespace, console: Console, interactive: bool, motion: str) -> None:
    """Say how the axis will move and ask before it does (--yes answers for scripts)."""
    console.print(f"[bold]The axis will move[/]: {motion}. Keep clear of the machine.")
    if args.yes:
        console.print("Motion confirmed by --yes.")
        return
    if not interactive:
        raise InputError("confirmation needed before the axis moves: run with --yes")
    if console.input("Start the motion? Type y and Enter: ").strip().lower() not in ("y", "yes"):
        raise InputError("not confirmed: nothing moved")


def on_dashboard(config: Config, plan: Plan, args: argparse.Namespace, opened: Opened, console: Console,
                 interactive: bool, out: Path, campaign: Callable[[Dashboard, Control], Outcome],
                 before: Callable[[Control, Keys | None], None] | None = None,
                 then: Callable[[int, FrameType | None], None] | None = None) -> Outcome:
    """The motion phase on the dashboard: `before(control, keys)` (the alignment check), then
    `campaign(dashboard, control)`. Keys and Ctrl-C are live throughout; an abort at any point ends
    with the outcome so far; the terminal is restored at the end, and SIGINT too, or set to `then`."""
    hw, _ = opened
    asks = args.on_fault is None and interactive  # else the config's policy (--on-fault is in the config)
    control = Control(asks_operator=asks)
    with ExitStack() as stack:
        dashboard = Dashboard(console, config, plan, control, "ask" if asks else None, hw)
        if interactive:
            dashboard.keys = stack.enter_context(Keys(dashboard.on_key))
        stack.enter_context(CtrlC(dashboard, then))
        if before is not None:
            try:
                before(control, dashboard.keys)
            except KeyboardInterrupt:
                return Outcome(out, "interrupted", 0, len(plan.points), 0.0,
                               "aborted during the alignment check: the axis is halted, nothing was recorded")
        try:
            with dashboard:
                return campaign(dashboard, control)
        except KeyboardInterrupt:
            return recorded_outcome(out, len(plan.points), dashboard.abort_reason)


def check_alignment(hw: Hardware, plan: Plan, config: Config, control: Control, console: Console,
                    keys: Keys | None) -> None:
    while True:
        console.print(f"Alignment check: the axis moves to both ends at {config.plan.velocity:g} "
                      f"{config.axis.unit}/s ...")
        item = alignment_item(hw, plan, config, control)
        console.print(checklist_table([item]))
        if item.ok:
            return
        if keys is None:
            stop_on(item)
        console.print("Fix the alignment, then press r to check again (the axis moves again), or q to quit.")
        if keys.ask({"r": "retry", "q": "quit"}, control) != "retry":
            stop_on(item)


def recorded_outcome(directory: Path, planned: int, reason: str | None) -> Outcome:
    """The outcome of a campaign that ended with an abort, from its directory. A record without its
    stop record (a second Ctrl-C came while it was written) is interrupted: resume treats it so."""
    campaign = open_campaign(directory)
    status = "interrupted" if campaign.status == "running" else campaign.status
    return Outcome(directory, status, len(recorded_point_indices(directory)), planned,
                   campaign.duration_s, reason or campaign.message or "aborted")


def conclude(outcome: Outcome, config: Config, args: argparse.Namespace, console: Console) -> int:
    """The ISO 230-2 summary so far, the outliers, the verdict (campaign/assess.py: the same as
    `analyze` and `report`), where the record is and what comes next. Exit 0 when the campaign
    completed, 3 when it stopped (resumable)."""
    from campaign.assess import assess_path
    from campaign.views import outlier_lines, verdict_line

    d = outcome.dir

    def say(text: str) -> None:  # paths and commands: never wrapped, never read as markup
        console.print(text, soft_wrap=True, markup=False, highlight=False)

    if not (d / "meta.json").exists():
        say(f"Stopped: {outcome.message}.")
        return 3
    assessment = assess_path(d) if outcome.points else None
    if assessment is not None:
        console.print(summary_table(assessment.evaluation))
        for line in outlier_lines(assessment.outliers, assessment.evaluation.unit):
            console.print(line, markup=False)
    console.print(f"Campaign {outcome.status}: {outcome.points} of {outcome.planned} points in "
                  f"{outcome.duration_s / 60:.1f} min of campaign time.")
    if assessment is not None:
        console.print(verdict_line(assessment.verdict) + ".")
    else:
        console.print("[bold yellow]NOT JUDGED[/]: no point was recorded.")
    if outcome.status == "completed" and outcome.points == outcome.planned:
        say(f"Record: {d} (points.csv, raw.csv, events.jsonl, plan.jsonl, meta.json).")
        say(f"Report for quality:\n  axiscal report {d} -o {d}/report.html")
        say(f"Next step, compensation (FMT: {COMPENSATE_FORMATS}):\n"
            f"  axiscal compensate {d}/points.csv --format FMT -o FILE")
    elif outcome.status == "completed":
        say(f"Record: {d}. {outcome.planned - outcome.points} point(s) were skipped.\n"
            f"Measure them with:\n  axiscal resume {d}")
    else:
        say(f"Stopped: {outcome.message}. Record: {d}.\nContinue with:\n  axiscal resume {d}")
    from campaign.commands.history import record_after

    record_after(d, getattr(args, "command", None) or "guide")  # after the verdict is on the screen
    if args.json:
        result = {"dir": str(d), "status": outcome.status, "points": outcome.points, "planned": outcome.planned,
                  "duration_s": round(outcome.duration_s, 3)}
        if assessment is not None:
            result.update(assessment.as_json())
        else:
            result.update(verdict="not judged", reasons=["no point was recorded"])
        print_json(result)
    return 0 if outcome.status == "completed" else 3

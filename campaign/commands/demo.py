"""`axiscal demo [--out DIR] [--speed N] [--capture dwell|stable] [--json] [--plot OUT]
[--controller sim|linuxcnc|epics [--verify]] [--fake] [--cycles N]`.

The main job: a complete campaign on the simulated machine (the horizontal axis of Li et al. 2022) through
the real ADS client against the loopback test server and the real serial stack over a pty,
followed by the ISO 230-2 analysis. `--fake`: the same campaign on the in-process fake machine
(drivers/fake.py), in about a second.
"""

from __future__ import annotations

import argparse
from importlib import resources
from typing import Any

from campaign import capture_methods
from campaign.commands import SUMMARY, YES_HELP, hardware_opener, positive_integer
from campaign.commands.run import add_run_options, finish, run_config, with_on_fault
from campaign.config import Config, parse_config
from campaign.errors import InputError
from campaign.faults import parse_inject
from campaign.measure import Executor, RichProgress, resume_campaign, start_campaign
from campaign.record import read_events
from protocols.hardware import Hardware


def demo_config_text() -> str:
    return resources.files("campaign").joinpath("demo.toml").read_text(encoding="utf-8")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("demo", help=SUMMARY["demo"],
                       description="Run the horizontal-axis campaign of Li et al. 2022 on the simulated machine.")
    add_run_options(p)
    p.add_argument("--capture", choices=capture_methods.names(live=True, sweeps=False),
                   help="capture method (default dwell)")
    p.add_argument("--controller", choices=("sim", "linuxcnc", "epics"), default="sim",
                   help="sim (default): the simulated PLC over ADS; linuxcnc: a headless LinuxCNC (real time) "
                        "with a simulated laser on its joint (docs/linuxcnc.md); epics: the simulated axis as an "
                        "EPICS motor record over Channel Access on loopback (docs/epics.md)")
    p.add_argument("--verify", action="store_true",
                   help="with --controller linuxcnc: compensate (--format linuxcnc), restart LinuxCNC with the "
                        "COMP_FILE and measure again; with --controller epics: write the table through Channel "
                        "Access and measure again")
    p.add_argument("--fake", action="store_true",
                   help="run on the in-process fake machine instead (drivers/fake.py: no PLC, no socket, no pty; "
                        "the demo's error model without noise), in about a second")
    p.add_argument("--cycles", type=positive_integer, help="runs of the campaign (default 5)")
    p.add_argument("--yes", action="store_true", help=YES_HELP)
    p.add_argument("--inject", metavar="NAME[@S],...",
                   help="rehearse faults at simulated times, e.g. beam_break@300,ads_lost@500 "
                        "(names: see docs/faults.md); the campaign resumes by itself where needed")
    p.add_argument("--history", type=positive_integer, metavar="N",
                   help="instead: N re-checks of the demo axis over two years (lead error growing, one reversal "
                        "jump), simulated by the fast simulator in seconds, recorded into the history store, then "
                        "its trend (docs/history.md)")
    p.set_defaults(func=run)


MAX_RESUMES = 3


def run(args: argparse.Namespace) -> int:
    if args.history:
        from campaign.commands.history import demo_history

        return demo_history(args)
    text = demo_config_text()
    if args.cycles:
        text = text.replace("cycles = 5", f"cycles = {args.cycles}")
    if args.fake:
        return fake_demo(text, args)
    if args.controller == "linuxcnc":
        from campaign.commands.linuxcnc_demo import linuxcnc_demo

        return linuxcnc_demo(text, args)
    if args.controller == "epics":
        from campaign.commands.epics_demo import epics_demo

        if args.capture:
            text = text.replace('method = "dwell"', f'method = "{args.capture}"')
        return epics_demo(text, args)
    if args.verify:
        raise InputError("--verify: the simulated PLC's closed loop is `axiscal verify`; --verify goes with "
                         "--controller linuxcnc or epics")
    if args.capture:
        text = text.replace('method = "dwell"', f'method = "{args.capture}"')
    if not args.inject:
        return run_config(parse_config(text, "demo.toml"), args)
    faults = parse_inject(args.inject)
    text += "\n[sim.faults]\n" + "".join(f"{name} = {{ at_s = {p['at_s']!r} }}\n" for name, p in faults.items())
    return rehearse(parse_config(text, "demo.toml"), faults, args)


def fake_demo(text: str, args: argparse.Namespace) -> int:
    """The demo campaign on the fake machine (drivers/fake.py): the same plan, executor, recording
    and analysis, on an in-process axis and laser that follow the demo's error model without noise.
    Recorded as machine "fake-press" with driver "fake" in meta.json, and not fsynced point by
    point (`durable` false in meta.json): its points measure nothing, and the fsyncs were most of
    its wall time."""
    for option, given in (("--controller linuxcnc", args.controller != "sim"), ("--verify", args.verify),
                          ("--inject", bool(args.inject)), ("--speed", args.speed is not None)):
        if given:
            raise InputError(f"--fake: {option} needs the simulated machine; the fake machine has no PLC to fault "
                             "and takes no wall time")
    if args.capture:
        text = text.replace('method = "dwell"', f'method = "{args.capture}"')
    text = text.replace('machine = "sim-press"', 'machine = "fake-press"').replace(
        "on the simulated machine", "on the in-process fake machine")
    return run_config(parse_config(text, "demo.toml"), args, opener=hardware_opener(fake=True),
                      meta_extra={"driver": "fake", "durable": False}, durable=False)


def rehearse(config: Config, faults: dict, args: argparse.Namespace) -> int:
    """Run with faults injected; resume (without faults) as often as needed, then report."""
    config = with_on_fault(config, args)
    fired: list = []

    def keep_log(hardware: Hardware, sim: Any, executor: Executor) -> None:
        fired.append(sim.faults.log)

    def progress() -> RichProgress:
        unit = config.axis.unit
        return RichProgress(unit)

    with progress() as observer:
        outcome = start_campaign(config, args.out, opener=hardware_opener(), speed=args.speed, observer=observer,
                                 on_open=keep_log)
    resumes = 0
    while outcome.status != "completed" and resumes < MAX_RESUMES:
        resumes += 1
        fired_names = {name for log in fired for _, name, what in log if what == "injected"}
        remaining = {name: p for name, p in faults.items() if name not in fired_names}
        with progress() as observer:
            outcome = resume_campaign(outcome.dir, faults=remaining, opener=hardware_opener(), speed=args.speed,
                                      observer=observer, on_open=keep_log)
    events = read_events(outcome.dir)
    survived = outcome.status == "completed" and outcome.points == outcome.planned
    extra = {"faults": [{"name": name, "at_s": round(t, 3), "what": what} for log in fired for t, name, what in log],
             "resumes": resumes, "survived": survived, "events": events}
    return finish(outcome, args, extra)

"""The subcommands of `axiscal`, one module each (see campaign/cli.py).

Each module has `register(subparsers)`, which adds its parser (with `help=SUMMARY[name]`) and sets
`func(args) -> int`. A command module imports only what its parser needs at the top; the heavy
libraries (numpy, pandas, scipy, matplotlib, pyads) are imported when the command runs, so that
`axiscal --help` and every command start fast.
"""

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the session module is heavy: not imported for `axiscal --help`
    from campaign.measure import Opener
    from campaign.specs import DriverSpec

SUMMARY = {
    "analyze": "evaluate a point table to ISO 230-2 (or VDI 3441)",
    "plan": "print the test plan: points, travel, estimated duration",
    "run": "run a measurement campaign from a config",
    "demo": "run the paper's campaign on the simulated machine",
    "compensate": "write a pitch-error compensation table for a controller",
    "correction": "show how a correction step is planned (rate and accel bounds)",
    "verify": "measure again with the compensation active (before/after)",
    "refine": "propose extra targets for a follow-up campaign",
    "discover": "name the effects an error model is missing",
    "guide": "guided campaign for the technician: checklist, dashboard, keys",
    "resume": "continue an interrupted campaign: the points it left out",
    "replay": "re-run a recorded campaign offline through the capture code",
    "import-stream": "turn a continuous position log into a point table",
    "program": "the plan as a part program (LinuxCNC, FANUC, SINUMERIK, HEIDENHAIN) for another controller",
    "convert": "measurement files of other programs (.rtl, ecmc .dat) to point tables and back",
    "report": "write the HTML report of a campaign for quality",
    "history": "the campaign store: every campaign of every axis, its trend, when it leaves tolerance",
}
"""Every command's one-line help, in the order `axiscal --help` lists them. The module of a
command is its name with '-' as '_'."""


def positive_number(text: str) -> float:
    """argparse type: a finite number > 0 (nan and inf are refused, as is 0)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, found '{text}'")
    return value


def finite_number(text: str) -> float:
    """argparse type: a finite number (nan and inf are refused)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, found '{text}'")
    return value


def non_negative_number(text: str) -> float:
    """argparse type: a finite number ≥ 0."""
    value = finite_number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be ≥ 0, found '{text}'")
    return value


def positive_integer(text: str) -> int:
    """argparse type: a whole number > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a whole number > 0, found '{text}'")
    return value


def non_negative_integer(text: str) -> int:
    """argparse type: a whole number ≥ 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number ≥ 0, found '{text}'")
    return value


def hardware_opener(fake: bool = False) -> "Opener":
    """The drivers' hardware factory (campaign.measure.session.Opener), imported when a command
    needs hardware: the commands are the one place where the domain meets the drivers. `fake`:
    the in-process fake machine instead (drivers/fake.py), imported only then."""
    from drivers.factory import fake_opener, open_hardware

    return fake_opener() if fake else open_hardware


YES_HELP = ("stop a controller an earlier axiscal started and left running (a LinuxCNC whose axiscal was "
            "killed) without asking; one axiscal did not start is never stopped")


def kept_sim_model(directory: Path) -> Path | None:
    """The simulated machine's error model a campaign kept in its directory (what a resume reopens the
    machine with), if it kept one."""
    from drivers.factory import SIM_MODEL_FILE

    kept = Path(directory) / SIM_MODEL_FILE
    return kept if kept.is_file() else None


def stop_leftover_controller(spec: "DriverSpec", yes: bool) -> None:
    """Before a command starts the controller `spec` names: one an earlier axiscal started and left
    running (a LinuxCNC whose axiscal was killed) is stopped, with `yes` or when the user answers y
    at a terminal. Otherwise it is left alone and the opener refuses to start, saying what runs
    and how to stop it (--yes)."""
    from drivers.factory import leftover_controller

    found = leftover_controller(spec)
    if found is None:
        return
    what, stop = found
    if not yes:
        if not sys.stdin.isatty():
            return
        print(f"{what[0].upper()}{what[1:]} is still running. Stop it? [y/N] ", end="", file=sys.stderr, flush=True)
        if sys.stdin.readline().strip().lower() not in ("y", "yes"):  # on stderr: --json keeps stdout
            return
    print(f"stopping {what}", file=sys.stderr, flush=True)
    stop()

"""The subcommands of `axiscal`, one module each (see campaign/cli.py)."""

import argparse
import math


def positive_number(text: str) -> float:
    """argparse type: a finite number > 0 (nan and inf are refused, as is 0)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, found '{text}'")
    return value


def hardware_opener():
    """The drivers' hardware factory (campaign.measure.session.Opener), imported when a command
    needs hardware: the commands are the one place where the domain meets the drivers."""
    from drivers.factory import open_hardware

    return open_hardware

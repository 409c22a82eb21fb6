"""The `axiscal` command line. Each subcommand lives in campaign/commands/<name>.py and has
`register(subparsers)`, which adds its parser and sets `func(args) -> int`.

Bad input ends with exit status 2 and one line on stderr, `error: <what and where>`; never a
traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
from typing import NoReturn

# One BLAS thread unless the user says otherwise (set before numpy is first imported): discovery's
# least squares are many small products, where OpenBLAS's threads only spin. A 100,000-row
# discover took 110 s of CPU with the default threads, 28.7 s with one (bench/discovery_dense.py).
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

from campaign import __version__
from campaign.commands import SUMMARY
from campaign.errors import BAD_INPUT, CampaignInterrupted, InputError, one_line
from protocols.hardware import AxisError, InstrumentError


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one `error:` line and exit status 2."""

    def error(self, message: str) -> NoReturn:
        raise InputError(f"{self.prog}: {message}")


def build_parser(argv: list[str] | None = None) -> Parser:
    """The parser. Only the command named in `argv` (if any) is imported and registered in full;
    the others are listed with their one-line help, so that `axiscal --help` imports nothing heavy."""
    parser = Parser(prog="axiscal", description="Pitch-error measurement campaigns to ISO 230-2.")
    parser.add_argument("--version", action="version", version=f"axiscal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    words = sys.argv[1:] if argv is None else argv
    chosen = next((w for w in words if not w.startswith("-")), None)
    for name, summary in SUMMARY.items():
        if name == chosen:
            importlib.import_module(f"campaign.commands.{name.replace('-', '_')}").register(sub)
        else:
            sub.add_parser(name, help=summary)
    return parser


def main(argv: list[str] | None = None) -> int:
    if threading.current_thread() is threading.main_thread():
        # A process started as a background job inherits SIGINT ignored; Ctrl-C (or kill -INT)
        # must still halt the axis and flush the recording.
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            raise InputError("no command given: axiscal COMMAND (the commands are listed above)")
        return int(args.func(args) or 0)
    except BAD_INPUT as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (AxisError, InstrumentError) as exc:
        print(f"error: {one_line(str(exc))}", file=sys.stderr)
        return 3
    except CampaignInterrupted as exc:
        print(f"interrupted (Ctrl-C): the axis was asked to halt and the recording is flushed in {exc.directory}; "
              f"continue with: axiscal resume {exc.directory}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    except Exception as exc:  # a bug: one line for the user, the traceback on request
        if os.environ.get("AXISCAL_DEBUG"):
            raise
        print(f"error: internal error: {type(exc).__name__}: {one_line(str(exc))} (AXISCAL_DEBUG=1 shows the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())

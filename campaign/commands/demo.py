"""`axiscal demo [--out DIR] [--speed N] [--capture dwell|stable] [--json] [--plot OUT]`.

The main job: a complete campaign on the simulated machine (seed 000's horizontal axis) through
the real ADS client against the loopback test server and the real serial stack over a pty,
followed by the ISO 230-2 analysis.
"""

from __future__ import annotations

from importlib import resources

from campaign.commands.run import add_run_options, run_config
from campaign.config import parse_config


def demo_config_text() -> str:
    return resources.files("campaign").joinpath("demo.toml").read_text(encoding="utf-8")


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the paper's campaign on the simulated machine",
                       description="Run seed 000's horizontal-axis campaign on the simulated machine.")
    add_run_options(p)
    p.add_argument("--capture", choices=("dwell", "stable"), help="capture method (default dwell)")
    p.set_defaults(func=run)


def run(args) -> int:
    text = demo_config_text()
    if args.capture:
        text = text.replace('method = "dwell"', f'method = "{args.capture}"')
    config = parse_config(text, "demo.toml")
    return run_config(config, args)

"""`axiscal plan CONFIG [--json]`: print the plan without moving anything."""

from __future__ import annotations

from rich.table import Table

from campaign.config import load_config
from campaign.plan import build_plan, check_plan, estimate_duration_s
from campaign.views import make_console, print_json


def register(sub) -> None:
    p = sub.add_parser("plan", help="print the test plan: points, travel, estimated duration",
                       description="Print the plan of a campaign config and check it against the limits.")
    p.add_argument("config", help="campaign TOML (see docs/config.md)")
    p.add_argument("--json", action="store_true", help="one JSON object")
    p.add_argument("--steps", action="store_true", help="also list every step")
    p.set_defaults(func=run)


def summary(config, plan) -> dict:
    a = config["axis"]
    return {"points": len(plan.points), "runs": config["plan"]["cycles"], "targets": list(plan.targets),
            "offsets": list(plan.offsets), "seed": plan.seed, "unit": a["unit"],
            "travel": round(plan.travel(), 6), "estimated_duration_s": round(estimate_duration_s(plan, config), 1),
            "moves": len(plan.stops()), "cycle": config["plan"]["cycle"],
            "soft_limits": [a["soft_limit_min"], a["soft_limit_max"]], "max_velocity": a["max_velocity"]}


def run(args) -> int:
    config = load_config(args.config)
    plan = build_plan(config)
    check_plan(plan, config)
    info = summary(config, plan)
    if args.json:
        print_json(info)
        return 0
    console = make_console()
    u = info["unit"]
    table = Table(title=f"Plan: {args.config}", show_header=False)
    table.add_row("points", f"{info['points']} ({len(plan.targets)} targets × 2 directions × {info['runs']} runs)"
                  if info["cycle"] == "linear" else str(info["points"]))
    table.add_row("targets", ", ".join(f"{t:g}" for t in plan.targets) + f" {u}")
    table.add_row("travel", f"{info['travel']:.1f} {u}")
    table.add_row("estimated duration", f"{info['estimated_duration_s'] / 60:.1f} min")
    table.add_row("soft limits", f"[{info['soft_limits'][0]:g}, {info['soft_limits'][1]:g}] {u}; "
                                 f"max velocity {info['max_velocity']:g} {u}/s — plan within limits")
    console.print(table)
    if args.steps:
        for i, step in enumerate(plan.steps):
            console.print(f"{i:5d} {step}")
    return 0

"""`axiscal correction --step UM --max-rate UM_PER_S --max-accel UM_PER_S2 --cycle-ms MS`: a
step of the desired correction next to the planned correction (the 2024 motion-planning patent), with the largest
change per cycle and the largest acceleration of each."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from campaign.commands import SUMMARY, finite_number, positive_number
from campaign.errors import InputError
from campaign.plot import check_plot_path
from campaign.views import make_console, print_json
from protocols.correction_planner import PlannerLimits, minimum_time, plan


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("correction", help=SUMMARY["correction"],
                       description="Plan a step of the correction with bounded rate and acceleration.")
    p.add_argument("--step", type=finite_number, required=True, help="size of the step, µm")
    p.add_argument("--max-rate", type=positive_number, required=True, metavar="UM_PER_S", help="rate bound, µm/s")
    p.add_argument("--max-accel", type=positive_number, required=True, metavar="UM_PER_S2", help="acceleration bound, µm/s²")
    p.add_argument("--cycle-ms", type=positive_number, required=True, help="control cycle, ms")
    p.add_argument("--plot", metavar="OUT", help="write the plot to OUT.png or OUT.svg")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def _profile(values: np.ndarray, dt: float) -> tuple[float, float]:
    """(largest change per cycle µm, largest acceleration µm/s²) of a sampled signal from 0."""
    steps = np.diff(np.concatenate([[0.0], values]))
    accel = np.diff(np.concatenate([[0.0], steps])) / dt**2
    return float(np.max(np.abs(steps))), float(np.max(np.abs(accel)))


def run(args: argparse.Namespace) -> int:
    if not math.isfinite(args.step):
        raise InputError("--step must be a finite number")
    dt = args.cycle_ms / 1000.0
    try:
        limits = PlannerLimits(args.max_rate, args.max_accel, dt)
    except ValueError as exc:
        raise InputError(f"--max-rate, --max-accel, --cycle-ms: {exc}") from None
    plot_path = check_plot_path(args.plot) if args.plot else None
    t_min = minimum_time(args.step, args.max_rate, args.max_accel)
    cycles = math.ceil(t_min / dt) + 5
    if cycles > 10_000_000:
        raise InputError(f"the step takes {t_min:g} s, more than 10^7 cycles of {args.cycle_ms:g} ms")
    desired = np.full(cycles, args.step)
    planned = plan(desired, limits)
    settled = int(np.argmax(planned == args.step)) + 1 if np.any(planned == args.step) else None
    step_change, step_accel = _profile(desired, dt)
    plan_change, plan_accel = _profile(planned, dt)
    result = {"step_um": args.step, "cycle_ms": args.cycle_ms, "minimum_time_s": t_min,
              "cycles_to_settle": settled,
              "step": {"max_change_per_cycle_um": step_change, "max_accel_um_s2": step_accel},
              "planned": {"max_change_per_cycle_um": plan_change, "max_accel_um_s2": plan_accel}}
    if plot_path:
        _plot(desired, planned, dt, plot_path)
    if args.json:
        print_json(result)
        return 0
    console = make_console()
    settles = (f"settles after {settled} cycles = {settled * dt:.6g} s" if settled is not None else
               f"has not settled after {cycles} cycles")
    console.print(f"step {args.step:g} µm, cycle {args.cycle_ms:g} ms: {settles}; the continuous-time profile takes "
                  f"{t_min:.6g} s (the planner changes the correction once per cycle, so it may end a cycle or two "
                  "before or after that)")
    console.print(f"step:    max change per cycle {step_change:.4g} µm, max acceleration {step_accel:.4g} µm/s²")
    console.print(f"planned: max change per cycle {plan_change:.4g} µm, max acceleration {plan_accel:.4g} µm/s²")
    if plot_path:
        console.print(f"plot written to {plot_path}")
    return 0


def _plot(desired: np.ndarray, planned: np.ndarray, dt: float, path: str | Path) -> None:
    import matplotlib.pyplot as plt  # campaign.plot has set the Agg backend

    t = np.arange(1, len(desired) + 1) * dt * 1000.0
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.step(np.concatenate([[0.0], t]), np.concatenate([[0.0], desired]), where="post", label="desired (step)")
    ax.plot(np.concatenate([[0.0], t]), np.concatenate([[0.0], planned]), ".-", ms=3, label="planned")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("correction (µm)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)

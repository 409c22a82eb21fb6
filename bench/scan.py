"""Bench: a scan of the demo axis against the stop-and-go demo campaign of the same machine.

Issue 33's figures that need no executor: on the simulated demo axis (campaign/demo.toml's machine:
its error model, seed, acceleration, plan), with an instrument clock drawn at random per seed
(offset 10-80 ms, rate error 10-80 ppm, wander, sample jitter 5-30 µs, transport latency), a
bidirectional 3-pass scan at 10 mm/s and at 25 mm/s, resting the plan's dwell at each end:

- the mean unidirectional and bidirectional deviations at the demo's targets against the
  stop-and-go campaign (`axiscal run campaign/demo.toml`, same machine) and against the
  simulated truth at rest, RMS µm; E against the stop-and-go E; machine time against its time;
- what the tool says about the speed (timing budget, speed limit, warnings).

And a 1 µm, 10 mm screw lead over 60 mm at 2 mm/s: period and amplitude from a sine fit on the
profile. Writes bench/results/scan.json.

    .venv/bin/python bench/scan.py [--seeds N] [--rate HZ]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from campaign.config import load_config
from campaign.iso230 import evaluate
from campaign.model import ErrorModel, sim_model
from campaign.plan import make_plan
from campaign.pointtable import PointTable, read_points
from campaign.stream.align import ControllerStream, InstrumentStream
from campaign.stream.scan import analyse_scan, sine_fit
from drivers.sim.scan_streams import InstrumentClock, scan_machine

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "scan.json"
DEMO = ROOT / "campaign" / "demo.toml"


def draw_clock(seed: int) -> InstrumentClock:
    rng = np.random.default_rng([seed, 33])
    sign = rng.choice([-1.0, 1.0], 2)
    return InstrumentClock(offset_s=float(sign[0] * rng.uniform(0.01, 0.08)),
                           rate_error_ppm=float(sign[1] * rng.uniform(10, 80)), wander_ppm=float(rng.uniform(0, 0.1)),
                           wander_period_s=float(rng.uniform(300, 1200)), sample_jitter_s=float(rng.uniform(5e-6, 30e-6)),
                           latency_s=float(rng.uniform(0.002, 0.03)), latency_jitter_s=float(rng.uniform(0, 0.005)))


def means(table: PointTable, targets: np.ndarray) -> dict[int, np.ndarray]:
    return {d: np.array([table.deviation[(table.direction == d) & np.isclose(table.target, t)].mean()
                         for t in targets]) for d in (1, -1)}


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


def stop_and_go(tmp: Path) -> tuple[PointTable, float]:
    out = tmp / "demo"
    run = subprocess.run([sys.executable, "-m", "campaign", "run", str(DEMO), "--out", str(out), "--json"],
                         capture_output=True, text=True, check=True)
    return read_points(out / "points.csv"), float(json.loads(run.stdout)["duration_s"])


def demo_scan(seed: int, velocity: float, rate_hz: float, ref: PointTable, ref_time_s: float) -> dict:
    config = load_config(DEMO)
    plan = make_plan(config.plan, config.capture)
    model = sim_model(config.sim)
    clock = draw_clock(seed)
    low, high = plan.ends()
    machine = scan_machine(model, "mm", config.axis.max_velocity, config.axis.max_acceleration, low, clock, rate_hz,
                           seed=config.sim.seed)
    rec = machine.scan(low, high, velocity, 3, end_dwell_s=config.plan.dwell_s)
    res = analyse_scan(ControllerStream(rec.controller_time_s, rec.controller_position),
                       InstrumentStream(rec.instrument_time_s, rec.instrument_reading), plan.targets, rate_hz,
                       window=1.0, wanted_u=0.2, noise=model.reading_sigma_um, average_s=config.capture.average_s)
    targets = np.array(plan.targets)
    scan_m, ref_m = means(res.table, targets), means(ref, targets)
    rest = {d: model.deviation_um(targets, d, 0.0, np.inf) for d in (1, -1)}
    ev, ev_ref = evaluate(res.table), evaluate(ref)
    t_ref = res.alignment.t_ref_s
    return {
        "seed": seed, "velocity_mm_s": velocity, "rate_hz": rate_hz,
        "clock_true": {"offset_ms": round((float(clock.reading(t_ref)) - t_ref) * 1e3, 6),
                       "rate_error_ppm": clock.rate_error_ppm, "sample_jitter_us": clock.sample_jitter_s * 1e6},
        "alignment": res.alignment.as_dict(),
        "rest_step_um": {("+" if d > 0 else "-"): [round(s.step, 3), round(s.u, 3)] for d, s in res.rest.items()},
        "rms_vs_stop_and_go_um": {"up": rms(scan_m[1] - ref_m[1]), "down": rms(scan_m[-1] - ref_m[-1]),
                                  "bidirectional": rms((scan_m[1] + scan_m[-1]) / 2 - (ref_m[1] + ref_m[-1]) / 2)},
        "rms_vs_truth_at_rest_um": {"up": rms(scan_m[1] - rest[1]), "down": rms(scan_m[-1] - rest[-1])},
        "E_um": ev.summary["E"], "E_stop_and_go_um": ev_ref.summary["E"],
        "E_ratio": ev.summary["E"] / ev_ref.summary["E"],
        "machine_time_s": machine.clock.now(), "stop_and_go_time_s": ref_time_s,
        "time_ratio": machine.clock.now() / ref_time_s,
        "timing_u_um": res.budget.deviation_u, "speed_limit_mm_s": res.speed_limit, "warnings": res.warnings,
    }


def lead_scan(seed: int, rate_hz: float) -> dict:
    model = ErrorModel({"linear_scale": {"ppm": -8.0}, "periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0,
                                                                        "phase_rad": 0.7},
                        "backlash": {"b_um": 2.0}, "noise": {"sigma_um": 0.3, "reading_sigma_um": 0.05}})
    clock = draw_clock(seed)
    machine = scan_machine(model, "mm", 50.0, 200.0, -2.0, clock, rate_hz, seed=seed)
    rec = machine.scan(-2.0, 62.0, 2.0, 1, end_dwell_s=2.0)
    res = analyse_scan(ControllerStream(rec.controller_time_s, rec.controller_position),
                       InstrumentStream(rec.instrument_time_s, rec.instrument_reading), [0.0, 30.0, 60.0], rate_hz,
                       noise=0.05)
    inside = (res.profile.position >= 0.0) & (res.profile.position <= 60.0)
    from campaign.stream.scan import Profile
    p = res.profile
    sub = Profile(p.kind, p.position[inside], p.direction[inside], p.pass_[inside], p.deviation[inside], p.time_s[inside])
    period, amplitude = sine_fit(sub, 5.0, 20.0)
    return {"seed": seed, "period_mm": period, "period_error_pct": 100 * (period / 10.0 - 1),
            "amplitude_um": amplitude, "amplitude_error_pct": 100 * (amplitude / 1.0 - 1),
            "machine_time_s": machine.clock.now()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--rate", type=float, default=500.0, help="instrument sample rate, Hz")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        ref, ref_time = stop_and_go(Path(tmp))
    results: dict = {"stop_and_go": {"machine_time_s": ref_time, "E_um": evaluate(ref).summary["E"]}, "scans": [],
                     "lead": []}
    for velocity in (10.0, 25.0):
        for seed in range(1, args.seeds + 1):
            r = demo_scan(seed, velocity, args.rate, ref, ref_time)
            results["scans"].append(r)
            print(json.dumps({k: r[k] for k in ("seed", "velocity_mm_s", "rms_vs_stop_and_go_um", "E_ratio",
                                                "time_ratio", "timing_u_um", "speed_limit_mm_s", "rest_step_um")}),
                  flush=True)
    for seed in range(1, args.seeds + 1):
        r = lead_scan(seed, args.rate)
        results["lead"].append(r)
        print(json.dumps(r), flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Bench: a scan of the demo axis through `axiscal run`, against the stop-and-go demo campaign of
the same machine (issue 33's figures through the executor).

`axiscal run data/configs/scan-demo.toml` (the demo axis: campaign/demo.toml's error model, seed,
limits and targets; 3 passes; the laser at 500 Hz on its own clock) at 10 mm/s and at 25 mm/s, the
instrument clock drawn per seed (offset 10-80 ms, rate error 10-80 ppm, latency 2-30 ms, sample
jitter 5-30 µs), against `axiscal run campaign/demo.toml` (stop-and-go, 5 runs, same machine):

- the mean deviation at the 11 targets per direction and bidirectional, RMS difference, µm;
- E against the stop-and-go E; machine (campaign) time against its time;
- the clock offset found against the truth, and what the tool says about the speed.

Writes bench/results/scan_run.json.

    .venv/bin/python bench/scan_run.py [--seeds N] [--velocities 10,25]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from campaign.iso230 import evaluate
from campaign.pointtable import PointTable, read_points

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "scan_run.json"
DEMO = ROOT / "campaign" / "demo.toml"
SCAN = ROOT / "data" / "configs" / "scan-demo.toml"


def draw_clock(seed: int) -> dict[str, float]:
    rng = np.random.default_rng([seed, 3301])
    sign = rng.choice([-1.0, 1.0], 2)
    return {"instrument_offset_s": round(float(sign[0] * rng.uniform(0.01, 0.08)), 6),
            "instrument_rate_ppm": round(float(sign[1] * rng.uniform(10, 80)), 3),
            "instrument_latency_s": round(float(rng.uniform(0.002, 0.03)), 6),
            "instrument_jitter_s": round(float(rng.uniform(5e-6, 30e-6)), 8)}


def means(table: PointTable) -> dict[int, np.ndarray]:
    targets = sorted(set(table.target.tolist()))
    return {d: np.array([table.deviation[(table.direction == d) & np.isclose(table.target, t)].mean()
                         for t in targets]) for d in (1, -1)}


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


def run(config: Path, out: Path) -> dict:
    proc = subprocess.run([sys.executable, "-m", "campaign", "run", str(config), "--out", str(out), "--json"],
                          capture_output=True, text=True, cwd=ROOT, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"{config}: exit {proc.returncode}: {proc.stderr.strip()[-500:]}")
    return json.loads(proc.stdout)


def scan_config(tmp: Path, seed: int, velocity: float) -> tuple[Path, dict[str, float]]:
    clock = draw_clock(seed)
    text = SCAN.read_text().replace("scan_velocity = 10.0", f"scan_velocity = {velocity:g}")
    for key, value in clock.items():
        text = re.sub(rf"^{key} = .*$", f"{key} = {value!r}", text, flags=re.MULTILINE)
    path = tmp / f"scan-{seed}-{velocity:g}.toml"
    path.write_text(text)
    return path, clock


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--velocities", default="10,25")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        ref = run(DEMO, tmp / "demo")
        ref_table = read_points(tmp / "demo" / "points.csv")
        ref_m, ref_e = means(ref_table), evaluate(ref_table).summary["E"]
        results: dict = {"stop_and_go": {"machine_time_s": ref["duration_s"], "E_um": ref_e}, "scans": []}
        print(json.dumps(results["stop_and_go"]), flush=True)
        for velocity in (float(v) for v in args.velocities.split(",")):
            for seed in range(1, args.seeds + 1):
                config, clock = scan_config(tmp, seed, velocity)
                out = tmp / f"scan-{seed}-{velocity:g}"
                got = run(config, out)
                table = read_points(out / "points.csv")
                m, e = means(table), evaluate(table).summary["E"]
                meta = table.meta
                r = {"seed": seed, "velocity_mm_s": velocity, "clock": clock, "status": got["status"],
                     "verdict": got["verdict"],
                     "rms_vs_stop_and_go_um": {"up": rms(m[1] - ref_m[1]), "down": rms(m[-1] - ref_m[-1]),
                                               "bidirectional": rms((m[1] + m[-1]) / 2 - (ref_m[1] + ref_m[-1]) / 2)},
                     "E_um": e, "E_ratio": e / ref_e, "machine_time_s": got["duration_s"],
                     "time_ratio": got["duration_s"] / ref["duration_s"],
                     "clock_offset_ms": meta.get("clock_offset_ms"), "clock_reference_s": meta.get("clock_reference_s"),
                     "timing_u": meta.get("timing_u"), "speed_limit": meta.get("speed_limit"),
                     "deviation": meta.get("deviation"),
                     "warnings": [v for k, v in meta.items() if k.startswith("warning")]}
                results["scans"].append(r)
                print(json.dumps(r), flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

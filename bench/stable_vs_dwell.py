"""Bench: the stability trigger against a fixed 4 s dwell on the same simulated axis (issue 3).

Goals: campaign duration ratio (stable / dwell) <= 0.5, and A within 5 %. The axis is seed 000's
horizontal axis (data/models/seed000-horizontal.toml) with settling on (1.5 µm decaying with
0.3 s), positioning at 50 mm/s. The stable trigger waits for the reading to stay within 0.2 µm
for 0.5 s (timeout 4 s). Several noise seeds; writes bench/results/stable_vs_dwell.json.

    .venv/bin/python bench/stable_vs_dwell.py [--seeds N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from campaign.config import parse_config
from campaign.measure.session import analyse_dir, start_campaign
from drivers.factory import open_hardware

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).parent / "results"

CONFIG = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 610.0
max_velocity = 50.0
max_acceleration = 500.0
[plan]
length = 600.0
count = 11
overrun = 5.0
cycles = 5
dwell_s = 4.0
velocity = 50.0
[capture]
method = "{method}"
average_s = 1.0
stable_tolerance = 0.2
stable_window_s = 0.5
stable_timeout_s = 4.0
[sim]
seed = {seed}
model = "{model}"
[sim.effects.settling]
e0_um = 1.5
tau_s = 0.3
"""


def campaign(method: str, seed: int, tmp: str) -> tuple[float, float]:
    text = CONFIG.format(method=method, seed=seed, model=ROOT / "data/models/seed000-horizontal.toml")
    outcome = start_campaign(parse_config(text, str(ROOT / "bench" / "bench.toml")), f"{tmp}/{method}-{seed}",
                             opener=open_hardware)
    assert outcome.status == "completed"
    _, ev = analyse_dir(outcome.dir)
    return outcome.duration_s, ev.summary["A"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.seeds + 1):
            dwell_s, dwell_a = campaign("dwell", seed, tmp)
            stable_s, stable_a = campaign("stable", seed, tmp)
            rows.append({"seed": seed, "dwell_duration_s": round(dwell_s, 1), "stable_duration_s": round(stable_s, 1),
                         "duration_ratio": round(stable_s / dwell_s, 3), "A_dwell_um": round(dwell_a, 3),
                         "A_stable_um": round(stable_a, 3),
                         "A_difference_pct": round(100 * abs(stable_a - dwell_a) / dwell_a, 2)})
            print(rows[-1])
    result = {"runs": rows, "duration_ratio_median": statistics.median(r["duration_ratio"] for r in rows),
              "A_difference_pct_max": max(r["A_difference_pct"] for r in rows),
              "goals": {"duration_ratio": 0.5, "A_difference_pct": 5.0}}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "stable_vs_dwell.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "runs"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Bench: the stability trigger against the fixed 4 s dwell on the demo axis itself (issue 13).

The axis and every setting are those of `axiscal demo` (campaign/demo.toml: Li et al. 2022's horizontal
axis with settling, 1.5 µm decaying with 0.6 s, 8 mm/s), the capture at its default settings.
Goals: A within 5 % of the fixed dwell's A, with at most half the waiting at the targets (the mean
capture wait over the 4 s dwell). Several seeds of the simulated machine; for each seed both
methods see the same per-approach scatter (drivers/sim/machine.py draws it from its own stream),
so the difference is the capture's. Also reports the campaign duration ratio (moves included).
Writes bench/results/stable_vs_dwell.json.

    .venv/bin/python bench/stable_vs_dwell.py [--seeds N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np

from campaign.config import parse_config
from campaign.measure.session import analyse_dir, start_campaign
from drivers.factory import open_hardware

RESULTS = Path(__file__).parent / "results"


def campaign(method: str, seed: int, tmp: str) -> tuple[float, float, float, float]:
    """(campaign duration s, A µm, mean capture wait s, dwell s) of the demo with `method`."""
    text = resources.files("campaign").joinpath("demo.toml").read_text(encoding="utf-8")
    text = text.replace('method = "dwell"', f'method = "{method}"').replace("\nseed = 1\n", f"\nseed = {seed}\n")
    config = parse_config(text, "demo.toml")
    outcome = start_campaign(config, f"{tmp}/{method}-{seed}", opener=open_hardware)
    assert outcome.status == "completed" and outcome.points == outcome.planned
    table, ev = analyse_dir(outcome.dir)
    return outcome.duration_s, ev.summary["A"], float(np.mean(table.extra["capture_wait_s"])), config.plan.dwell_s


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.seeds + 1):
            dwell_s, dwell_a, _, dwell = campaign("dwell", seed, tmp)
            stable_s, stable_a, wait, _ = campaign("stable", seed, tmp)
            rows.append({"seed": seed, "A_dwell_um": round(dwell_a, 3), "A_stable_um": round(stable_a, 3),
                         "A_difference_pct": round(100 * (stable_a - dwell_a) / dwell_a, 2),
                         "mean_wait_s": round(wait, 3), "wait_ratio": round(wait / dwell, 3),
                         "duration_ratio": round(stable_s / dwell_s, 3)})
            print(rows[-1], flush=True)
    result = {"axis": "campaign/demo.toml, default capture settings", "runs": rows,
              "A_difference_pct_max_abs": max(abs(r["A_difference_pct"]) for r in rows),
              "wait_ratio_max": max(r["wait_ratio"] for r in rows),
              "duration_ratio_median": statistics.median(r["duration_ratio"] for r in rows),
              "goals": {"A_difference_pct": 5.0, "wait_ratio": 0.5}}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "stable_vs_dwell.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "runs"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

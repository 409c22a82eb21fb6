"""Bench: what the smoothing of the means gains and costs (campaign/compensation/smooth.py).

Simulated 5-run campaigns of a cubic screw on 11 targets, scatter s = 1 (so every figure is in
units of s). For a bump of b·s at one target (b = 0 is the smooth screw) it gives:

- the share of campaigns where the bump is detected (the raw means are kept);
- the RMS miss of the table's errors against the true error over the 11 targets, for the raw
  means and for the smoothed ones.

These are the figures quoted in docs/compensation-formats.md and in the module text. Writes
bench/results/smoothing.json.

    .venv/bin/python bench/smoothing.py [--campaigns N]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from campaign.compensation.smooth import scatter_within_runs, smooth_means

RESULTS = Path(__file__).parent / "results"
TARGETS, RUNS, BUMP_AT = 11, 5, 4
BUMPS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0)


def one_bump(bump: float, campaigns: int, rng: np.random.Generator) -> dict:
    targets = np.linspace(0.0, 600.0, TARGETS)
    u = targets / 300 - 1
    truth = 30 * u + 8 * (1.5 * u**2 - 0.5) - 12 * (2.5 * u**3 - 1.5 * u)
    truth[BUMP_AT] += bump
    run, target = np.tile(np.arange(RUNS), TARGETS), np.repeat(targets, RUNS)
    raw_miss, smooth_miss, kept = [], [], 0
    for _ in range(campaigns):
        x = truth[:, None] + rng.normal(0, 1, (TARGETS, RUNS))
        means = x.mean(axis=1)
        sm = smooth_means(targets, means, np.full(TARGETS, 1 / RUNS), scatter_within_runs(run, target, x.ravel()))
        kept += sm.degree is None
        raw_miss.append(means - truth)
        smooth_miss.append(sm.values - truth)
    return {"bump_s": bump, "raw_means_kept": round(kept / campaigns, 3),
            "rms_miss_raw_s": round(float(np.sqrt(np.mean(np.square(raw_miss)))), 3),
            "rms_miss_smoothed_s": round(float(np.sqrt(np.mean(np.square(smooth_miss)))), 3)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", type=int, default=1000)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    rows = [one_bump(b, args.campaigns, rng) for b in BUMPS]
    for r in rows:
        print(r)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "smoothing.json").write_text(json.dumps({"targets": TARGETS, "runs": RUNS,
                                                        "campaigns": args.campaigns, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

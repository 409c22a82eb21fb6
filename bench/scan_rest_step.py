"""Bench: how well a scan's rest-step uncertainty covers the truth (campaign/stream/scan.py RestStep).

Drawn scans of a drive train wound up on the move (the settling effect, e0 0.5-2 µm, τ 0.3 s; the clock,
rate, noise, speed and acceleration drawn as tests/test_scan.py draws them), 2.5 s rests at the ends, the
axis coming to rest within 0.05 µm RMS of where it should, at 1, 2 and 3 passes, and at 1 pass again with
the axis coming to rest exactly: for each direction, the rest step found against the truth (-d·e0), in
units of its stated u. Writes bench/results/scan_rest_step.json and prints, per number of passes, how many of the
steps lie beyond 2u and 3u.

    .venv/bin/python bench/scan_rest_step.py [--first 100] [--seeds 100]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from campaign.stream.scan import analyse_scan
from tests.test_scan import _streams, _wound_up_scan

RESULTS = Path(__file__).parent / "results"
TARGETS = [0.0, 10.0, 20.0, 30.0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=100, help="the first scan's seed")
    parser.add_argument("--seeds", type=int, default=100, help="scans drawn for each number of passes")
    args = parser.parse_args()
    out = {"first": args.first, "seeds": args.seeds, "passes": {}}
    for passes, positioning_um in ((1, 0.05), (2, 0.05), (3, 0.05), (1, 0.0)):
        z = []
        for seed in range(args.first, args.first + args.seeds):
            draw, e0, rec = _wound_up_scan(seed, passes, positioning_um)
            res = analyse_scan(*_streams(rec), TARGETS, draw["rate_hz"], noise=draw["noise_um"], average_s=0.5)
            z += [(res.rest[d].step + d * e0) / res.rest[d].u for d in (1, -1)]
        a = np.abs(np.array(z))
        key = str(passes) if positioning_um else f"{passes}, comes to rest exactly"
        out["passes"][key] = {"steps": len(z), "beyond_2u": int(np.sum(a > 2)), "beyond_3u": int(np.sum(a > 3)),
                              "largest_z": round(float(a.max()), 2)}
        print(key, "pass(es):", out["passes"][key], flush=True)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "scan_rest_step.json").write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

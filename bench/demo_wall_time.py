"""Bench: wall time of the full paper campaign in `axiscal demo` (issue 3).

Goal: <= 10 s on 2 cores for 11 targets x 2 directions x 5 runs with 4 s dwells (about 20
simulated minutes), through the real ADS client, the loopback test server and the real serial
stack over a pty, analysis included. Runs the installed command several times and reports the
median. Writes bench/results/demo_wall_time.json.

    .venv/bin/python bench/demo_wall_time.py [--repeats R]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GOAL_S = 10.0
RESULTS = Path(__file__).parent / "results"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    times, simulated = [], None
    for i in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "campaign", "demo", "--out", f"{tmp}/d", "--json"],
                                  capture_output=True, text=True, check=True)
            times.append(time.perf_counter() - start)
            data = json.loads(proc.stdout)
            simulated = data["duration_s"]
            assert data["points"] == 110
        print(f"run {i + 1}: {times[-1]:.2f} s wall for {simulated:.0f} s simulated")
    median = statistics.median(times)
    result = {"wall_s_median": round(median, 3), "wall_s_all": [round(t, 3) for t in times],
              "simulated_s": simulated, "goal_s": GOAL_S, "ratio_to_goal": round(median / GOAL_S, 3),
              "speedup_over_real_time": round(simulated / median, 1)}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "demo_wall_time.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

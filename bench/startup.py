"""Bench: start-up time of the command line (issue 14).

Goal: `axiscal --help` within 10 times a bare `python -c pass` on the same machine. Also times
`axiscal COMMAND --help` for every command (each imports only what its parser needs; the heavy
libraries load when the command runs). Median of R runs each. Writes bench/results/startup.json.

    .venv/bin/python bench/startup.py [--repeats R]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from campaign.commands import SUMMARY

GOAL_RATIO = 10.0
RESULTS = Path(__file__).parent / "results"
AXISCAL = Path(sys.executable).with_name("axiscal")


def median_s(argv: list[str], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    bare = median_s([sys.executable, "-c", "pass"], args.repeats)
    top = median_s([str(AXISCAL), "--help"], args.repeats)
    commands = {name: round(median_s([str(AXISCAL), name, "--help"], max(3, args.repeats // 3)), 3)
                for name in SUMMARY}
    result = {"python_pass_s": round(bare, 4), "axiscal_help_s": round(top, 4), "ratio": round(top / bare, 2),
              "goal_ratio": GOAL_RATIO, "command_help_s": commands}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "startup.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

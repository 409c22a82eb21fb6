"""Bench: the paper campaign on the fake machine (drivers/fake.py), issue 32.

Goal: `axiscal demo --fake` (the 110-point demo campaign on the in-process fake machine: no PLC,
no socket, no pty) completes within 1 s wall, analysis included. Also measures the campaign alone
in-process (plan, executor, recording with its fsyncs, no start-up and no analysis) and per point:
what the executor and the recorder cost without any simulated hardware. The median of several
runs; the load average is recorded with the result, since wall time on a busy machine says little.
Writes bench/results/fake_machine.json.

    .venv/bin/python bench/fake_machine.py [--repeats R]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GOAL_S = 1.0
RESULTS = Path(__file__).parent / "results"


def campaign_alone_s(tmp: str) -> tuple[float, int]:
    """Wall time of start_campaign of the demo config on the fake machine, s, and its points."""
    from campaign.commands.demo import demo_config_text
    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from drivers.factory import fake_opener

    config = parse_config(demo_config_text(), "demo.toml")
    start = time.perf_counter()
    outcome = start_campaign(config, f"{tmp}/alone", opener=fake_opener())
    wall = time.perf_counter() - start
    assert outcome.status == "completed", outcome
    return wall, outcome.points


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    env = {**os.environ, "AXISCAL_DB": "none"}  # a bench records into no history store
    command, alone, points = [], [], 0
    for i in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "campaign", "demo", "--fake", "--out", f"{tmp}/d", "--json"],
                                  capture_output=True, text=True, check=True, env=env)
            command.append(time.perf_counter() - start)
            data = json.loads(proc.stdout)
            assert data["status"] == "completed" and data["points"] == 110, data
            wall, points = campaign_alone_s(tmp)
            alone.append(wall)
        print(f"run {i + 1}: axiscal demo --fake {command[-1]:.2f} s; the campaign alone {alone[-1]:.2f} s")
    median = statistics.median(command)
    result = {"command_wall_s_median": round(median, 3), "command_wall_s_all": [round(t, 3) for t in command],
              "campaign_alone_s_median": round(statistics.median(alone), 3),
              "per_point_ms": round(1000 * statistics.median(alone) / points, 2), "points": points,
              "simulated_s": data["duration_s"], "A_um": data.get("A"), "goal_s": GOAL_S,
              "ratio_to_goal": round(median / GOAL_S, 3), "load_average_1min": round(os.getloadavg()[0], 2),
              "cores": os.cpu_count()}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "fake_machine.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

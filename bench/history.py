"""Bench: the campaign store (issue 27). Importing 1,000 campaign directories into a new SQLite
store, and the trend of an axis over them, each against reading the same directories alone
(meta.json, runs.jsonl and the point table of each: what any tool must read).

The 1,000 directories are 12 simulated re-checks of the demo axis (campaign/history/simulated.py),
each copied with its own date and start record (a campaign of its own to the store). Writes
bench/results/history.json.

    .venv/bin/python bench/history.py [--campaigns N]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import shutil
import tempfile
import time
from pathlib import Path

from campaign.history.axis import axis_trend
from campaign.history.recording import record_campaign
from campaign.history.simulated import simulate_history
from campaign.history.store import open_store
from campaign.pointtable import read_points
from campaign.record import open_campaign

RESULTS = Path(__file__).parent / "results"


def make_directories(root: Path, count: int) -> list[Path]:
    _, bases = simulate_history(root / "bases", campaigns=12, machine="bench-history")
    start = dt.datetime(2000, 1, 1)
    made = []
    for i in range(count):
        base, target = bases[i % len(bases)], root / "campaigns" / f"c{i:04d}"
        shutil.copytree(base, target)
        meta = json.loads((target / "meta.json").read_text())
        meta["created"] = (start + dt.timedelta(days=7 * i)).isoformat() + "+00:00"
        (target / "meta.json").write_text(json.dumps(meta, indent=1) + "\n")
        runs = (target / "runs.jsonl").read_text().splitlines()
        first = json.loads(runs[0])
        first["pid"] = 100000 + i
        (target / "runs.jsonl").write_text("\n".join([json.dumps(first), *runs[1:]]) + "\n")
        lines = (target / "points.csv").read_text().splitlines()
        for n, line in enumerate(lines):  # a measurement of its own: deviations moved by i·0.01 µm
            cells = line.split(",")
            if line[:1].isdigit():
                cells[3] = repr(float(cells[3]) + 0.01 * i)
                lines[n] = ",".join(cells)
        (target / "points.csv").write_text("\n".join(lines) + "\n")
        made.append(target)
    return made


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", type=int, default=1000)
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench-history-"))
    try:
        dirs = make_directories(root, args.campaigns)
        t0 = time.perf_counter()
        for d in dirs:
            open_campaign(d)
            read_points(d / "points.csv")
        read_s = time.perf_counter() - t0
        store = open_store(f"sqlite:///{root / 'history.sqlite'}")
        t0 = time.perf_counter()
        outcomes = [record_campaign(store, d)[1] for d in dirs]
        import_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        again = [record_campaign(store, d)[1] for d in dirs]
        reimport_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        trend = axis_trend(store.campaigns("bench-history", "X"), "bench-history", "X")
        trend_s = time.perf_counter() - t0
        store.close()
    finally:
        shutil.rmtree(root, ignore_errors=True)
    assert outcomes.count("added") == args.campaigns and again.count("unchanged") == args.campaigns
    result = {"campaigns": args.campaigns, "read_dirs_s": round(read_s, 3), "import_s": round(import_s, 3),
              "reimport_s": round(reimport_s, 3), "trend_s": round(trend_s, 3),
              "trend_campaigns": len(trend.counted), "import_ratio": round(import_s / read_s, 2),
              "trend_ratio": round(trend_s / read_s, 2)}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "history.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The plant at a glance on a plant-sized store (issue 30, item 4): 50 machines × 3 axes × 20
campaigns (3000 re-checks drawn as campaign/history/simulated.py `draw_history` draws them,
recorded straight into the store; TEMPLATES distinct histories, copied), then `axiscal history plant --json` and `--html FILE` timed
as a user runs them (a new process each, its start-up included) and in-process (the store read,
150 trends, the page). Goal: under 2 s on PostgreSQL.

    .venv/bin/python bench/history_plant.py [--machines 50] [--sqlite]

On PostgreSQL (default) a throwaway server is started (tests/pg_server.py: Debian's postgresql).
Prints the timings; writes nothing else.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import io
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np

from campaign.cli import main as axiscal
from campaign.history.simulated import draw_history, drawn_entries
from campaign.history.store import open_store

TEMPLATES = 12
"""Distinct axis histories simulated; the plant's 150 axes are copies of them under their own
machine names, keys and dates (the trend's work is the same as for 150 distinct ones; simulating
3000 campaigns would take minutes)."""


def fill(url: str, machines: int, axes: int, campaigns: int) -> float:
    """Record the plant's history; returns the seconds it took."""
    import dataclasses

    rng = np.random.default_rng(50)
    end = dt.datetime.now(dt.UTC).replace(tzinfo=None, microsecond=0) - dt.timedelta(days=10)
    templates = [drawn_entries(draw_history(rng, end, rechecks=(campaigns, campaigns), years=(3.0, 5.0)), "t", "X",
                               float(rng.choice([15.0, 25.0, 40.0]))) for _ in range(TEMPLATES)]
    start = time.perf_counter()
    with open_store(url) as store:
        for m in range(machines):
            for a, axis in enumerate("XYZ"[:axes]):
                shift = dt.timedelta(days=int(rng.integers(0, 300)))
                for entry in templates[(m * axes + a) % TEMPLATES]:
                    values = {**entry.values, "machine": f"machine-{m:02d}", "axis": axis,
                              "key": f"{entry.values['key']}-{m}-{axis}", "measured_utc": entry.values["measured_utc"] - shift}
                    store.put(dataclasses.replace(entry, values=values))
    return time.perf_counter() - start
def timed_process(*args: str, env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "campaign", *args], cwd=ROOT, env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - start


def timed_in_process(*args: str) -> float:
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = axiscal(list(args))
    assert code == 0
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--machines", type=int, default=50)
    parser.add_argument("--sqlite", action="store_true", help="a SQLite file instead of PostgreSQL")
    args = parser.parse_args()
    stop = None
    with tempfile.TemporaryDirectory() as tmp:
        if args.sqlite:
            url = f"sqlite:///{Path(tmp) / 'plant.sqlite'}"
        else:
            from tests.pg_server import start_server

            server, why, stop = start_server()
            if server is None:
                raise SystemExit(why)
            url = server.new_database()
        try:
            filled = fill(url, args.machines, 3, 20)
            print(f"recorded {args.machines} machines × 3 axes × 20 campaigns in {filled:.1f} s")
            env = {**os.environ, "AXISCAL_DB": url, "XDG_DATA_HOME": str(Path(tmp) / "xdg")}
            os.environ.update(env)
            page = Path(tmp) / "plant.html"
            for label, argv in (("history plant --json", ("history", "plant", "--json")),
                                ("history plant --html", ("history", "plant", "--html", str(page)))):
                runs = [timed_process(*argv, env=env) for _ in range(3)]
                inside = [timed_in_process(*argv) for _ in range(3)]
                print(f"{label}: {min(runs):.2f} s as a command (best of 3; start-up included), "
                      f"{min(inside):.2f} s in-process")
            print(f"page: {page.stat().st_size / 1024:.0f} KiB")
        finally:
            if stop is not None:
                stop()  # type: ignore[operator]


if __name__ == "__main__":
    main()

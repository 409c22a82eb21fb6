"""Bench: discovery on a dense table (issue 34 item 4): a continuous scan gives tens of thousands of
positions. A point table of ROWS rows (targets 0.06 mm apart over 600 mm, both directions, 5 runs,
a time column; a 1 µm, 10 mm screw lead, a bow and 0.3 µm of noise) is written as CSV; then, each
in a fresh process, the table is read (campaign.pointtable.read_points) and discovered
(`axiscal discover` on it). Reports the rows, the wall and CPU time and the peak resident memory of
each, the ratios of the discovery's times to the reading's, and the load average (on a shared
machine the wall time counts the others' work too), and OPENBLAS_NUM_THREADS as set (the children
inherit it; unset, `axiscal` takes one thread: OpenBLAS's own threads spin on the fits' small
products and multiply the CPU time). Writes bench/results/discovery_dense.json. `--local bump` or
`--local step` adds a local error the table was not built with (a 3 µm Gaussian bump at 300 mm, σ
20 mm; a 2.5 µm logistic step at 420 mm, scale 3 mm), which wakes the local search, its routes and the
shape rivals; it writes discovery_dense-bump.json or …-step.json. `--local random --seed S` draws
one at random (random_local: a bump or a step, 2–4 µm of either sign, 5–150 mm wide, centred in
50–550 mm) on the table with noise of that seed; it writes discovery_dense-random-S.json.
`--runs R --travel L` change the table's shape (R runs over L mm: with the rows fixed, fewer runs and a
longer travel give more distinct positions, as a long scan binned finely does; a random local error is
then centred within 50 mm of the ends); the file name gets -runsR-travelL.

    .venv/bin/python bench/discovery_dense.py [--rows N] [--local none|bump|step|random] [--seed S]
                                              [--runs R] [--travel L]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from campaign.pointtable import PointTable, write_points

RESULTS = Path(__file__).parent / "results"


LOCAL_ERRORS = {
    "none": lambda x: 0.0 * x,
    "bump": lambda x: 3.0 * np.exp(-0.5 * ((x - 300.0) / 20.0) ** 2),
    "step": lambda x: 2.5 / (1 + np.exp(-(x - 420.0) / 3.0)),
}
"""The local error added to the table (µm, of position in mm), by --local."""


def random_local(seed: int, travel_mm: float = 600.0) -> tuple[str, Callable[[np.ndarray], np.ndarray]]:
    """A local error drawn at random (`seed`) on a travel of `travel_mm`: a Gaussian bump `width` wide at
    half its height, or a logistic step rising over `width` (10 to 90 %); its description and its
    deviation (µm) of position."""
    rng = np.random.default_rng(seed)
    kind = str(rng.choice(["bump", "step"]))
    at, width = rng.uniform(50, travel_mm - 50), float(np.exp(rng.uniform(np.log(5), np.log(150))))
    height = rng.uniform(2, 4) * rng.choice([-1, 1])
    said = f"{kind} of {height:+.2f} µm at {at:.1f} mm, {width:.1f} mm wide"
    if kind == "bump":
        return said, lambda x: height * np.exp(-4 * np.log(2) * ((x - at) / width) ** 2)
    return said, lambda x: height / (1 + np.exp(-(x - at) * 2 * np.log(9) / width))


def dense_table(rows: int, seed: int = 1, local: str | Callable[[np.ndarray], np.ndarray] = "none",
                runs: int = 5, travel_mm: float = 600.0) -> PointTable:
    """`rows` points: targets over `travel_mm`, both directions, `runs` runs, in campaign order; with the
    local error `local` (a name of LOCAL_ERRORS, or a deviation of position) added."""
    targets = np.linspace(0.0, travel_mm, max(rows // (2 * runs), 2))
    run, direction, target = [], [], []
    for r in range(1, runs + 1):
        for sign, order in ((1, targets), (-1, targets[::-1])):
            run += [r] * len(order)
            direction += [sign] * len(order)
            target += list(order)
    x, d = np.array(target), np.array(direction)
    u = 2 * x / travel_mm - 1
    rng = np.random.default_rng(seed)
    y = (np.sin(2 * np.pi * x / 10.0 + 0.3) + 0.5 * (3 * u**2 - 1) / 2 - d * 0.75 + rng.normal(0, 0.3, len(x))
         + (LOCAL_ERRORS[local] if isinstance(local, str) else local)(x))
    return PointTable(kind="linear", run=np.array(run), direction=d, target=x, deviation=y,
                      optional={"time_s": np.arange(len(x)) * 0.05}, meta={}, source="<dense>")


def timed(code: str) -> tuple[float, float, float, str]:
    """Wall time (s), CPU time (s, user + system), peak resident memory (MB) and output of `code` run
    in a fresh Python (the child reports its own peak: getrusage of the children would give the
    largest child so far)."""
    code += ("\nimport resource, sys\nu = resource.getrusage(resource.RUSAGE_SELF)\n"
             "print(f'@@ {u.ru_utime + u.ru_stime} {u.ru_maxrss / 1024}', file=sys.stderr)")
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    wall = time.perf_counter() - started
    cpu, peak = (float(v) for v in done.stderr.rsplit("@@ ", 1)[1].split())
    return wall, cpu, peak, done.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=100_000)
    parser.add_argument("--local", choices=[*sorted(LOCAL_ERRORS), "random"], default="none")
    parser.add_argument("--seed", type=int, default=1, help="the table's noise, and with --local random the draw")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--travel", type=float, default=600.0, help="mm")
    args = parser.parse_args()
    drawn, local = random_local(args.seed, args.travel) if args.local == "random" else ("", args.local)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "dense.csv"
        write_points(path, dense_table(args.rows, seed=args.seed, local=local, runs=args.runs, travel_mm=args.travel))
        read_s, read_cpu, read_mb, _ = timed(f"from campaign.pointtable import read_points; read_points({str(path)!r})")
        disc_s, disc_cpu, disc_mb, said = timed(f"from campaign.cli import main; main(['discover', {str(path)!r}])")
    load = os.getloadavg()[0]
    out = {"rows": args.rows, "runs": args.runs, "travel_mm": args.travel, "local": args.local, "seed": args.seed, "drawn": drawn, "read_s": round(read_s, 2), "read_cpu_s": round(read_cpu, 2), "read_peak_mb": round(read_mb),
           "discover_s": round(disc_s, 2), "discover_cpu_s": round(disc_cpu, 2), "discover_peak_mb": round(disc_mb),
           "ratio": round(disc_s / read_s, 1), "cpu_ratio": round(disc_cpu / read_cpu, 1),
           "load_average": round(load, 1), "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "1 (axiscal's default)"),
           "said": said.splitlines()[:6]}
    RESULTS.mkdir(exist_ok=True)
    name = "discovery_dense" + ("" if args.local == "none" else f"-{args.local}") + (
        f"-{args.seed}" if args.local == "random" else "") + (
        "" if (args.runs, args.travel) == (5, 600.0) else f"-runs{args.runs}-travel{args.travel:g}")
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()

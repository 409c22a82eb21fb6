"""Bench: `axiscal import-stream` on a 5-million-sample stream.

Goal (issue 5): segmentation and extraction together cost at most 1.5 x the time pandas.read_csv
takes to parse the same file. The stream is synthetic (campaign/stream/synth.py): the demo plan
(11 targets, 5 runs, 4 s dwell) sampled fast enough to give about 5 million samples, with noise,
trapezoidal moves and a 2.5 s stop at each overrun (recognised and skipped). Each side is timed
several times; the medians are compared. Writes bench/results/import_stream.json.

    .venv/bin/python bench/import_stream.py [--samples N] [--repeats R]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from campaign.commands.demo import demo_config_text
from campaign.config import parse_config
from campaign.plan import build_plan, estimate_duration_s
from campaign.stream.importer import extract_points
from campaign.stream.reader import stream_from_frame
from campaign.stream.synth import synthetic_stream

RESULTS = Path(__file__).resolve().parent / "results" / "import_stream.json"
GOAL = 1.5


def median_time(action, repeats: int) -> tuple[float, object]:
    """Median wall time of `action()` over `repeats` runs (s), and its last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = action()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=5_000_000, help="stream length (default 5e6)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per side (default 5)")
    args = parser.parse_args()
    config = parse_config(demo_config_text(), "demo.toml")
    plan = build_plan(config)
    overrun_dwell_s = 2.5
    duration = estimate_duration_s(plan, config.axis) + overrun_dwell_s * (config.plan.cycles * 2 + 1)
    rate_hz = args.samples / duration
    frame, truth = synthetic_stream(plan, config, rate_hz, seed=5, overrun_dwell_s=overrun_dwell_s)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "stream.csv"
        frame.to_csv(path, index=False, float_format="%.7f")
        size_mb = path.stat().st_size / 1e6
        print(f"stream: {len(frame)} samples at {rate_hz:.0f} Hz, {size_mb:.0f} MB")
        read_s, parsed = median_time(lambda: pd.read_csv(path), args.repeats)

    def segment_and_extract():
        stream = stream_from_frame(parsed, str(path), "reading_mm")
        return extract_points(stream, plan, config, still_tolerance=5.0)

    import_s, result = median_time(segment_and_extract, args.repeats)
    error_um = float(np.max(np.abs(result.table.deviation - truth * 1000)))
    ratio = import_s / read_s
    verdict = "meets" if ratio <= GOAL else "misses"
    print(f"pandas.read_csv: {read_s:.3f} s (median of {args.repeats})")
    print(f"segmentation + extraction: {import_s:.3f} s (median of {args.repeats})")
    print(f"ratio: {ratio:.3f} ({verdict} the goal <= {GOAL}); {len(result.table)} points, "
          f"{result.overrun_stops} overrun stops, largest deviation error {error_um:.3f} um")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "samples": len(frame), "rate_hz": rate_hz, "file_mb": round(size_mb, 1), "repeats": args.repeats,
        "read_csv_s": read_s, "segment_extract_s": import_s, "ratio": ratio, "goal": GOAL,
        "meets_goal": ratio <= GOAL, "points": len(result.table), "overrun_stops": result.overrun_stops,
        "max_deviation_error_um": error_um, "python": platform.python_version(),
        "pandas": pd.__version__, "numpy": np.__version__, "machine": platform.machine(),
    }, indent=1) + "\n")
    print(f"written to {RESULTS}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

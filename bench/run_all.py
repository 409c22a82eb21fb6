"""Run every benchmark and print the ratios the README quotes (`make bench`).

Each script writes its own bench/results/NAME.json; this one runs them in turn and writes
bench/results/summary.md. Wall-clock results depend on the machine: run on an otherwise idle
2-core machine.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).parent
SCRIPTS = ("demo_wall_time.py", "stable_vs_dwell.py", "compensation.py", "import_stream.py")


def main() -> int:
    for script in SCRIPTS:
        print(f"== {script}", flush=True)
        subprocess.run([sys.executable, str(HERE / script)], check=True)
    r = {name: json.loads((HERE / "results" / f"{name}.json").read_text())
         for name in ("demo_wall_time", "stable_vs_dwell", "compensation", "import_stream")}
    comp = r["compensation"]["axes"]
    demo, stable = r["demo_wall_time"], r["stable_vs_dwell"]
    lines = ["| goal | measured | ratio (goal) |", "|---|---|---|"]
    lines.append(f"| paper campaign in `axiscal demo` ≤ 10 s wall | {demo['wall_s_median']:.2f} s "
                 f"for {demo['simulated_s']:.0f} s simulated | {demo['ratio_to_goal']:.2f} (≤ 1) |")
    lines.append(f"| stable trigger / 4 s dwell, campaign duration | median of {len(stable['runs'])} seeds | "
                 f"{stable['duration_ratio_median']:.2f} (≤ 0.5) |")
    lines.append(f"| stable trigger vs dwell, A agrees | worst {stable['A_difference_pct_max']:.1f} % | (≤ 5 %) |")
    for axis, c in comp.items():
        lines.append(f"| {axis} axis, A after compensation / floor | A {c['A_after_median_um']:.2f} µm, "
                     f"floor {c['floor_median_um']:.2f} µm (paper: A {c['paper_A_after_um']} µm) | "
                     f"{c['ratio_median']:.2f} median, {c['ratio_max']:.2f} worst (≤ 1.1) |")
    imp = r["import_stream"]
    lines.append(f"| import-stream segmentation + extraction / pandas.read_csv, {imp['samples'] / 1e6:.1f} M samples | "
                 f"{imp['segment_extract_s']:.3f} s vs {imp['read_csv_s']:.3f} s | {imp['ratio']:.2f} (≤ 1.5) |")
    text = "\n".join(lines) + "\n"
    (HERE / "results" / "summary.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

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
SCRIPTS = (("demo_wall_time.py",), ("stable_vs_dwell.py",), ("compensation.py",),
           ("compensation.py", "--smooth", "none"), ("compensation.py", "--cycles", "10"), ("import_stream.py",),
           ("smoothing.py",), ("startup.py",), ("history.py",), ("fake_machine.py",), ("scan.py",),
           ("discovery_draws.py",), ("history_drawn.py",), ("history_plant.py",), ("history_seeds.py",),
           ("scan_run.py",), ("discovery_dense.py",), ("discovery_follow_up.py",), ("scan_rest_step.py",))
"""Each benchmark script with its options, run in turn. The last nine print their figures (scan,
scan_run, discovery_draws, discovery_dense, discovery_follow_up and scan_rest_step also write bench/results/*.json; history_drawn and
history_plant only print); the summary quotes the others."""
SEPARATE: dict[str, str] = {"discovery_gaps.py": "a diagnosis, run by hand on chosen cells and seeds: which draws of discovery_draws.py end above 1.3 × the noise, and why (it writes no result)"}
"""The benchmark scripts `make bench` does not run, and why."""
COMPENSATION = (("compensation", "5-run campaigns"),
                ("compensation-raw-means", "5-run campaigns, table from the raw means (`--smooth none`)"),
                ("compensation-10-runs", "10-run campaigns"))
"""Result file -> what its rows say; the perfect-table reference follows the rows of each design."""


def main() -> int:
    if "--summary-only" not in sys.argv:  # --summary-only: rebuild summary.md from stored results
        run_scripts()
    return summarise()


def run_scripts() -> None:
    for script, *options in SCRIPTS:
        print(f"== {script} {' '.join(options)}", flush=True)
        subprocess.run([sys.executable, str(HERE / script), *options], check=True)


def summarise() -> int:
    r = {name: json.loads((HERE / "results" / f"{name}.json").read_text())
         for name in ("demo_wall_time", "stable_vs_dwell", "import_stream", "startup", "history", "fake_machine")}
    demo, stable = r["demo_wall_time"], r["stable_vs_dwell"]
    lines = ["| goal | measured | ratio (goal) |", "|---|---|---|"]
    lines.append(f"| paper campaign in `axiscal demo` ≤ 10 s wall | {demo['wall_s_median']:.2f} s "
                 f"for {demo['simulated_s']:.0f} s simulated | {demo['ratio_to_goal']:.2f} (≤ 1) |")
    lines.append(f"| stable trigger on the demo axis, default settings: waiting / 4 s dwell | worst of "
                 f"{len(stable['runs'])} seeds; campaign duration {stable['duration_ratio_median']:.2f} (median) | "
                 f"{stable['wait_ratio_max']:.2f} (≤ 0.5) |")
    lines.append(f"| stable trigger vs dwell on the demo axis, A agrees | worst {stable['A_difference_pct_max_abs']:.1f} % "
                 f"of {len(stable['runs'])} seeds | (≤ 5 %) |")
    results = [json.loads((HERE / "results" / f"{name}.json").read_text()) for name, _ in COMPENSATION]
    for i, ((_, label), result) in enumerate(zip(COMPENSATION, results, strict=True)):
        for axis, c in result["axes"].items():
            verdict = "met" if c["ratio_median"] <= 1.1 else "NOT met"
            lines.append(f"| {axis} axis, {label}: A after compensation / floor | "
                         f"A {c['A_after_median_um']:.2f} µm, floor {c['floor_median_um']:.2f} µm "
                         f"(paper: A {c['paper_A_after_um']} µm) | {c['ratio_median']:.3f} median ({verdict}), "
                         f"{100 * c['share_above_goal']:.0f} % of {result['seeds']} seeds above 1.1, "
                         f"worst {c['ratio_max']:.2f} |")
        if i + 1 == len(results) or results[i + 1]["cycles"] != result["cycles"]:  # after each design's rows
            p = result["perfect_table"]
            lines.append(f"| for reference, {result['cycles']}-run campaigns with a perfect table (no systematic "
                         f"error) | the measurement alone | {p['ratio_median']:.3f} median, "
                         f"{100 * p['share_above_goal']:.0f} % of campaigns above 1.1, "
                         f"{p['ratio_p90']:.2f} at the 90th percentile |")
    imp = r["import_stream"]
    lines.append(f"| import-stream segmentation + extraction / pandas.read_csv, {imp['samples'] / 1e6:.1f} M samples | "
                 f"{imp['segment_extract_s']:.3f} s vs {imp['read_csv_s']:.3f} s | {imp['ratio']:.2f} (≤ 1.5) |")
    start = r["startup"]
    slowest = max(start["command_help_s"].items(), key=lambda kv: kv[1])
    lines.append(f"| `axiscal --help` start-up / bare `python -c pass` | {start['axiscal_help_s'] * 1000:.0f} ms vs "
                 f"{start['python_pass_s'] * 1000:.0f} ms; slowest `axiscal {slowest[0]} --help` "
                 f"{slowest[1] * 1000:.0f} ms | {start['ratio']:.1f} (≤ {start['goal_ratio']:g}) |")
    h = r["history"]
    lines.append(f"| history: importing {h['campaigns']} campaign directories into a new SQLite store / reading them "
                 f"alone | {h['import_s']:.1f} s vs {h['read_dirs_s']:.1f} s (again, unchanged: {h['reimport_s']:.1f} s) "
                 f"| {h['import_ratio']:.1f} (seconds, not minutes) |")
    lines.append(f"| history: the trend of one axis over {h['trend_campaigns']} campaigns / reading the directories "
                 f"alone | {h['trend_s']:.2f} s vs {h['read_dirs_s']:.1f} s | {h['trend_ratio']:.2f} (seconds, not minutes) |")
    f = r["fake_machine"]
    lines.append(f"| paper campaign in `axiscal demo --fake` (in-process fake machine) ≤ 1 s wall | "
                 f"{f['command_wall_s_median']:.2f} s; the campaign alone {f['campaign_alone_s_median']:.2f} s, "
                 f"{f['per_point_ms']:.1f} ms per point (load average {f['load_average_1min']:g} on {f['cores']} cores) | "
                 f"{f['ratio_to_goal']:.2f} (≤ 1) |")
    text = "\n".join(lines) + "\n"
    (HERE / "results" / "summary.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Bench: what the follow-up shows of the drawn errors the first campaign did not state (issue 34 items 6, 8).

The draws of bench/discovery_draws.py (same generator, seeds and plans). For each visible draw that the
first campaign neither locates nor states, as a user would: `axiscal discover points.csv --follow-up`,
each campaign it writes run on the fast simulator (the same machine, another noise seed), then all the
campaigns discovered together and judged as the first was (tests/discovery_draws.py: located, stated,
a name the machine lacks). A follow-up that is a scan is not run (the fast simulator models the dwell
capture only; the scan loop runs on the simulated machine in tests/test_discovery_loop_machine.py).
Also the follow-up's machine time against the first campaign's. Writes
bench/results/discovery_follow_up.json (or --out).

    .venv/bin/python bench/discovery_follow_up.py [--draws N] [--seed S] [--out FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from discovery_draws import draw_seeds

from campaign.cli import main as axiscal
from campaign.commands.discover import read_tables
from campaign.config import load_config
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from campaign.pointtable import write_points
from tests.discovery_draws import PLAN, SHAPES, Truth, draw, judge, plan_config

RESULTS = Path(__file__).parent / "results"
START = ErrorModel({"linear_scale": {}})


def followed(truth: Truth, count: int, offsets: str, seed: int, directory: Path) -> dict:
    """The first campaign, its follow-up and the joint discovery of one draw: what each said."""
    first = directory / "first"
    first.mkdir()
    (first / "config.toml").write_text(PLAN.format(count=count, offsets=offsets), encoding="utf-8")
    config = load_config(first / "config.toml")
    write_points(first / "points.csv", simulate_campaign(config, ErrorModel(truth.model), seed=seed, dwell_jitter=0.8))
    data, *_ = read_tables([str(first / "points.csv")])
    alone = judge(discover(data, START, {"linear_scale": set()}), truth)
    row: dict = {"seed": seed, "shape": truth.shape, "targets": count, "offsets": offsets, "first": alone.said}
    if not truth.visible or alone.stated:
        return {**row, "followed": False}
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        axiscal(["discover", str(first / "points.csv"), "--follow-up", "-o", str(directory / "follow.toml"), "--json"])
    follow = json.loads(printed.getvalue()).get("follow_up")
    row["followed"] = True
    if not follow or not follow["campaigns"]:  # nothing planned (each group said in its "unplanned")
        return {**row, "follow_up": None}
    row["follow_up"] = {"seconds": follow["duration_s"], "first_seconds": follow["first_duration_s"],
                        "captures": [c["capture"] for c in follow["campaigns"]]}
    if any(c["capture"] == "scan" for c in follow["campaigns"]):
        return row  # not run here: see the docstring
    tables = [str(first / "points.csv")]
    for i, campaign in enumerate(follow["campaigns"]):
        config = load_config(Path(campaign["file"]))
        tables.append(str(directory / f"second-{i}.csv"))
        write_points(tables[-1], simulate_campaign(config, ErrorModel(truth.model), seed=seed + 100 + i,
                                                   dwell_jitter=config.plan.dwell_jitter))
    data, *_ = read_tables(tables)
    both = judge(discover(data, START, {"linear_scale": set()}), truth)
    return {**row, "located": both.located, "stated": both.stated, "false_names": both.false_names,
            "said": both.said}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=4, help="draws per shape and plan")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS / "discovery_follow_up.json")
    args = parser.parse_args()
    started = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for shape in SHAPES:
            for count in (11, 17, 21):
                for offsets in ("golden", "none"):
                    for seed in draw_seeds(args.seed, args.draws, count, offsets):
                        truth = draw(np.random.default_rng(seed), shape, plan_config(count, offsets))
                        row = followed(truth, count, offsets, seed, Path(tempfile.mkdtemp(dir=scratch)))
                        if row["followed"]:
                            rows.append(row)
                            print(json.dumps(row), flush=True)
    run = [r for r in rows if "located" in r]
    total = {"missed_first": len(rows), "no_follow_up": sum(r["follow_up"] is None for r in rows),
             "scans_not_run": sum(r["follow_up"] is not None and "located" not in r for r in rows),
             "run": len(run), "located": sum(r["located"] for r in run), "stated": sum(r["stated"] for r in run),
             "false_names": sum(bool(r["false_names"]) for r in run),
             "over_budget": sum(r["follow_up"]["seconds"] > r["follow_up"]["first_seconds"] for r in run)}
    args.out.parent.mkdir(exist_ok=True)
    args.out.write_text(json.dumps({"draws_per_cell": args.draws, "seed": args.seed,
                                    "seconds": round(time.perf_counter() - started, 1), "totals": total,
                                    "rows": rows}, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(total))


if __name__ == "__main__":
    main()

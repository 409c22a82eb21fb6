"""Bench: discovery on errors it was never taught (issue 34 item 8).

Random machines from tests/discovery_draws.py (an out-of-vocabulary error: a step, a symmetric or
skewed bump, two regions of either sign, a wave over part of the travel, a slope growing linearly in
time; 2-4 µm, 1-150 mm wide; beside a random bow, backlash and scale; noise 0.3-0.8 µm), on the 600 mm
test axis at 11, 17 and 21 targets, golden and uniform, 5 runs, recorded with the fast simulator; and
null machines (the vocabulary part alone). For each shape × plan: how many draws the targets can see
at all, how many of those are located (a region within its width, a step within 10 mm; a linear
drift named), how many stated (located, or a region in what the final model leaves; a linear growth:
the slope departing in time; or bracketed), and of those how many only bracketed: said to lie between
two neighbouring targets, as finely as the plan lets them be placed when that is coarser than 10 mm
(a step between the targets that hold it, one target's departure between its neighbours), how many name an effect the
machine lacks, how many end within 1.3 × the noise, of the draws not stated how many are beyond
what the campaign shows ("beyond": even the error's exact deviation at its true place, only its size
fitted, is not significant at p 0.001 beside the machine's vocabulary), and on the nulls how many leave a region along the
axis (not a reversal) in what the final model leaves. Each cell lists its draws that name an effect the machine
lacks ("false") and those neither located nor stated ("missed": the draw's generator seed, whether beyond
what the campaign shows, what was said). Writes bench/results/discovery_draws.json and the table quoted in docs/discovery.md.

    .venv/bin/python bench/discovery_draws.py [--draws N] [--seed S] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from campaign.discovery.data import campaign_data
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from tests.discovery_draws import SHAPES, draw, judge, named_out_of_gates, oracle_p, plan_config

RESULTS = Path(__file__).parent / "results"
ORACLE_ALPHA = 0.001
"""A draw not stated whose exact deviation, at its true place and shape, has an F-test p above this beside
the vocabulary the machine has (tests.discovery_draws.oracle_p) is beyond what the campaign shows: "beyond"."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=4, help="draws per shape and plan")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS / "discovery_draws.json",
                        help="where the JSON goes (another file lets seeds run side by side)")
    args = parser.parse_args()
    rows = []
    started = time.perf_counter()
    for shape in (*SHAPES, "null"):
        for count in (11, 17, 21):
            for offsets in ("golden", "none"):
                config = plan_config(count, offsets)
                tally = {"shape": shape, "targets": count, "offsets": offsets, "draws": 0, "visible": 0,
                         "located": 0, "stated": 0, "bracketed": 0, "seen": 0, "false_names": 0, "gap_within_1_3": 0,
                         "bad_names": 0, "regions_after": 0, "beyond": 0, "false": [], "missed": []}
                for seed in draw_seeds(args.seed, args.draws, count, offsets):
                    truth = draw(np.random.default_rng(seed), shape, config)
                    table = simulate_campaign(config, ErrorModel(truth.model), seed=seed, dwell_jitter=0.8)
                    data = campaign_data(table)
                    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
                    judged = judge(result, truth)
                    found_local = shape == "null" and bool(result.local_errors)
                    after = result.located_after.along if result.located_after is not None else []
                    tally["regions_after"] += any(r.direction != "opposite" for r in after)  # not a reversal
                    tally["draws"] += 1
                    tally["visible"] += truth.visible
                    tally["located"] += truth.visible and judged.located
                    tally["stated"] += truth.visible and judged.stated
                    tally["bracketed"] += truth.visible and judged.bracketed  # counted in stated too
                    tally["seen"] += truth.visible and judged.seen
                    if truth.visible and not judged.stated:  # could any method have shown it? (its exact shape known)
                        beyond = oracle_p(data, truth) > ORACLE_ALPHA
                        tally["beyond"] += beyond
                        tally["missed"].append({"seed": seed, "beyond": bool(beyond), "said": judged.said})
                    tally["bad_names"] += bool(named_out_of_gates(data, result))
                    tally["false_names"] += bool(judged.false_names) or found_local
                    tally["gap_within_1_3"] += judged.gap_ratio <= 1.3
                    if judged.false_names or found_local:
                        tally["false"].append({"seed": seed, "said": judged.said})
                rows.append(tally)
                print(shape, count, offsets, {k: v for k, v in tally.items() if k not in ("false", "missed")}, flush=True)
    args.out.parent.mkdir(exist_ok=True)
    out = {"draws_per_cell": args.draws, "seed": args.seed, "seconds": round(time.perf_counter() - started, 1),
           "versions": versions(), "totals": totals(rows), "rows": rows}
    args.out.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print("| shape | targets | golden: visible · seen · located · stated (of which bracketed) · false names · gap ≤ 1.3σ "
          "| uniform: the same |")
    print("|---|---|---|---|")
    for shape in (*SHAPES, "null"):
        for count in (11, 17, 21):
            cells = []
            for offsets in ("golden", "none"):
                r = next(r for r in rows if (r["shape"], r["targets"], r["offsets"]) == (shape, count, offsets))
                stated = f"{r['stated']}" + (f" ({r['bracketed']})" if r["bracketed"] else "")
                cells.append(f"{r['visible']}/{r['draws']} · {r['seen']} · {r['located']} · {stated} · "
                             f"{r['false_names']} · {r['gap_within_1_3']}")
            print(f"| {shape} | {count} | {cells[0]} | {cells[1]} |")
    print(json.dumps(out["totals"]))


def versions() -> dict[str, str]:
    """The numerical packages the rows were computed with: a draw at the edge of a test (a region just
    beyond its band, a gap ratio at 1.3) can change with their rounding, so rows are compared on the same."""
    import scipy

    return {"python": sys.version.split()[0], "numpy": np.__version__, "scipy": scipy.__version__}


def draw_seeds(seed: int, draws: int, count: int, offsets: str) -> list[int]:
    """The generator seeds of one cell's draws (the bench's seed `seed`, `draws` per cell)."""
    return [seed + 7919 * k + 31 * count + (0 if offsets == "none" else 1) for k in range(draws)]


def totals(rows: list[dict]) -> dict:
    """The sums over the out-of-vocabulary cells and over the nulls, with the shares the issue's goals
    are stated in."""
    oov = [r for r in rows if r["shape"] != "null"]
    nulls = [r for r in rows if r["shape"] == "null"]
    total = {k: sum(r[k] for r in oov) for k in ("draws", "visible", "seen", "located", "stated", "bracketed",
                                                  "false_names", "gap_within_1_3", "bad_names", "beyond")}
    total["no_false_share"] = round(1 - total["false_names"] / max(total["draws"], 1), 4)
    total["nulls"] = {k: sum(r[k] for r in nulls) for k in ("draws", "false_names", "bad_names", "regions_after")}
    return total


if __name__ == "__main__":
    main()

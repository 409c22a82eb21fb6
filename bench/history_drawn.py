"""The trend's acceptance on histories drawn at random (issue 30, item 1): N axis histories drawn
the way plants make them (campaign/history/simulated.py `draw_history`: drift 1–5 µm/m a year,
300–1000 mm, 11–21 targets, noise 0.3–1 µm, 11–14 re-checks over 1.5–2.5 years at irregular
dates, one reversal jump), each re-check simulated and recorded into a store (a new SQLite file,
or --db URL: a PostgreSQL database), then `history trend`'s A drift compared with the truth:

- coverage: the rate's 95 % interval contains the true rate (goal: at least 90 %);
- Birge ratio of A's fit, median (goal: 0.7 to 1.4);
- significance: a drift of 2 µm/m a year on a 1 m axis, 12 re-checks in 2 years (the other
  draws as above, with the reversal jump, and without it): significant in at least 90 %.

Each figure also for the weights used before (the budget's random terms, `--old`), for
comparison. Prints one line per history and the figures; writes nothing else.

    .venv/bin/python bench/history_drawn.py [--histories 100] [--seed 30] [--db URL | --postgres]
"""

from __future__ import annotations

import argparse
import datetime as dt
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np

from campaign.history.axis import axis_trend
from campaign.history.simulated import DrawnHistory, draw_history, record_drawn
from campaign.history.store import Store, open_store

END = dt.datetime(2026, 6, 1)


def judged(store: Store, history: DrawnHistory, machine: str, old: bool = False) -> dict[str, Any]:
    """The A drift of one recorded history against its truth."""
    rows = store.campaigns(machine, "X")
    if old:  # the weights before issue 30: the budget's random terms
        for row in rows:
            row["recheck"] = {}
    a = axis_trend(rows, machine, "X").fits["A"]
    truth = history.true_rate_a()
    covered = a.rate is not None and a.U_rate is not None and abs(a.rate - truth) <= a.U_rate
    return {"truth": truth, "rate": a.rate, "U": a.U_rate, "covered": covered, "birge": a.birge,
            "significant": a.significant, "steps": len(a.step_at)}


def sample(store: Store, rng: np.random.Generator, n: int, prefix: str, **ranges: Any) -> list[tuple[dict, dict]]:
    out = []
    for i in range(n):
        history = draw_history(rng, END, **ranges)
        machine = f"{prefix}-{i}"
        record_drawn(store, history, machine)
        new, old = judged(store, history, machine), judged(store, history, machine, old=True)
        print(f"{machine}: {history.as_json()} true {new['truth']:+.2f} µm/year; new {new['rate']:+.2f} ± "
              f"{new['U']:.2f} birge {new['birge']:.2f} covered {new['covered']} significant {new['significant']}; "
              f"old {old['rate']:+.2f} ± {old['U']:.2f} birge {old['birge']:.2f}", flush=True)
        out.append((new, old))
    return out


def figures(results: list[dict]) -> str:
    n = len(results)
    covered = sum(r["covered"] for r in results)
    significant = sum(r["significant"] for r in results)
    birge = statistics.median(r["birge"] for r in results if r["birge"] is not None)
    return (f"coverage {covered}/{n} ({100 * covered / n:.0f} %), median Birge ratio {birge:.2f}, "
            f"significant {significant}/{n} ({100 * significant / n:.0f} %)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--histories", type=int, default=100)
    parser.add_argument("--seed", type=int, default=30)
    parser.add_argument("--db", help="a store URL (default: a new SQLite file)")
    parser.add_argument("--postgres", action="store_true",
                        help="a throwaway PostgreSQL server (tests/pg_server.py) instead of SQLite")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    stop = None
    with tempfile.TemporaryDirectory() as tmp:
        url = args.db or f"sqlite:///{Path(tmp) / 'drawn.sqlite'}"
        if args.postgres:
            from tests.pg_server import start_server

            server, why, stop = start_server()
            if server is None:
                raise SystemExit(why)
            url = server.new_database()
        try:
            figures_of(url, rng, args.histories)
        finally:
            if stop is not None:
                stop()  # type: ignore[operator]


def figures_of(url: str, rng: np.random.Generator, histories: int) -> None:
    """Draw, record and judge the histories; print the figures."""
    with open_store(url) as store:
        print(f"store: {store.display} ({store.engine.dialect.name})")
        drawn = sample(store, rng, histories, "drawn")
        fixed = sample(store, rng, histories, "two-per-year", rechecks=(12, 12), years=(2.0, 2.0),
                       growth=(2.0, 2.0), span=(1000.0, 1000.0))
        smooth = sample(store, rng, histories, "two-per-year-no-jump", rechecks=(12, 12), years=(2.0, 2.0),
                        growth=(2.0, 2.0), span=(1000.0, 1000.0), jump=(0.0, 0.0))
    print(f"drawn histories (n = {len(drawn)}), new weights: {figures([n for n, _ in drawn])}")
    print(f"drawn histories (n = {len(drawn)}), old weights: {figures([o for _, o in drawn])}")
    print(f"2 µm/m a year on 1 m, 12 re-checks in 2 years (n = {len(fixed)}), new weights: "
          f"{figures([n for n, _ in fixed])}")
    print(f"2 µm/m a year on 1 m, 12 re-checks in 2 years (n = {len(fixed)}), old weights: "
          f"{figures([o for _, o in fixed])}")
    print(f"the same without the jump (n = {len(smooth)}), new weights: {figures([n for n, _ in smooth])}")
    print(f"the same without the jump (n = {len(smooth)}), old weights: {figures([o for _, o in smooth])}")


if __name__ == "__main__":
    main()

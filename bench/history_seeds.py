"""Seed study of the history's acceptance (issue 27; review items 5 and 6): the simulated history
of `axiscal demo --history 12` with N noise seeds, each recorded into a new SQLite store, and its
trend checked against the truth as tests/test_history.py checks it (the same truth functions):

- drift: the rate of A and of E within its stated U of the true rate (covered) and significant
  (both: drift_ok);
- jump: B's only change point between re-checks 7 and 8, and no other parameter's elsewhere;
- crossing: predicted, and its interval containing the day the expected A + U reaches the history's tolerance (15 µm).

Prints each seed's numbers and the coverage of each criterion out of N; writes nothing else.

    .venv/bin/python bench/history_seeds.py [--seeds 20]
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from campaign.history.axis import axis_trend
from campaign.history.recording import record_campaign
from campaign.history.simulated import simulate_history
from campaign.history.store import open_store
from tests.test_history import true_crossing, true_drift


def one(seed: int, root: Path) -> dict:
    truth, dirs = simulate_history(root / f"h{seed}", campaigns=12, seed=seed, machine=f"seed-{seed}")
    with open_store(f"sqlite:///{root / f's{seed}.sqlite'}") as store:
        for d in dirs:
            record_campaign(store, d, "demo")
        trend = axis_trend(store.campaigns(f"seed-{seed}", "X"), f"seed-{seed}", "X").as_json()
    labels = [c["label"] for c in trend["campaigns"]]
    dates = [dt.date.fromisoformat(c["date"]) for c in trend["campaigns"]]
    t = truth.as_json()
    rate_a, rate_e = true_drift(t)
    out: dict = {"seed": seed}
    drift_ok = True
    for p, true_rate in (("A", rate_a), ("E", rate_e)):
        d = trend["drift"][p]
        covered = d["rate_per_year"] is not None and abs(d["rate_per_year"] - true_rate) <= d["U_rate_per_year"]
        out[f"{p}_covered"], out[f"{p}_significant"] = bool(covered), bool(d["significant"])
        out[p] = f"{d['rate_per_year']} ± {d['U_rate_per_year']} (true {true_rate:.2f}, k {d.get('k')}, birge {d.get('birge_ratio')})"
        drift_ok &= bool(covered and d["significant"])
    out["drift_ok"] = drift_ok
    pairs = [(j["parameter"], j["before"]["label"], j["after"]["label"]) for j in trend["change_points"]]
    b_jumps = [(a, b) for p, a, b in pairs if p == "B"]
    out["jumps"] = pairs
    out["jump_ok"] = b_jumps == [(labels[6], labels[7])] and all((a, b) == (labels[6], labels[7]) for _, a, b in pairs)
    c = trend["crossing"]
    true_day = true_crossing(t, dates[-1], t["tolerance_um"])
    out["crossing"] = f"{c['state']} {c['earliest']}..{c['latest']} (true {true_day})"
    if c["state"] == "predicted":
        latest = dt.date.fromisoformat(c["latest"]) if c["latest"] else dt.date.max
        out["crossing_ok"] = dt.date.fromisoformat(c["earliest"]) <= true_day <= latest
    else:
        out["crossing_ok"] = False
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.seeds + 1):
            row = one(seed, Path(tmp))
            rows.append(row)
            print(row, flush=True)
    for key in ("A_covered", "A_significant", "E_covered", "E_significant", "drift_ok", "jump_ok", "crossing_ok"):
        print(f"{key}: {sum(r[key] for r in rows)} of {len(rows)}")
    print(f"all three: {sum(r['drift_ok'] and r['jump_ok'] and r['crossing_ok'] for r in rows)} of {len(rows)}")


if __name__ == "__main__":
    main()

"""The trend sees a real drift (issue 30, item 1): each campaign is weighted by how much its A
would scatter between re-checks of an unchanged axis (campaign/history/recheck.py), checked on
histories drawn at random the way plants make them (campaign/history/simulated.py
`draw_history`), recorded into the store, not on one tuned history. bench/history_drawn.py
prints the same figures for more histories."""

from __future__ import annotations

import datetime as dt
import statistics

import numpy as np
import pytest

from tests.conftest import sweep
from tests.test_history import db  # noqa: F401 - the store fixture, SQLite and PostgreSQL

END = dt.datetime(2026, 6, 1)


@pytest.mark.parametrize("sigma", sweep(0.34, 0.8))
def test_recheck_u_is_the_scatter_of_a_between_rechecks(sigma):
    """On the demo axis (noise 0.34 and 0.8 µm): the mean re-check u of A from each campaign's own
    points is within 25 % of the real scatter of A over 30 simulated re-checks of the same axis;
    the budget's random terms, which the trend used before, were about twice it."""
    from campaign.assess import assess
    from campaign.config import config_with, plain
    from campaign.discovery.simulate import simulate_campaign
    from campaign.history.axis import u_random
    from campaign.history.recheck import recheck_u
    from campaign.history.simulated import demo_config, recheck_config
    from campaign.model import sim_model

    config = recheck_config(demo_config(), -8.0, 2.5, 7)
    effects = plain(config.sim.effects)
    effects["noise"]["sigma_um"] = sigma
    config = config_with(config, {"sim": {"effects": effects}})
    a, mine, budget = [], [], []
    for seed in range(30):
        table = simulate_campaign(config, sim_model(config.sim), seed=300 + seed)
        result = assess(table, config)
        a.append(result.evaluation.summary["A"])
        mine.append(recheck_u(table.run, table.direction, table.target, table.deviation)["A"])
        budget.append(u_random(result.uncertainty.as_json(), "A"))
    real = float(np.std(a, ddof=1))
    assert 0.75 < np.mean(mine) / real < 1.25, (sigma, np.mean(mine), real)
    assert np.mean(budget) / real > 1.6, (sigma, np.mean(budget), real)


def drawn_figures(url: str, histories: int, seed: int, **ranges: object) -> dict[str, float]:
    """Coverage, median Birge ratio and share significant of A's drift over `histories` drawn
    histories, each recorded into the store at `url` and trended from it."""
    from campaign.history.axis import axis_trend
    from campaign.history.simulated import draw_history, record_drawn
    from campaign.history.store import open_store

    rng = np.random.default_rng(seed)
    covered, significant, birge = 0, 0, []
    with open_store(url) as store:
        for i in range(histories):
            history = draw_history(rng, END, **ranges)
            machine = f"drawn-{seed}-{i}"
            record_drawn(store, history, machine)
            fit = axis_trend(store.campaigns(machine, "X"), machine, "X").fits["A"]
            truth = history.true_rate_a()
            covered += fit.rate is not None and abs(fit.rate - truth) <= (fit.U_rate or 0.0)
            significant += fit.significant
            birge.append(fit.birge)
    return {"coverage": covered / histories, "birge": statistics.median(b for b in birge if b is not None),
            "significant": significant / histories}


@pytest.mark.machine  # 40 histories of 11 to 14 simulated campaigns each: about a minute
def test_drawn_histories_cover_the_truth(db):  # noqa: F811
    """Drift 1–5 µm/m a year, 300–1000 mm, 11–21 targets, noise 0.3–1 µm, 11–14 re-checks at
    irregular dates, one reversal jump: the rate's 95 % interval contains the true rate in at
    least 90 % of them, and the median Birge ratio lies between 0.7 and 1.4 (0.46 with the
    budget's random terms as weights: the campaigns scattered half as much as they said)."""
    from campaign.history.location import store_url

    figures = drawn_figures(store_url(db) or "", 40, seed=30)
    assert figures["coverage"] >= 0.9, figures
    assert 0.7 <= figures["birge"] <= 1.4, figures


@pytest.mark.machine
def test_a_plant_drift_is_significant(db):  # noqa: F811
    """2 µm/m a year on a 1 m axis, 12 re-checks in 2 years at irregular dates, targets and noise
    drawn as above, no jump (the issue's case: '+1.13 ± 2.47 µm/year, no significant drift'
    before): significant in at least 90 %. With a reversal jump in the middle, which sets A's line
    apart in two segments of a year, it is significant in 78 to 88 % (bench/history_drawn.py):
    the noisiest draws (0.8 to 1 µm) cannot show 2 µm a year within a year's campaigns."""
    from campaign.history.location import store_url

    figures = drawn_figures(store_url(db) or "", 40, seed=31, rechecks=(12, 12), years=(2.0, 2.0),
                            growth=(2.0, 2.0), span=(1000.0, 1000.0), jump=(0.0, 0.0))
    assert figures["significant"] >= 0.9, figures
    assert figures["coverage"] >= 0.9, figures

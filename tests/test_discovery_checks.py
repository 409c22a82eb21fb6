"""The checks discovery makes of a named period and the figures it reports (issue 34): the one-target
test of a searched period charges the period's search once; zero_at_targets reads the form's full
columns and is skipped where the targets sample the period densely; a joint fit's gap and noise
weigh each table as the fit does. Machines drawn per seed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from campaign.config import parse_config
from campaign.discovery.data import campaign_data, join_campaigns
from campaign.discovery.fit import Term, linear_fit, weighted
from campaign.discovery.local import gap_um
from campaign.discovery.naming import one_target_p, zero_at_targets
from campaign.discovery.periodogram import independent_periods
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.discovery.vocabulary import pooled_scatter_um
from campaign.model import ErrorModel
from tests.discovery_draws import plan_config
from tests.test_discovery_period import FINE_PLAN


def _lead_machine(rng: np.random.Generator, period_mm: float) -> dict:
    return {"linear_scale": {"ppm": float(rng.uniform(-10, 10))},
            "periodic_lead": {"amplitude_um": float(rng.uniform(0.8, 1.5)), "period_mm": period_mm,
                              "phase_rad": float(rng.uniform(0, 2 * math.pi))},
            "noise": {"sigma_um": float(rng.uniform(0.2, 0.4))}}


def _lead_fit(data, period_mm: float, given: bool):
    """The scale and a lead at `period_mm`, searched (its period a fitted shape) or given (held)."""
    held = {"period_mm": period_mm} if given else {}
    scale = Term("linear_scale")
    without = linear_fit(data, [scale])
    return without, linear_fit(data, [scale, Term("periodic_lead", held, False, {"period_mm": period_mm})])


@pytest.mark.parametrize("seed", range(4))
def test_one_target_charges_a_searched_period_once(seed):
    """A lead drawn at random on the 21-target golden plan: the one-target test (its period held,
    the target it helps most left out) gives the p-value of the same lead with its period given,
    times the search's look-elsewhere factor, and only that: counted as a fitted parameter as well,
    the period was charged twice (the F-test's p is then larger than the given period's)."""
    rng = np.random.default_rng(400 + seed)
    config = plan_config(21, "golden")
    period = float(rng.uniform(8, 30))
    data = campaign_data(simulate_campaign(config, ErrorModel(_lead_machine(rng, period)), seed=400 + seed))
    factor = independent_periods(data)
    without, searched = _lead_fit(data, period, given=False)
    _, given = _lead_fit(data, period, given=True)
    p_searched, at = one_target_p(data, without, searched, "periodic_lead", factor)
    p_given, at_given = one_target_p(data, without, given, "periodic_lead", factor)
    assert at == at_given
    assert p_searched == pytest.approx(p_given, rel=1e-9, abs=1e-300)


@pytest.mark.parametrize("seed", range(3))
def test_zero_at_targets_reads_the_full_columns(seed):
    """A lead whose second column was dropped (collinear with the model: keep mask) has its
    coefficients in the form's full order, the dropped one 0: the check reads the full columns, and
    says what it says of the same wave with both columns kept and that coefficient 0."""
    rng = np.random.default_rng(500 + seed)
    period = float(rng.uniform(8, 30))
    data = campaign_data(simulate_campaign(plan_config(17, "golden"), ErrorModel(_lead_machine(rng, period)),
                                           seed=500 + seed))
    term = Term("periodic_lead", {}, False, {"period_mm": period}, keep=(True, False))
    fit = linear_fit(data, [Term("linear_scale"), term])
    assert fit.coefs[1][1] == 0.0
    whole = linear_fit(data, [Term("linear_scale"), Term("periodic_lead", {}, False, {"period_mm": period})])
    whole.coefs[1] = fit.coefs[1].copy()
    assert zero_at_targets(data, fit, "periodic_lead") == zero_at_targets(data, whole, "periodic_lead")


@pytest.mark.parametrize("seed", range(12))
def test_a_lead_sampled_densely_is_not_said_to_be_zero_at_the_targets(seed):
    """1,201 targets 0.05 mm apart over 60 mm (a dense table), a lead of 35 to 55 mm drawn at random: the targets follow
    the wave along its period, so its mean square there is that of the travel's part of the wave, not
    of random phases; zero_at_targets is skipped (its random-phase rule would call a lead whose travel
    holds a fraction of a period 'near zero at most targets': about one draw in five)."""
    rng = np.random.default_rng(600 + seed)
    period = float(rng.uniform(35, 55))
    config = parse_config(FINE_PLAN.format(count=1201, cycles=1))
    data = campaign_data(simulate_campaign(config, ErrorModel(_lead_machine(rng, period)), seed=600 + seed))
    _, fit = _lead_fit(data, period, given=False)
    assert zero_at_targets(data, fit, "periodic_lead") is None


def _joint(seed: int):
    """Two stop-and-go tables of one drawn machine (11 golden targets, 5 runs): the second with a
    five times larger noise, so each is weighed by its own repeatability."""
    rng = np.random.default_rng(700 + seed)
    machine = {"linear_scale": {"ppm": float(rng.uniform(-10, 10))},
               "backlash": {"b_um": float(rng.uniform(1, 3))},
               "local_defect": {"amplitude_um": float(rng.uniform(2, 4)), "centre_mm": float(rng.uniform(150, 450)),
                                "width_mm": float(rng.uniform(40, 80))}}
    sigma = float(rng.uniform(0.3, 0.5))
    parts = []
    for k, scale in enumerate((1.0, 5.0)):
        effects = {**machine, "noise": {"sigma_um": sigma * scale}}
        table = simulate_campaign(plan_config(11, "golden"), ErrorModel(effects), seed=700 + 10 * seed + k)
        parts.append(campaign_data(table))
    return join_campaigns(parts, ["fine.csv", "coarse.csv"]), parts


@pytest.mark.parametrize("seed", [0, *(pytest.param(s, marks=pytest.mark.machine) for s in (1, 2))])
def test_a_joint_fits_gap_and_noise_weigh_each_table_as_the_fit_does(seed):
    """Two tables of different repeatability fitted together: the reported gap is the fit's own
    weighted RSS over the sum of the weights (not the plain RMS, which the coarse table's noise
    fills), the noise is pooled with the same weights, and each table's own gap and noise are listed."""
    data, parts = _joint(seed)
    assert data.row_scale is not None
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    residual = data.y - result.final.prediction
    rss = float(np.sum(weighted(data, residual) ** 2))
    assert result.gap_after_um**2 * float(np.sum(data.row_scale**2)) == pytest.approx(rss, rel=1e-9)
    assert result.noise_um == pytest.approx(pooled_scatter_um(data, residual))
    plain = float(np.sqrt(np.mean(residual**2)))
    assert result.gap_after_um < plain  # the fine table, weighed most, is the closer one
    assert len(result.tables) == 2
    for c, part in enumerate(parts):
        keep = data.campaign_index == c
        assert result.tables[c].gap_um == pytest.approx(float(np.sqrt(np.mean(residual[keep] ** 2))), abs=1e-4)
    assert result.tables[0].noise_um < result.tables[1].noise_um
    # one table: the weighted figures are the plain ones
    alone = parts[0]
    fit = linear_fit(alone, [Term("linear_scale")])
    r = alone.y - fit.prediction
    assert gap_um(alone, r) == pytest.approx(float(np.sqrt(np.mean(r**2))))


@pytest.mark.parametrize("seed", [5, 6])
def test_a_registered_periodic_effect_is_searched_by_its_own_period_key(seed):
    """Issue 34 item 7: which effect is periodic, and which of its parameters is the period, is the
    effect's word (`Effect.period`), not a name written into discovery. A new effect registered with
    its period under another key (a gear's pitch) is searched over the periodogram as periodic_lead is:
    its candidate lists its optima and finds the lead's period; its unresolved entry carries its name."""
    from campaign.discovery.effects import PERIOD_KEY
    from campaign.discovery.naming import try_candidate
    from campaign.discovery.vocabulary import period_entry
    from campaign.effects import register, unregister
    from campaign.effects.base import SIZE_UM, Effect, EffectForm, period_limits

    def columns(data, shape, held):
        angle = 2 * np.pi * data.x / shape["pitch_mm"]
        return np.column_stack([np.sin(angle), np.cos(angle)])

    def to_params(c, shape, held):
        return {"size_um": float(math.hypot(c[0], c[1])), "pitch_mm": shape["pitch_mm"]}

    gear = Effect("gear_wave", 99, {"size_um": "amplitude, µm", "pitch_mm": "gear pitch, mm"}, None,
                  EffectForm("gear_wave", ("sin_um", "cos_um"), ("pitch_mm",), "target", columns, to_params,
                             sizes=("size_um",), ranges=lambda data: {"size_um": (0.0, SIZE_UM),
                                                                     "pitch_mm": period_limits(data)}),
                  period="pitch_mm")
    with pytest.raises(ValueError, match="not a shape parameter"):
        Effect("bad_wave", 99, {}, None, EffectForm("bad_wave", ("b_um",), (), "target", columns), period="pitch_mm")
    rng = np.random.default_rng(seed)
    period = float(rng.uniform(8.0, 12.0))
    table = simulate_campaign(parse_config(FINE_PLAN.format(count=61, cycles=3)),
                              ErrorModel(_lead_machine(rng, period)), seed=seed)
    data = campaign_data(table)
    register(gear)
    try:
        assert PERIOD_KEY["gear_wave"] == "pitch_mm" and PERIOD_KEY["periodic_lead"] == "period_mm"
        current = linear_fit(data, [Term("linear_scale")])
        cand = try_candidate(data, current, "gear_wave", [])
        assert cand.fit is not None and cand.periods, cand.verdict
        found = cand.fitted.params()["gear_wave"]["pitch_mm"]
        assert found == pytest.approx(period, rel=0.01) and cand.periods[0][0] == pytest.approx(found)
        assert period_entry(cand, data).effects == ("gear_wave",)
    finally:
        unregister("gear_wave")


def test_a_table_left_without_points_is_no_longer_one():
    """keep_rows numbers the tables anew: a fit of the rows of the second table alone has one
    table, and its offset is a number (the first table's was the mean of nothing, NaN, with numpy's
    warning)."""
    import warnings

    from campaign.discovery.data import keep_rows

    data, _ = _joint(0)
    second = keep_rows(data, data.campaign_index == 1)
    assert second.campaigns == 1 and set(second.campaign_index) == {0}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = linear_fit(second, [Term("linear_scale")])
    assert len(fit.offsets_um) == 1 and np.isfinite(fit.offsets_um).all()


@pytest.mark.machine  # one drawn campaign and its discovery, a few seconds
def test_no_local_error_is_larger_than_anything_the_campaign_shows():
    """A drawn bump (2.8 µm at 270 mm, 38 mm wide) beside a bow and a backlash on 17 golden targets: what
    the model left was held by a step of +1.6 µm and one of -39 µm between the same two targets, the
    second found beside the first where nothing checked its size (only the routes did). No local term
    of the final model, nor any local error said, is larger than twice the campaign's largest deviation
    from the starting model."""
    from campaign.discovery.rivals import LOCAL_LARGEST, beyond_the_campaign
    from tests.discovery_draws import draw

    config = plan_config(17, "golden")
    truth = draw(np.random.default_rng(16419), "bump", config)
    assert truth.model["local_defect"]["amplitude_um"] == pytest.approx(2.786, abs=1e-3)
    data = campaign_data(simulate_campaign(config, ErrorModel(truth.model), seed=16419, dwell_jitter=0.8))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    largest = float(np.max(np.abs(data.y - result.start.prediction)))
    assert result.local_errors, result.notes
    assert all(abs(e.size_um) <= LOCAL_LARGEST * largest for e in result.local_errors), \
        [e.sentence() for e in result.local_errors]
    assert not beyond_the_campaign(data, result.start, result.final), result.final.params()


@pytest.mark.machine  # one drawn campaign and its discovery, a few seconds
def test_a_route_the_bic_prefers_by_less_than_its_margin_is_decided_by_cross_validation():
    """The bench's draw at seed 71 (a 2.1 µm step at 77 mm, rising over 4 mm, beside a bow and a
    backlash, on 11 uniform targets 60 mm apart): the route with the step scored 1.8 below the
    vocabulary alone, short of the margin of 2, and predicted left-out targets far better (CV 0.60 against
    0.80 µm), yet the vocabulary was kept and the step was not said at all. Undecided by the BIC, the CV
    decides: the step is said between the targets either side of it, the bow and backlash named."""
    from tests.discovery_draws import draw, judge

    config = plan_config(11, "none")
    truth = draw(np.random.default_rng(8331), "step", config)
    data = campaign_data(simulate_campaign(config, ErrorModel(truth.model), seed=8331, dwell_jitter=0.8))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    judged = judge(result, truth)
    assert judged.bracketed and not judged.false_names, judged.said
    assert any(e.between_mm == (60.0, 120.0) for e in result.local_errors), judged.said
    assert {"nonlinear_lead", "backlash"} <= set(result.added), judged.said

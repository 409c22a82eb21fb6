"""Each target's leave-one-target-out sum of squares (campaign.discovery.cv.cv_group_errors), which
cv_rms_um sums and as_good compares target by target, against a brute-force refit of every fold by
numpy's least squares: by refitting each fold (up to CV_FOLDS_REFITTED targets) and from the hat
matrix beyond (a dense table: linear in the rows)."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.discovery.cv import CV_FOLDS_REFITTED, cv_group_errors, cv_rms_um
from campaign.discovery.data import campaign_data
from campaign.discovery.fit import Term, design, weighted
from campaign.discovery.local import local_term, target_term
from campaign.pointtable import PointTable


def campaign(targets: int, seed: int, extra_runs_at: int = 0):
    """Two runs over `targets` random targets, both directions; a third run in + over the first
    `extra_runs_at` targets (groups of two sizes)."""
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(0.0, 500.0, targets))
    run = np.concatenate([np.repeat([1, 2], 2 * targets), np.full(extra_runs_at, 3)])
    direction = np.concatenate([np.tile(np.repeat([1, -1], targets), 2), np.ones(extra_runs_at, dtype=int)])
    target = np.concatenate([np.tile(np.concatenate([x, x[::-1]]), 2), x[:extra_runs_at]])
    deviation = (4e-3 * target - 0.8 * direction + 2.5 * np.exp(-0.5 * ((target - 230.0) / 30.0) ** 2)
                 + rng.normal(0.0, 0.4, len(target)))
    return campaign_data(PointTable(kind="linear", run=run, direction=direction, target=target,
                                    deviation=deviation, optional={}, meta={}, source="<test>"))


def brute_force(data, terms, groups):
    a, y = weighted(data, design(data, terms)[0]), weighted(data, data.y)
    _, index = np.unique(groups, return_inverse=True)
    sums = np.zeros(index.max() + 1)
    for g in range(len(sums)):
        out = index == g
        beta = np.linalg.lstsq(a[~out], y[~out], rcond=None)[0]
        sums[g] = np.sum((y[out] - a[out] @ beta) ** 2)
    return sums


@pytest.mark.parametrize("targets, seed", [(23, 1), (60, 2), (CV_FOLDS_REFITTED + 37, 3), (400, 4)])
def test_each_targets_left_out_sum_of_squares_is_a_refit_without_it(targets, seed):
    data = campaign(targets, seed)
    terms = [Term("linear_scale"), Term("backlash"), local_term(225.0, 60.0)]
    groups = cv_group_errors(data, terms, data.target_index)
    expected = brute_force(data, terms, data.target_index)
    assert groups == pytest.approx(expected, rel=1e-7, abs=1e-12)
    assert cv_rms_um(data, terms, data.target_index) == pytest.approx(np.sqrt(expected.sum() / len(data)), rel=1e-9)
    # another grouping than the targets' (the runs, each left out in turn)
    assert cv_group_errors(data, terms, data.run) == pytest.approx(brute_force(data, terms, data.run), rel=1e-7)


@pytest.mark.parametrize("targets", [40, CV_FOLDS_REFITTED + 37])
def test_a_departure_at_the_target_left_out_is_not_predicted_by_it(targets):
    """A departure at one target (its column zero once that target is left out) and groups of two sizes
    (a third run over part of the targets): the fold cannot say the departure, so the target is predicted
    without it. Through the hat matrix, a pseudo-inverse of its block dropped the residual's part there
    and gave 0.23 against 0.53 µm² at 237 targets."""
    data = campaign(targets, 5, extra_runs_at=targets // 3)
    at = float(data.targets_mm[targets // 2])
    terms = [Term("linear_scale"), Term("backlash"), target_term(data.targets_mm, at)]
    expected = brute_force(data, terms, data.target_index)
    assert cv_group_errors(data, terms, data.target_index) == pytest.approx(expected, rel=1e-7, abs=1e-12)


def test_a_departure_tried_beside_a_growing_fit_is_not_predicted_at_its_target():
    """GrowingFit (region terms tried one at a time on a dense table, without refits) gives the CV of the
    model plus the term tried: with a departure at one target, that target's fold cannot say it, as above."""
    from campaign.discovery.cv import GrowingFit
    from campaign.discovery.fit import linear_fit

    targets = CV_FOLDS_REFITTED + 37
    data = campaign(targets, 5, extra_runs_at=targets // 3)
    base = [Term("linear_scale"), Term("backlash")]
    growing = GrowingFit.start(data, linear_fit(data, base), data.target_index)
    assert growing is not None
    departure = target_term(data.targets_mm, float(data.targets_mm[targets // 2]))
    _, _, cv, kept = growing.trial(departure)
    expected = brute_force(data, [*base, departure], data.target_index)
    assert cv == pytest.approx(np.sqrt(expected.sum() / len(data)), rel=1e-7)
    growing.add(kept)  # and kept: a bump tried beside it
    bump = local_term(230.0, 60.0)
    assert growing.trial(bump)[2] == pytest.approx(
        np.sqrt(brute_force(data, [*base, departure, bump], data.target_index).sum() / len(data)), rel=1e-7)


@pytest.mark.parametrize("shelf", [3, 48])
def test_terms_kept_one_after_another_in_a_growing_fit_give_a_refits_numbers(shelf, monkeypatch):
    """Terms kept one after another (on shelves of `shelf` columns: a term wider than one, and terms
    on several; smooth bumps not zero anywhere, and region terms zero outside their region, whose
    products GrowingFit takes over those rows alone): the next term tried gives the RSS of linear_fit
    on them all and the CV of a brute-force refit of every fold."""
    from campaign.discovery import cv
    from campaign.discovery.cv import GrowingFit
    from campaign.discovery.fit import linear_fit

    monkeypatch.setattr(cv, "ADDED_SHELF", shelf)
    from campaign.discovery.locate import Region
    from campaign.discovery.unexplained import region_term

    targets = CV_FOLDS_REFITTED + 11
    data = campaign(targets, 7)
    base = [Term("linear_scale"), Term("backlash")]
    growing = GrowingFit.start(data, linear_fit(data, base), data.target_index)
    assert growing is not None
    kept: list[Term] = []
    for i, (centre, shape) in enumerate(((60.0, "smooth"), (140.0, "bump"), (230.0, "smooth"), (320.0, "step"),
                                         (410.0, "smooth"), (470.0, "bump"), (250.0, "wave"))):
        if shape == "smooth":
            term = local_term(centre, 35.0, by_direction=True, index=i + 1)  # two columns
        else:
            region = Region("position", "deviation", centre - 20.0, centre + 20.0, 1.0, centre, "both", shape)
            term = region_term(data, region, i + 1)
            assert term is not None
        rss, _, cv, trial = growing.trial(term)
        assert rss == pytest.approx(linear_fit(data, [*base, *kept, term]).rss, rel=1e-9)
        assert cv == pytest.approx(
            np.sqrt(brute_force(data, [*base, *kept, term], data.target_index).sum() / len(data)), rel=1e-7)
        growing.add(trial)
        kept.append(term)

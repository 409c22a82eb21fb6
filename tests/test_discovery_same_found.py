"""Routes of discovery: a route is not tried again from local errors found as an earlier route's
(search._same_found): the same kind, directions and target, centre and width within SAME_FOUND of
the width; anything more apart is a route of its own."""

from __future__ import annotations

from campaign.discovery.fit import Term
from campaign.discovery.local import LocalError
from campaign.discovery.search import SAME_FOUND, _same_found


def found(kind: str, centre_mm: float, width_mm: float, directions: str = "both") -> LocalError:
    return LocalError(term=Term("local_error"), params={"amplitude_um": 3.0, "centre_mm": centre_mm, "width_mm": width_mm},
                      errors={}, directions=directions, time_p=1.0, time_change_um=0.0, explained_pct=50.0,
                      delta_bic=-40.0, p_value=1e-9, cv_before_um=1.0, cv_after_um=0.5, kind=kind)


def test_local_errors_found_again_to_rounding_are_the_same_start():
    """Seed 101 of the dense bench: a bump at 229.7244 mm, 72.084 mm wide, and the same found
    beside another effect left out at 229.7241 mm: one route, not two vocabulary searches."""
    assert _same_found([found("bump", 229.7244, 72.084)], [found("bump", 229.7241, 72.084)])
    shift = 2 * SAME_FOUND * 72.084  # twice the tolerance: another start
    assert not _same_found([found("bump", 229.7244, 72.084)], [found("bump", 229.7244 + shift, 72.084)])
    assert not _same_found([found("bump", 229.7244, 72.084)], [found("bump", 229.7244, 72.084 + shift)])


def test_another_kind_direction_or_count_is_another_start():
    bump = found("bump", 300.0, 20.0)
    assert not _same_found([bump], [found("step", 300.0, 20.0)])
    assert not _same_found([bump], [found("bump", 300.0, 20.0, directions="+")])
    assert not _same_found([bump], [bump, found("step", 100.0, 5.0)])
    assert _same_found([bump, found("step", 100.0, 5.0)], [bump, found("step", 100.0, 5.0)])

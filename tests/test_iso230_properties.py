"""Property tests of the ISO 230-2 evaluation (hypothesis)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from campaign.iso230 import evaluate
from campaign.pointtable import PointTable


@st.composite
def tables(draw):
    """Random bidirectional tables: 5..12 targets, 2..6 runs, deviations within ±500 µm."""
    m = draw(st.integers(5, 12))
    n = draw(st.integers(2, 6))
    dev = draw(st.lists(st.floats(-500, 500, allow_nan=False), min_size=2 * m * n, max_size=2 * m * n))
    targets = np.arange(m) * 25.0
    run, direction, target = [], [], []
    for j in range(n):
        for d in (1, -1):
            for t in targets[:: d]:
                run.append(j + 1)
                direction.append(d)
                target.append(t)
    return PointTable("linear", np.array(run), np.array(direction), np.array(target), np.array(dev))


def _same(a, b):
    if a is None or b is None:
        return a is b
    return np.isclose(a, b, rtol=1e-9, atol=1e-6)


@settings(max_examples=150, deadline=None)
@given(tables())
def test_ordering_of_parameters(table):
    s = evaluate(table).summary
    assert s["A"] >= s["E"] - 1e-9 >= s["M"] - 2e-9
    assert s["A"] >= max(s["A_up"], s["A_down"]) - 1e-9
    assert s["E"] >= max(s["E_up"], s["E_down"]) - 1e-9
    assert s["R"] >= max(s["R_up"], s["R_down"]) - 1e-9


@settings(max_examples=150, deadline=None)
@given(tables())
def test_reversal_is_max_abs_of_per_target(table):
    ev = evaluate(table)
    assert ev.summary["B"] == max(abs(t.B) for t in ev.targets)
    assert np.isclose(ev.summary["B_mean"], np.mean([t.B for t in ev.targets]))


@settings(max_examples=100, deadline=None)
@given(tables(), st.floats(-1000, 1000, allow_nan=False))
def test_ranges_do_not_move_with_a_constant_shift(table, shift):
    before = evaluate(table).summary
    shifted = PointTable(table.kind, table.run, table.direction, table.target, table.deviation + shift)
    after = evaluate(shifted).summary
    for key in ("A", "A_up", "A_down", "E", "E_up", "E_down", "M", "B", "B_mean", "R", "R_up", "R_down"):
        assert np.isclose(before[key], after[key], rtol=1e-9, atol=1e-6), key


@settings(max_examples=100, deadline=None)
@given(tables())
def test_swapping_directions_swaps_up_and_down(table):
    before = evaluate(table).summary
    swapped = PointTable(table.kind, table.run, -table.direction, table.target, table.deviation)
    after = evaluate(swapped).summary
    for base in ("A", "E", "R"):
        assert _same(before[f"{base}_up"], after[f"{base}_down"])
        assert _same(before[f"{base}_down"], after[f"{base}_up"])
    for key in ("A", "E", "M", "B", "R"):
        assert _same(before[key], after[key])
    assert _same(before["B_mean"], -after["B_mean"])

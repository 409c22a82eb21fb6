"""The motion-planned correction (protocols/correction_planner.py, the 2024 motion-planning patent)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from protocols.correction_planner import (
    PlannerLimits,
    PlannerState,
    minimum_time,
    plan,
    plan_cycle,
    stopping_step,
)

TOL = 2e-9  # relative: the planner may exceed the acceleration bound by 1e-9 to absorb rounding


def run_to(target: float, limits: PlannerLimits, max_cycles: int = 200_000) -> list[PlannerState]:
    states, state = [], PlannerState()
    while state.value != target and len(states) < max_cycles:
        state = plan_cycle(state, target, limits)
        states.append(state)
    return states


def test_hand_worked_triangle():
    # a = max_accel*dt² = 1, no rate bound in play, target 4. Cycle 1: from rest the step can
    # grow to 1 -> 1. Cycle 2: remaining 3 = 2 + 1 (brake 2, 1): step 2 -> 3. Cycle 3: remaining
    # 1, step 1 (within 2±1), lands -> 4, and stays.
    limits = PlannerLimits(max_rate=100.0, max_accel=1.0, cycle_s=1.0)
    assert list(plan([4.0] * 5, limits)) == [1.0, 3.0, 4.0, 4.0, 4.0]


def test_hand_worked_rate_bound():
    # max step 1 per cycle, a = 1, target 3: 1, 2, 3 (cruise at the rate bound, then stop: the last
    # step 1 -> 0 is within a).
    limits = PlannerLimits(max_rate=1.0, max_accel=1.0, cycle_s=1.0)
    assert list(plan([3.0] * 4, limits)) == [1.0, 2.0, 3.0, 3.0]


def test_stopping_step_hand_values():
    # braking from step d covers d + (d-a) + ... : 1.5a then 0.5a covers 2a
    assert stopping_step(2.0, 1.0) == pytest.approx(1.5)
    assert stopping_step(0.3, 1.0) == pytest.approx(0.3)
    assert stopping_step(6.0, 1.0) == pytest.approx(3.0)  # 3 + 2 + 1
    assert stopping_step(0.0, 1.0) == 0.0


def test_minimum_time_hand_values():
    assert minimum_time(4.0, 100.0, 1.0) == pytest.approx(4.0)  # triangle: 2*sqrt(4/1)
    assert minimum_time(10.0, 1.0, 1.0) == pytest.approx(11.0)  # trapezoid: 10/1 + 1/1


limits_strategy = st.builds(
    PlannerLimits,
    max_rate=st.floats(1e-3, 1e2),
    max_accel=st.floats(1e-3, 1e3),
    cycle_s=st.floats(1e-4, 1e-1),
)


@pytest.mark.machine  # a sweep of 300 generated cases, about 3 s: make test runs it, the fast tier keeps the hand-worked ones
@settings(max_examples=300, deadline=None)
@given(limits=limits_strategy, ratio=st.floats(1e-2, 1e6), sign=st.sampled_from([1.0, -1.0]))
def test_constant_target_bounds_no_overshoot_and_time(limits, ratio, sign):
    target = sign * ratio * limits.accel_step
    t_min = minimum_time(target, limits.max_rate, limits.max_accel)
    assume(t_min / limits.cycle_s < 50_000)
    states = run_to(target, limits)
    assert states[-1].value == target
    values = np.array([0.0] + [s.value for s in states])
    steps = np.array([0.0] + [s.step for s in states] + [0.0])
    assert np.max(np.abs(steps)) <= limits.max_step * (1 + TOL)
    assert np.max(np.abs(np.diff(steps))) <= limits.accel_step * (1 + TOL)
    assert np.max(sign * (values - target)) <= 1e-12 * abs(target)  # never passes the target
    assert np.all(sign * np.diff(values) >= 0)  # never moves away from it
    assert len(states) <= t_min / limits.cycle_s + 2
    after = plan_cycle(states[-1], target, limits)
    assert after.value == target and after.step == 0.0  # no chattering


@pytest.mark.machine  # a sweep of 100 generated target sequences, about 3 s (as above)
@settings(max_examples=100, deadline=None)
@given(limits=limits_strategy,
       targets=st.lists(st.tuples(st.floats(-1e4, 1e4), st.integers(1, 300)), min_size=1, max_size=8))
def test_changing_target_keeps_bounds_and_settles(limits, targets):
    desired = np.concatenate([np.full(n, v * limits.accel_step) for v, n in targets])
    final = desired[-1]
    t_settle = 4 * minimum_time(2e4 * limits.accel_step, limits.max_rate, limits.max_accel) / limits.cycle_s
    assume(t_settle < 50_000)
    desired = np.concatenate([desired, np.full(int(t_settle) + 10, final)])
    values = plan(desired, limits)
    steps = np.diff(np.concatenate([[0.0], values]))
    scale = 1e-12 * np.max(np.abs(desired))
    assert np.max(np.abs(steps)) <= limits.max_step * (1 + TOL) + scale
    assert np.max(np.abs(np.diff(np.concatenate([[0.0], steps])))) <= limits.accel_step * (1 + TOL) + scale
    assert values[-1] == final


def lp_minimum_cycles(target: float, max_step: float, accel_step: float, upto: int) -> int:
    """Fewest cycles N to go from rest to rest at `target` without passing it, by linear
    programming over the steps d_1..d_N (independent of the planner's algorithm)."""
    for n in range(1, upto + 1):
        # variables d_1..d_n; |d_i| <= max_step; |d_i - d_(i-1)| <= a with d_0 = 0 and d_(n+1) = 0;
        # partial sums <= target; total == target
        rows, rhs = [], []
        for i in range(n + 1):
            row = np.zeros(n)
            if i < n:
                row[i] = 1.0
            if i > 0:
                row[i - 1] -= 1.0
            rows += [row, -row]
            rhs += [accel_step, accel_step]
        for i in range(n):
            row = np.zeros(n)
            row[: i + 1] = 1.0
            rows.append(row)
            rhs.append(target)
        res = linprog(np.zeros(n), A_ub=np.array(rows), b_ub=np.array(rhs), A_eq=np.ones((1, n)),
                      b_eq=[target], bounds=[(-max_step, max_step)] * n, method="highs")
        if res.status == 0:
            return n
    raise AssertionError("no solution")


@pytest.mark.parametrize("target, max_rate", [(0.5, 10.0), (2.0, 10.0), (7.3, 10.0), (7.3, 1.5),
                                              (19.0, 2.0), (30.0, 100.0)])
def test_cycles_equal_the_linear_programming_optimum(target, max_rate):
    limits = PlannerLimits(max_rate=max_rate, max_accel=1.0, cycle_s=1.0)
    cycles = len(run_to(target, limits))
    assert cycles == lp_minimum_cycles(target, limits.max_step, limits.accel_step, cycles + 1)


def test_correction_cli_json(cli):
    result = cli("correction", "--step", "10", "--max-rate", "100", "--max-accel", "1000",
                 "--cycle-ms", "1", "--json")
    assert result.code == 0, result.err
    out = json.loads(result.out)
    assert out["step"]["max_change_per_cycle_um"] == 10.0
    assert out["step"]["max_accel_um_s2"] == pytest.approx(10.0 / 1e-6)
    assert out["planned"]["max_change_per_cycle_um"] <= 100 * 1e-3 * (1 + TOL)
    assert out["planned"]["max_accel_um_s2"] <= 1000 * (1 + TOL)
    assert out["cycles_to_settle"] <= math.ceil(0.2 / 1e-3) + 2  # 10/100 + 100/1000 = 0.2 s


def test_correction_cli_plot_and_bad_input(cli, tmp_path):
    from tests.conftest import assert_one_line_error

    out = tmp_path / "c.png"
    result = cli("correction", "--step", "-5", "--max-rate", "50", "--max-accel", "500", "--cycle-ms", "2",
                 "--plot", out)
    assert result.code == 0 and out.stat().st_size > 0
    assert "planned" in result.out
    assert_one_line_error(cli("correction", "--step", "5", "--max-rate", "0", "--max-accel", "1",
                              "--cycle-ms", "1"), "--max-rate: must be a finite number > 0")


@pytest.mark.machine
def test_st_block_parses_and_mirrors_the_planner_constants():
    """Parse only: no ST runtime exists here, so nothing claims to run the block."""
    from pathlib import Path

    from protocols.correction_planner import SLACK
    from tests.test_plc_st import parse_st

    path = Path(__file__).resolve().parents[1] / "protocols" / "st" / "FB_AxiscalCompensation.st"
    assert parse_st(path)  # blark parses it without an error (the same parse test_plc_st checks)
    text = path.read_text()
    slack = float(text.split("fSlack : LREAL := ")[1].split(";")[0])
    assert slack == SLACK
    for name in ("M_PlanCycle", "M_StoppingStep", "M_TableLookup", "MC_PositionCorrectionLimiter"):
        assert name in text

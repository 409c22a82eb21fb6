"""The plan generator: the paper's exact cycle, options, and refusal of plans outside the limits."""

import json

import pytest

from campaign.config import parse_config
from campaign.errors import SafetyError
from campaign.plan import Capture, Checkpoint, Move, Settle, build_plan, check_plan
from tests.conftest import assert_one_line_error

BASE = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 130.0
max_velocity = 20.0
[plan]
targets = [0.0, 60.0, 120.0]
overrun = 5.0
cycles = 2
dwell_s = 4.0
velocity = 10.0
[capture]
average_s = 1.0
"""


def make(extra: str = "", base: str = BASE):
    return parse_config(base + extra, "test.toml")


def test_linear_cycle_exact_sequence():
    """start -> -L1, 0, L, 2L, 2L+L1, 2L, L, 0, -L1, repeated; dwell 4 s = settle 3 s + 1 s window."""
    plan = build_plan(make())
    moves = [(s.position, s.overrun) for s in plan.steps if isinstance(s, Move)]
    one_cycle = [(-5.0, True), (0.0, False), (60.0, False), (120.0, False), (125.0, True),
                 (120.0, False), (60.0, False), (0.0, False)]
    assert moves == one_cycle * 2 + [(-5.0, True)]
    first_point = plan.steps[1:5]
    assert first_point[0] == Move(0.0, 10.0)
    assert first_point[1] == Settle(3.0)
    assert isinstance(first_point[2], Capture) and first_point[2].window_s == 1.0
    assert isinstance(first_point[3], Checkpoint) and first_point[3].point == first_point[2].point
    keys = [(p.run, p.direction, p.target) for p in plan.points]
    assert keys == [(1, 1, 0.0), (1, 1, 60.0), (1, 1, 120.0), (1, -1, 120.0), (1, -1, 60.0), (1, -1, 0.0),
                    (2, 1, 0.0), (2, 1, 60.0), (2, 1, 120.0), (2, -1, 120.0), (2, -1, 60.0), (2, -1, 0.0)]
    assert [p.index for p in plan.points] == list(range(12))
    assert not any(isinstance(s, (Capture, Checkpoint)) for s in plan.steps if getattr(s, "overrun", False))


def test_paper_campaign_counts_and_duration():
    """11 targets x 2 directions x 5 runs with 4 s dwells: 110 points, about 20 minutes."""
    text = BASE.replace("targets = [0.0, 60.0, 120.0]", "length = 600.0\ncount = 11").replace(
        "soft_limit_max = 130.0", "soft_limit_max = 610.0").replace("cycles = 2", "cycles = 5").replace(
        "velocity = 10.0", "velocity = 8.0")
    plan = build_plan(make(base=text))
    assert len(plan.points) == 110
    assert plan.targets == tuple(float(60 * i) for i in range(11))
    from campaign.plan import estimate_duration_s
    assert 17 * 60 < estimate_duration_s(plan, make(base=text).axis) < 23 * 60


def test_stable_capture_has_no_settle():
    plan = build_plan(make('method = "stable"\nstable_window_s = 0.5\nstable_timeout_s = 6.0\n'))
    assert not any(isinstance(s, Settle) for s in plan.steps)
    cap = next(s for s in plan.steps if isinstance(s, Capture))
    assert (cap.window_s, cap.timeout_s) == (0.5, 6.0)


@pytest.mark.parametrize("kind", ["random", "golden"])
def test_offsets_are_seeded_and_bounded(kind):
    text = BASE.replace("targets = [0.0, 60.0, 120.0]", "length = 120.0\ncount = 7")
    extra = f'offsets = "{kind}"\noffset_fraction = 0.2\nseed = 7\n'
    a = build_plan(make(base=text.replace("[capture]", extra + "[capture]")))
    b = build_plan(make(base=text.replace("[capture]", extra + "[capture]")))
    c = build_plan(make(base=text.replace("[capture]", extra.replace("seed = 7", "seed = 8") + "[capture]")))
    assert a.targets == b.targets and a.seed == 7
    assert a.offsets[0] == 0.0 and all(abs(o) <= 0.2 * 20.0 + 1e-9 for o in a.offsets)
    assert len({round(o, 6) for o in a.offsets}) == 7
    assert a.offsets != c.offsets


def test_pilgrim_cycle_visits_one_target_at_a_time():
    plan = build_plan(make(base=BASE.replace("velocity = 10.0", 'velocity = 10.0\ncycle = "pilgrim"')))
    keys = [(p.target, p.direction, p.run) for p in plan.points]
    assert keys[:4] == [(0.0, 1, 1), (0.0, -1, 1), (0.0, 1, 2), (0.0, -1, 2)]
    moves = [s.position for s in plan.steps if isinstance(s, Move)][:4]
    assert moves == [-5.0, 0.0, 5.0, 0.0]


def test_rotary_axis_in_degrees():
    text = BASE.replace("[axis]", '[axis]\nkind = "rotary"\nunit = "deg"')
    plan = build_plan(make(base=text))
    assert plan.targets == (0.0, 60.0, 120.0)


def test_plan_outside_soft_limits_refused():
    config = make(base=BASE.replace("soft_limit_max = 130.0", "soft_limit_max = 122.0"))
    with pytest.raises(SafetyError, match="soft limits"):
        check_plan(build_plan(config), config.axis)


def test_plan_above_velocity_limit_refused():
    config = make(base=BASE.replace("velocity = 10.0", "velocity = 25.0"))
    with pytest.raises(SafetyError, match="velocity"):
        check_plan(build_plan(config), config.axis)


def test_plan_command(cli, tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(BASE)
    result = cli("plan", path, "--json")
    data = json.loads(result.out)
    assert result.code == 0 and data["points"] == 12
    assert data["travel"] == pytest.approx(2 * 2 * 130.0)
    path.write_text(BASE.replace("overrun = 5.0", "overrun = 15.0"))
    assert_one_line_error(cli("plan", path), "outside the soft limits")


def test_plan_steps_is_a_readable_table_and_json_records(cli):
    from tests.conftest import ROOT

    text = cli("plan", ROOT / "campaign" / "demo.toml", "--steps").out
    assert "Move(" not in text and "Point(" not in text  # no Python reprs
    rows = [ln for ln in text.splitlines() if "capture (average)" in ln]
    assert len(rows) == 110 and "│     1 │   1 │  +  │" in rows[0]
    data = json.loads(cli("plan", ROOT / "campaign" / "demo.toml", "--steps", "--json").out)
    assert data["steps"][0] == {"step": "move", "position": -5.0, "velocity": 8.0, "overrun": True}
    assert sum(s["step"] == "capture" for s in data["steps"]) == 110

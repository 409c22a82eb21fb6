"""`axiscal refine`: extra targets where interpolation cannot follow; on the simulated machine the
follow-up campaign's table lowers A measured between the original targets."""

import json

import numpy as np
import pytest

from campaign.compensation.refine import follow_up_config, interpolation_error
from tests.conftest import PAPER, assert_one_line_error
from tests.test_demo_e2e import axiscal

WAVY = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 310.0
max_velocity = 50.0
[plan]
start = 0.0
length = 300.0
count = 7
overrun = 3.0
cycles = 3
dwell_s = 1.5
velocity = 40.0
[capture]
average_s = 0.5
[sim.effects.linear_scale]
ppm = 20.0
[sim.effects.periodic_lead]
amplitude_um = 10.0
period_mm = 150.0
phase_rad = 0.0
[sim.effects.noise]
sigma_um = 0.3
"""


def test_interpolation_error_of_a_parabola():
    x = np.arange(0.0, 61.0, 10.0)
    f = 0.01 * x**2  # f'' = 0.02 per mm²: worst error over a 10 mm interval is 0.02 * 100 / 8 = 0.25
    assert interpolation_error(x, f) == pytest.approx(np.full(6, 0.25))
    assert interpolation_error(x, 3 * x + 1) == pytest.approx(np.zeros(6))


@pytest.mark.machine
def test_follow_up_lowers_a_between_the_original_targets(tmp_path):
    (tmp_path / "wavy.toml").write_text(WAVY)
    mid = WAVY.replace("start = 0.0", "start = 25.0").replace("length = 300.0", "length = 250.0").replace(
        "count = 7", "count = 6")  # 25, 75, ..., 275: halfway between the original targets
    (tmp_path / "mid.toml").write_text(mid)

    def run(*args):
        proc = axiscal(*args)
        assert proc.returncode == 0, proc.stderr[-1500:]
        return proc.stdout

    run("run", tmp_path / "wavy.toml", "--out", tmp_path / "first")
    proposal = json.loads(run("refine", tmp_path / "first" / "points.csv", "--config", tmp_path / "wavy.toml",
                              "-o", tmp_path / "follow.toml", "--json"))
    assert len(proposal["new"]) >= 6 and all(0 < t < 300 for t in proposal["new"])
    run("run", tmp_path / "follow.toml", "--out", tmp_path / "follow")
    accuracy = {}
    for name in ("first", "follow"):
        run("compensate", tmp_path / name / "points.csv", "--format", "json", "-o", tmp_path / f"{name}.json",
            "--overrun", "3")
        out = json.loads(run("verify", tmp_path / "mid.toml", "--comp", tmp_path / f"{name}.json",
                             "--out", tmp_path / f"check-{name}", "--json"))
        accuracy[name] = out["A"]
    assert accuracy["follow"] < 0.5 * accuracy["first"], accuracy


def test_smooth_axis_needs_no_new_targets(cli):
    data = json.loads(cli("refine", PAPER / "horizontal_before.csv", "--threshold", "5", "--json").out)
    assert data["new"] == [] and len(data["intervals"]) == 10


def test_refine_with_nothing_to_add_writes_no_file_and_says_so(cli, tmp_path):
    """The old refine wrote a follow-up config identical in targets to the campaign, silently."""
    from tests.conftest import ROOT

    out = tmp_path / "follow.toml"
    result = cli("refine", PAPER / "horizontal_before.csv", "--threshold", "5", "--config",
                 ROOT / "campaign" / "demo.toml", "-o", out)
    assert result.code == 0, result.err
    assert not out.exists() and "no follow-up config written" in result.out
    data = json.loads(cli("refine", PAPER / "horizontal_before.csv", "--threshold", "5", "--config",
                          ROOT / "campaign" / "demo.toml", "-o", out, "--json").out)
    assert data["written"] is None and not out.exists()


def test_follow_up_config_text():
    text = follow_up_config("[axis]\nname = 'X'\n[plan]\nlength = 10.0\ncount = 3\nvelocity = 1.0\n[capture]\n",
                            [0.0, 2.5, 5.0])
    assert "length" not in text and "count" not in text
    assert "targets = [0.0, 2.5, 5.0]" in text and text.index("targets") < text.index("[capture]")


def test_refine_bad_input(cli, tmp_path):
    assert_one_line_error(cli("refine", tmp_path / "none.csv"), "no such file")
    assert_one_line_error(cli("refine", PAPER / "horizontal_before.csv", "--threshold", "0"), "--threshold")
    assert_one_line_error(cli("refine", PAPER / "horizontal_before.csv", "-o", tmp_path / "x.toml"), "--config")

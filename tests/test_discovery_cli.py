"""`axiscal discover` on files: JSON, plot, saved model, bad input, the horizontal axis of Li et al. 2022, and
agreement of the fast simulator (campaign/discovery/simulate.py) with the real simulated machine (`axiscal
run`: real pyads against the loopback ADS server, one campaign at a time)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from campaign.config import parse_config
from campaign.discovery.simulate import Environment, simulate_campaign
from campaign.errors import InputError
from campaign.model import read_model, sim_model
from campaign.pointtable import write_points
from tests.conftest import PAPER, ROOT, assert_one_line_error

REAL_PLAN = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 610.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 600.0
count = 21
overrun = 5.0
cycles = 4
dwell_s = 1.0
velocity = 40.0
offsets = "golden"
offset_fraction = 0.45

[capture]
average_s = 0.5

[sim]
seed = 7

[sim.effects.linear_scale]
ppm = -12.4

[sim.effects.noise]
sigma_um = 0.3
reading_sigma_um = 0.05
"""

SPATIAL_AND_TIME = """
[sim.effects.backlash]
b_um = 4.0

[sim.effects.periodic_lead]
amplitude_um = 1.5
period_mm = 10.0
phase_rad = 0.7

[sim.effects.thermal_drift]
growth_ppm = 10.0
tau_s = 120.0
pivot_mm = 300.0
"""

REVERSAL_AND_SETTLING = """
[sim.effects.position_dependent_backlash]
b0_um = 3.0
k_ppm = 10.0

[sim.effects.nonlinear_lead]
p2_um = 2.0
p3_um = -1.5
start_mm = 0.0
end_mm = 600.0

[sim.effects.settling]
e0_um = 1.0
tau_s = 0.5
"""


def discover_json(cli, *args) -> dict:
    result = cli("discover", *args, "--json")
    assert result.code == 0, result.err
    return json.loads(result.out)


def test_seed_000_horizontal_axis(cli, tmp_path):
    data = discover_json(cli, PAPER / "horizontal_before.csv", "--save", tmp_path / "h.toml",
                         "--plot", tmp_path / "h.png")
    assert data["time_source"] == "point order"
    assert any("point order" in note for note in data["notes"])
    assert any("evenly spaced" in note for note in data["notes"])  # no periodic search on a 60 mm grid
    # issue 34: the bow only just passed its cross-validation (0.911 -> 0.908 µm); a local term over the
    # region the locator finds (280-520 mm) predicts left-out targets far better (0.52 µm), so the bow
    # is not named and the region is said as an unexplained local error
    assert data["added"] == []
    [local] = data["local_errors"]
    assert local["kind"] == "region" and local["region_mm"][0] < 300.0 and 420.0 < local["region_mm"][1]
    assert local["cv_after_um"] < 0.7 * local["cv_before_um"]
    assert any(r["shape"] == "bump" for r in data["located"]["before"]["regions"])
    assert data["gap_after_um"] < data["gap_before_um"]
    saved = read_model(tmp_path / "h.toml")
    assert set(saved.effects) == {"linear_scale", "noise"}
    assert saved.effects["linear_scale"]["ppm"] == pytest.approx(data["model"]["linear_scale"]["ppm"], abs=1e-3)
    assert (tmp_path / "h.png").read_bytes()[:4] == b"\x89PNG"


def test_an_incomplete_campaign_is_said_first(cli, tmp_path):
    lines = (PAPER / "horizontal_before.csv").read_text().splitlines(keepends=True)
    (tmp_path / "cut.csv").write_text("".join(lines[:-3]))  # the last run lacks 3 points
    notes = discover_json(cli, tmp_path / "cut.csv")["notes"]
    assert notes[0].startswith("incomplete campaign: 3 of 66 points missing (11 targets × 2 direction(s) × 3 runs)")
    assert not any("incomplete" in note for note in discover_json(cli, PAPER / "horizontal_before.csv")["notes"])


@pytest.mark.machine
def test_text_output_names_steps_units_and_noise(cli, tmp_path):
    config = parse_config(REAL_PLAN + SPATIAL_AND_TIME)
    table = simulate_campaign(config, sim_model(config.sim), seed=2)
    write_points(tmp_path / "points.csv", table)
    model = tmp_path / "start.toml"
    model.write_text("[effects.linear_scale]\n[effects.backlash]\n")
    result = cli("discover", tmp_path / "points.csv", "--model", model, "--verbose")
    assert result.code == 0, result.err
    assert "add periodic_lead" in result.out and "period_mm = " in result.out and " mm" in result.out
    assert "add thermal_drift" in result.out and "µm/m per hour" in result.out
    assert "noise estimate" in result.out


@pytest.mark.parametrize("args, fragment", [
    (["missing.csv"], "no such file"),
    ([PAPER / "horizontal_before.csv", "--model", "nope.toml"], "no such file"),
    ([PAPER / "horizontal_before.csv", "--plot", "x.jpg"], "unsupported plot format"),
    ([PAPER / "horizontal_before.csv", "--save", "x.json"], "--save"),
])
def test_bad_input_is_one_error_line(cli, args, fragment):
    assert_one_line_error(cli("discover", *args), fragment)


def test_bad_model_names_the_key(cli, tmp_path):
    model = tmp_path / "m.toml"
    model.write_text("[effects.wobble]\n")
    assert_one_line_error(cli("discover", PAPER / "horizontal_before.csv", "--model", model), "effects.wobble")


def run_real_campaign(tmp_path, effects: str) -> tuple:
    """Run the campaign on the real simulated machine, and the same on the fast simulator."""
    path = tmp_path / "c.toml"
    path.write_text(REAL_PLAN + effects)
    proc = subprocess.run([sys.executable, "-m", "campaign", "run", path, "--out", tmp_path / "real", "--json"],
                          capture_output=True, text=True, timeout=300, cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    config = parse_config(REAL_PLAN + effects)
    fast = simulate_campaign(config, sim_model(config.sim), seed=7)
    write_points(tmp_path / "fast.csv", fast)
    return tmp_path / "real" / "points.csv", tmp_path / "fast.csv"


@pytest.mark.machine
def test_fast_simulator_agrees_with_the_machine_on_spatial_and_time_effects(cli, tmp_path):
    real, fast = run_real_campaign(tmp_path, SPATIAL_AND_TIME)
    model = tmp_path / "start.toml"
    model.write_text("[effects.linear_scale]\n[effects.backlash]\n")
    found = [discover_json(cli, path, "--model", model) for path in (real, fast)]
    for data in found:
        assert sorted(data["added"]) == ["periodic_lead", "thermal_drift"], data["notes"]
        assert data["model"]["periodic_lead"]["period_mm"] == pytest.approx(10.0, rel=0.15)
        assert data["model"]["thermal_drift"]["growth_ppm"] == pytest.approx(10.0, rel=0.15)
        assert data["gap_after_um"] <= 1.3 * 0.3
    assert found[0]["gap_before_um"] == pytest.approx(found[1]["gap_before_um"], rel=0.15)


@pytest.mark.machine
def test_fast_simulator_agrees_with_the_machine_on_reversal_and_settling(cli, tmp_path):
    real, fast = run_real_campaign(tmp_path, REVERSAL_AND_SETTLING)
    for path in (real, fast):
        data = discover_json(cli, path)
        assert sorted(data["added"]) == ["nonlinear_lead", "position_dependent_backlash"], data["notes"]
        assert data["model"]["position_dependent_backlash"]["k_ppm"] == pytest.approx(10.0, rel=0.15)
        # a constant dwell: settling is the part of the reversal that is not named
        assert any("settling is confounded with backlash" in note for note in data["notes"])


def test_save_without_a_time_column_does_not_save_a_time_constant_in_points(cli, tmp_path):
    """On the point order, thermal_drift's time constant is in points: the saved file says so and
    leaves tau_s out, so that the simulator refuses it and discover refits it."""
    config = parse_config(REAL_PLAN.replace("cycles = 4", "cycles = 5") + SPATIAL_AND_TIME.split("[sim.effects.periodic")[0]
                          + "[sim.effects.thermal_drift]\ngrowth_ppm = 20.0\ntau_s = 200.0\npivot_mm = 300.0\n")
    table = simulate_campaign(config, sim_model(config.sim), seed=2)
    table.optional = {}
    write_points(tmp_path / "points.csv", table)
    model = tmp_path / "start.toml"
    model.write_text("[effects.linear_scale]\n[effects.backlash]\n")
    data = discover_json(cli, tmp_path / "points.csv", "--model", model, "--save", tmp_path / "new.toml")
    assert data["added"] == ["thermal_drift"], data["notes"]
    assert data["time_source"] == "point order"
    text = (tmp_path / "new.toml").read_text()
    assert "NOT seconds" in text and "\ntau_s =" not in text
    with pytest.raises(InputError, match="tau_s"):
        read_model(tmp_path / "new.toml")
    refit = discover_json(cli, tmp_path / "points.csv", "--model", tmp_path / "new.toml")
    assert refit["added"] == []
    assert refit["model"]["thermal_drift"]["tau_s"] == pytest.approx(data["model"]["thermal_drift"]["tau_s"], rel=0.05)


@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_environment_from_a_file_is_named_with_its_error_and_left_out_of_the_saved_model(cli, tmp_path):
    config = parse_config(REAL_PLAN.replace("dwell_s = 1.0", "dwell_s = 10.0").replace("cycles = 4", "cycles = 10"))
    env = Environment(air_temp_c=(20.0, 24.0), air_pressure_hpa=(1015.0, 1011.0), humidity_pct=(45.0, 45.0))
    table = simulate_campaign(config, sim_model(config.sim), seed=3,
                              environment=env)
    write_points(tmp_path / "points.csv", table)
    data = discover_json(cli, tmp_path / "points.csv", "--save", tmp_path / "new.toml")
    assert data["added"] == ["environment"], data["notes"]
    assert data["model"]["environment"]["air_factor"] == pytest.approx(1.0, rel=0.15)
    assert data["steps"][0]["standard_errors"]["air_factor"] < 0.05
    assert data["choices"][0]["chosen"] == "environment"
    text = (tmp_path / "new.toml").read_text()
    assert "# Left out: environment (air_factor = " in text and "[effects.environment]" not in text
    assert set(read_model(tmp_path / "new.toml").effects) == {"linear_scale", "noise"}
    out = cli("discover", tmp_path / "points.csv", "--verbose").out
    assert "add environment (air_factor = " in out and " ± " in out and "chose environment" in out


def test_a_table_that_repeats_nothing_does_not_call_what_is_left_noise(cli):
    """One mean per target (the 2012 turntable's published errors): the run-to-run scatter is not
    measured, so the residual is not said to be noise; a table with repeated runs still is judged."""
    from tests.conftest import DATA

    single = cli("discover", DATA / "paper-2012-pmac-turntable" / "forward_errors.csv", "--json")
    assert single.code == 0, single.err
    assert json.loads(single.out)["noise_measured"] is False
    text = " ".join(cli("discover", DATA / "paper-2012-pmac-turntable" / "forward_errors.csv").out.split())
    assert "noise not measured" in text and "what is left is noise" not in text
    repeated = cli("discover", DATA / "paper-2022-beckhoff-press" / "horizontal_before.csv", "--json")
    assert repeated.code == 0 and json.loads(repeated.out)["noise_measured"] is True


def test_a_step_between_two_targets_is_said_between_them_not_at_a_fitted_place(cli):
    """The seed paper's horizontal axis after compensation (targets 60 mm apart) has a step no target
    lies on: the data show it between two targets, not where between them nor how sharp."""
    from tests.conftest import DATA

    said = cli("discover", DATA / "paper-2022-beckhoff-press" / "horizontal_after.csv", "--json")
    assert said.code == 0, said.err
    steps = [e for e in json.loads(said.out)["local_errors"] if e["kind"] == "step"]
    assert steps and all(e["between_targets_mm"][1] - e["between_targets_mm"][0] == pytest.approx(60.0)
                         for e in steps)
    assert all("between the targets at" in e["sentence"] and "rising over" not in e["sentence"] for e in steps)


def test_discover_tells_its_stages_in_order_and_they_change_nothing():
    """discover's `stage` hears each stage as it begins (the vocabulary first, the final model's
    residual located last, the routes counted in between), and the result is the one without it."""
    from campaign.discovery.data import campaign_data
    from campaign.discovery.search import discover
    from campaign.model import ErrorModel
    from tests.test_discovery_period import FINE_PLAN

    config = parse_config(FINE_PLAN.format(count=21, cycles=3), source="fine")
    truth = ErrorModel({"linear_scale": {"ppm": 4.0}, "backlash": {"b_um": 1.5},
                        "local_defect": {"amplitude_um": 3.0, "centre_mm": 31.0, "width_mm": 8.0, "skew": 0.0},
                        "noise": {"sigma_um": 0.3}})
    data = campaign_data(simulate_campaign(config, truth, seed=5))
    start = ErrorModel({"linear_scale": {}})
    stages: list[str] = []
    told = discover(data, start, {"linear_scale": set()}, stage=stages.append)
    plain = discover(data, start, {"linear_scale": set()})
    assert stages[0] == "searching the vocabulary" and stages[-1] == "locating what the final model leaves"
    assert any(s.startswith("choosing between ") and s.endswith(" routes") for s in stages)
    routes = [s for s in stages if s.startswith("route ")]
    assert routes  # the defect is found beside the vocabulary: a route at least
    assert [int(s.split()[1].rstrip(":")) for s in routes] == list(range(1, len(routes) + 1))
    assert told.added == plain.added and told.gap_after_um == plain.gap_after_um
    assert [e.sentence() for e in told.local_errors] == [e.sentence() for e in plain.local_errors]


@pytest.mark.machine  # a terminal (pty) and two subprocesses, about 6 s
def test_discover_shows_what_it_is_doing_on_a_terminal_and_nothing_in_a_pipe():
    import os

    import pexpect

    table = ROOT / "tests" / "recorded" / "backlash-settling-bump-350mm.csv"
    env = dict(os.environ, TERM="xterm")
    child = pexpect.spawn(sys.executable, ["-m", "campaign", "discover", str(table)], cwd=str(ROOT), env=env,
                          dimensions=(40, 160), encoding="utf-8", timeout=60)
    child.expect("discovering")
    child.expect(pexpect.EOF)
    child.close()
    assert child.exitstatus == 0
    piped = subprocess.run([sys.executable, "-m", "campaign", "discover", str(table)], cwd=str(ROOT),
                           capture_output=True, text=True, timeout=60, check=False)
    assert piped.returncode == 0 and "discovering" not in piped.stderr + piped.stdout
    assert "gap " in piped.stdout


def test_noise_on_evenly_spaced_targets_says_which_periods_were_not_looked_for(cli, tmp_path):
    """11 targets 60 mm apart: a screw lead shorter than 120 mm is not looked for. The summary said
    only "what is left is noise" (a user's trial: a 2 µm, 5 mm lead was there), the reason being in
    --verbose alone; the summary now says what was not looked for and how to plan to look."""
    from campaign.model import ErrorModel
    from tests.discovery_draws import plan_config

    table = simulate_campaign(plan_config(11, "none"), ErrorModel({"linear_scale": {"ppm": -10.0},
                                                                   "noise": {"sigma_um": 0.3}}), seed=4)
    write_points(tmp_path / "points.csv", table)
    said = " ".join(cli("discover", tmp_path / "points.csv").out.split())
    assert "what is left is noise" in said
    assert "not looked for: periodic_lead at periods under 120 mm (the targets are evenly spaced 60 mm apart)" in said
    golden = simulate_campaign(plan_config(11, "golden"), ErrorModel({"linear_scale": {"ppm": -10.0},
                                                                      "noise": {"sigma_um": 0.3}}), seed=4)
    write_points(tmp_path / "golden.csv", golden)
    assert "not looked for" not in cli("discover", tmp_path / "golden.csv").out

"""LinuxCNC as a second real controller: a headless instance (Debian linuxcnc-uspace, installed by
tests/setup_system.sh), the demo campaign through linuxcncrsh, and the closed loop through
LinuxCNC's own COMP_FILE loader and motion module. axiscal applies nothing itself on this path:
the compensation can only come from LinuxCNC."""

import configparser
import json
import shutil

import pytest

from campaign.commands.demo import demo_config_text
from campaign.commands.linuxcnc_demo import linuxcnc_config
from campaign.config import parse_config
from campaign.plan import check_plan, make_plan
from campaign.specs import AxisSpec
from drivers.linuxcnc.process import ini_text
from tests.conftest import assert_one_line_error
from tests.test_demo_e2e import axiscal

INSTALLED = all(shutil.which(tool) for tool in ("linuxcnc", "linuxcncrsh", "halcmd"))


@pytest.mark.machine
@pytest.mark.skipif(not INSTALLED, reason="LinuxCNC is not installed (tests/setup_system.sh installs "
                                          "linuxcnc-uspace where apt is available)")
def test_demo_on_linuxcnc_with_its_own_compensation(tmp_path):
    # two of the demo's five cycles each way: LinuxCNC runs in real time and, with the demo's own
    # 50 mm/s limit, the five cycles each way take about 7.5 minutes, most of `make test`'s budget
    # (docs/linuxcnc.md gives the full run's figures: 110 points each way, A 9.40 -> 2.24 µm)
    proc = axiscal("demo", "--controller", "linuxcnc", "--verify", "--json", "--cycles", "2",
                   "--out", tmp_path / "lc", timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    data = json.loads(proc.stdout)
    assert data["points"] == 44 and data["points_after"] == 44
    assert data["A_after"] <= 0.5 * data["A_before"], data
    lines = (tmp_path / "lc" / "comp.txt").read_text().splitlines()
    assert len(lines) == 11 and all(len(line.split()) == 3 for line in lines)
    # one LinuxCNC per machine: while one is held, a second demo is refused before it starts one
    # (it used to connect to the first one's linuxcncrsh and drive its axis)
    from drivers.linuxcnc.process import _one_instance
    from tests.test_crash_safety import data_rows

    held = _one_instance()
    try:
        second = axiscal("demo", "--controller", "linuxcnc", "--out", tmp_path / "second", timeout=60)
    finally:
        held.close()
    assert second.returncode == 3 and second.stderr.startswith("error: another axiscal is running LinuxCNC")
    table = tmp_path / "second" / "points.csv"
    assert not table.exists() or data_rows(table) == 0  # no point was measured on the first one's axis


@pytest.mark.skipif(INSTALLED, reason="checks the message when LinuxCNC is missing")
def test_without_linuxcnc_the_demo_says_how_to_install(cli):
    assert_one_line_error(cli("demo", "--controller", "linuxcnc"), "apt-get install linuxcnc-uspace")


def test_verify_needs_the_linuxcnc_controller(cli):
    assert_one_line_error(cli("demo", "--verify"), "--controller linuxcnc")


def test_the_generated_ini_has_the_demo_configs_limits_and_the_quick_plan_keeps_within_them():
    """The LinuxCNC demo's joint is the demo's axis: soft limits, maximum velocity and acceleration
    from demo.toml's [axis] (issue 26 item 6; it had 300 mm/s and 3000 mm/s² of its own). Only the
    plan is made quick, within those limits."""
    demo = parse_config(demo_config_text(), "demo.toml").axis
    config = linuxcnc_config(demo_config_text())
    ini = configparser.ConfigParser()
    ini.read_string(ini_text(config.axis, None))
    for section in ("JOINT_0", "AXIS_X"):
        got = {key: float(ini[section][key]) for key in ("MIN_LIMIT", "MAX_LIMIT", "MAX_VELOCITY", "MAX_ACCELERATION")}
        assert got == {"MIN_LIMIT": demo.soft_limit_min, "MAX_LIMIT": demo.soft_limit_max,
                       "MAX_VELOCITY": demo.max_velocity, "MAX_ACCELERATION": demo.max_acceleration}, section
    assert float(ini["TRAJ"]["MAX_LINEAR_VELOCITY"]) == demo.max_velocity
    assert float(ini["TRAJ"]["MAX_LINEAR_ACCELERATION"]) == demo.max_acceleration
    assert ini["TRAJ"]["LINEAR_UNITS"] == "mm" and "COMP_FILE" not in ini["JOINT_0"]
    # every move of the demo's plan on LinuxCNC keeps within the joint's limits as the INI states them
    joint = AxisSpec(name="X", kind="linear", unit="mm", soft_limit_min=float(ini["JOINT_0"]["MIN_LIMIT"]),
                     soft_limit_max=float(ini["JOINT_0"]["MAX_LIMIT"]),
                     max_velocity=float(ini["JOINT_0"]["MAX_VELOCITY"]),
                     max_acceleration=float(ini["JOINT_0"]["MAX_ACCELERATION"]))
    check_plan(make_plan(config.plan, config.capture), joint)
    assert config.plan.velocity == demo.max_velocity  # made quick: the fastest the demo's axis allows


def test_the_generated_ini_takes_a_configs_own_limits_and_comp_file(tmp_path):
    text = demo_config_text().replace("soft_limit_min = -10.0", "soft_limit_min = -2.5").replace(
        "max_acceleration = 200.0", "max_acceleration = 150.0")
    ini = configparser.ConfigParser()
    ini.read_string(ini_text(linuxcnc_config(text).axis, tmp_path / "comp.txt"))
    assert (ini["JOINT_0"]["MIN_LIMIT"], ini["AXIS_X"]["MAX_ACCELERATION"]) == ("-2.5", "150.0")
    assert (ini["JOINT_0"]["COMP_FILE"], ini["JOINT_0"]["COMP_FILE_TYPE"]) == (str(tmp_path / "comp.txt"), "0")

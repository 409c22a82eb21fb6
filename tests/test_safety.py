"""Nothing unsafe is commanded: limits before every motion (also on resume), read-only dry run,
writes limited to the PLC contract."""

import json

import pytest

from campaign.config import parse_config
from campaign.errors import SafetyError
from campaign.measure.executor import Executor
from campaign.measure.session import dry_run
from campaign.plan import Move, build_plan, plan_records
from campaign.record.recorder import Recorder
from drivers.factory import open_hardware
from protocols import plc_contract
from tests.conftest import ROOT, assert_one_line_error
from tests.test_crash_safety import start_slow_demo, wait_for_points
from tests.test_demo_e2e import axiscal

DEMO = (ROOT / "campaign" / "demo.toml").read_text()


def control_values(plc):
    return {member: plc.value(symbol.name) for member, symbol in plc_contract.control_symbols(1).items()}


@pytest.mark.machine
def test_dry_run_commands_nothing():
    config = parse_config(DEMO, "demo.toml")
    hardware, sim = open_hardware(parse_config(DEMO.replace('type = "sim"\n', 'type = "sim"\nread_only = true\n', 1),
                                               "ro.toml").driver)
    before = control_values(sim.plc)
    report = dry_run(config, opened=(hardware, sim))
    assert report["read_only"] and report["points"] == 110 and report["readings"] >= 9
    assert report["axis_enabled"] and report["beam_ok"]
    assert control_values(sim.plc) == before  # no symbol written
    assert sim.plc.setpoint_position(sim.clock.now()) == 0.0  # the axis never moved


@pytest.mark.machine
def test_dry_run_command(tmp_path):
    proc = axiscal("run", ROOT / "data/configs/vertical-sim.toml", "--dry-run", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["read_only"] and data["plan_within_limits"] and data["axis_position"] == 0.0


@pytest.mark.machine
@pytest.mark.parametrize("position, velocity, why", [(700.0, 8.0, "soft limits"), (100.0, 80.0, "velocity")])
def test_every_motion_is_checked_before_it_is_sent(tmp_path, position, velocity, why):
    config = parse_config(DEMO, "demo.toml")
    plan = build_plan(config)
    hardware, sim = open_hardware(config.driver)
    recorder = Recorder.create(tmp_path / "c", DEMO, {}, plan_records(plan), {}, "linear")
    executor = Executor(plan, config, hardware, recorder)
    try:
        with pytest.raises(SafetyError, match=why):
            executor._move(Move(position, velocity))
        sent = control_values(sim.plc)
        assert sent["fPosition"] == 0.0 and sent["bExecute"] is False
        assert sim.plc.setpoint_position(sim.clock.now()) == 0.0
    finally:
        hardware.close()
        recorder.close()


@pytest.mark.machine
def test_resume_checks_the_limits_before_moving(tmp_path, cli):
    out = tmp_path / "r"
    proc = start_slow_demo(out)
    wait_for_points(out / "points.csv", 3, proc)
    proc.kill()
    proc.wait(timeout=10)
    config = out / "config.toml"
    config.write_text(config.read_text().replace("soft_limit_min = -10.0", "soft_limit_min = -1.0"))
    size = (out / "raw.csv").stat().st_size
    result = cli("resume", out)
    assert result.code == 2 and "soft limits" in result.err
    assert (out / "raw.csv").stat().st_size == size  # nothing ran


def test_hardware_type_is_a_closed_set():
    """No config key names an ADS symbol: the axis driver writes only the contract's symbols."""
    from campaign.config import SCHEMA

    keys = {k for section in SCHEMA.values() for k in section}
    assert not any("symbol" in k or "gvl" in k.lower() for k in keys)
    assert plc_contract.writable_symbols(1) == {s.name for s in (*plc_contract.control_symbols(1).values(),
                                                                   *plc_contract.comp_symbols(1).values())}
    assert not plc_contract.writable_symbols(1) & {s.name for s in plc_contract.status_symbols(1).values()}


def test_a_dry_run_without_the_plc_says_where_it_looked_and_exits_2(cli, tmp_path):
    """No PLC listens on 127.0.0.1 here (the suite's simulated PLCs take 127.0.x.y, y ≥ 2): the dry run changes nothing, so it is a set-up error (exit 2)
    naming the IP, the AMS Net ID, the port and the usual causes."""
    text = DEMO.replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "ads"\nip = "127.0.0.1"\n'
                        'ams_net_id = "127.0.0.1.1.1"\ntimeout_s = 0.2')
    text = text.replace('[instrument]\ntype = "sim"', '[instrument]\ntype = "serial"\nport = "/dev/null"')
    path = tmp_path / "away.toml"
    path.write_text(text)
    assert_one_line_error(cli("run", path, "--dry-run"), "dry run: ", "PLC at IP 127.0.0.1",
                          "AMS Net ID 127.0.0.1.1.1", "port 851", "ADS route", "not in RUN", "cable")


@pytest.mark.machine
def test_a_wrong_ams_port_fails_on_the_simulated_machine_as_on_a_real_one(cli, tmp_path):
    """The simulated PLC answers only on port 851, as a TwinCAT 3 PLC runtime: the router's 0x6
    (target port not found), and the hint names the port."""
    path = tmp_path / "port852.toml"
    path.write_text(DEMO.replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "sim"\nams_port = 852'))
    assert_one_line_error(cli("run", path, "--dry-run"), "dry run: ", "Target port not found", "port 852",
                          "ams_port is wrong")

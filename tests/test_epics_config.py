"""`[axis_driver] type = "epics"` and the EPICS faults, as the config and the command line read them
(fast tier: nothing is opened)."""

from __future__ import annotations

import pytest

from campaign.commands.demo import demo_config_text
from campaign.commands.epics_demo import epics_config
from campaign.config import parse_config
from campaign.errors import InputError
from campaign.faults import parse_faults, parse_inject


def test_the_epics_demo_config_names_the_motor_record():
    config = epics_config(demo_config_text())
    assert (config.controller.type, config.controller.pv) == ("epics", "SIM:M1")
    assert config.simulated  # instrument.type sim: the simulated IOC


def test_a_real_motor_record_needs_a_real_laser_port():
    text = demo_config_text().replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "epics"\npv = "BL01:MOT1"')
    text = text.replace('[instrument]\ntype = "sim"', '[instrument]\ntype = "serial"')
    with pytest.raises(InputError, match="instrument.port"):
        parse_config(text, "real.toml")
    config = parse_config(text.replace('type = "serial"', 'type = "serial"\nport = "/dev/ttyUSB0"'), "real.toml")
    assert config.controller.pv == "BL01:MOT1" and not config.simulated


def test_an_unknown_controller_type_is_refused_naming_epics_among_the_choices():
    text = demo_config_text().replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "pva"')
    with pytest.raises(InputError, match="epics"):
        parse_config(text, "x.toml")


def test_the_epics_faults_are_known_with_their_defaults():
    assert parse_inject("ca_lost@200,limit_switch@400,stall@600") == {
        "ca_lost": {"at_s": 200.0}, "limit_switch": {"at_s": 400.0}, "stall": {"at_s": 600.0}}
    faults = parse_faults({"ca_lost": {"at_s": 5.0}, "stall": {}}, "x.toml")
    assert [(f.name, f.at_s, f.params) for f in faults] == [("ca_lost", 5.0, {"duration_s": 5.0}),
                                                           ("stall", 120.0, {})]


def test_the_epics_faults_are_refused_on_the_ads_machine_before_anything_opens():
    from drivers.factory import open_hardware

    config = parse_config(demo_config_text() + "\n[sim.faults]\nlimit_switch = { at_s = 10.0 }\n", "demo.toml")
    with pytest.raises(InputError, match='limit_switch rehearse the EPICS axis'):
        open_hardware(config.driver)


REAL = demo_config_text().replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "epics"\nPV_LINE').replace(
    '[instrument]\ntype = "sim"', '[instrument]\ntype = "serial"\nport = "/dev/ttyUSB0"')


@pytest.mark.parametrize("pv_line, says", [
    ("", "required for a real IOC"),  # no silent SIM:M1 for a real IOC
    ('pv = ""', "required for a real IOC"),
    ('pv = "BL01:MOT1.VAL"', "names a field"),
    ('pv = "BL01: MOT1"', "' ' is not allowed"),
    ('pv = "BL01:MOT1\\t"', "'\\t' is not allowed"),
    ('pv = "BL01:MÖT1"', "is not allowed"),
    (f'pv = "{"M" * 61}"', "61 characters"),
])
def test_a_bad_motor_record_name_is_refused_naming_the_key(pv_line, says):
    with pytest.raises(InputError, match="axis_driver.pv") as refused:
        parse_config(REAL.replace("PV_LINE", pv_line), "real.toml")
    assert says in str(refused.value)


def test_good_motor_record_names_and_the_simulated_iocs_default():
    for pv in ("BL01:MOT1", "LAB-MC-01:Axis_2", "M" * 60, "IOC:m1[0]"):
        assert parse_config(REAL.replace("PV_LINE", f'pv = "{pv}"'), "real.toml").controller.pv == pv
    simulated = demo_config_text().replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "epics"')
    assert parse_config(simulated, "sim.toml").controller.pv == ""  # the simulated IOC serves SIM:M1


def test_a_bad_motor_record_name_exits_2_with_one_error_line(tmp_path, capsys):
    from campaign.cli import main

    (tmp_path / "real.toml").write_text(REAL.replace("PV_LINE", 'pv = "BL01:MOT1.RBV"'))
    assert main(["verify", str(tmp_path / "real.toml"), "--comp", str(tmp_path / "none.corr")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "axis_driver.pv" in lines[0], lines


def test_the_bluesky_extra_brings_a_channel_access_layer_for_ophyd():
    """ophyd's EpicsMotor talks Channel Access through pyepics (its default) or caproto: `pip install
    'axiscal[bluesky]'` must bring one, or the beamline's session cannot move a motor."""
    import re
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    extra = project["project"]["optional-dependencies"]["bluesky"]
    names = {re.split(r"[<>=!~\[ ;]", requirement, maxsplit=1)[0].lower() for requirement in extra}
    assert {"bluesky", "ophyd"} <= names and names & {"pyepics", "caproto"}, extra


def test_a_missing_caproto_is_exit_2_with_one_error_line(tmp_path, monkeypatch, capsys):
    """Without caproto (the `epics` extra not installed) an EPICS config ends in exit 2 and one
    `error:` line saying what to install, not a traceback."""
    import sys

    from campaign.cli import main
    from campaign.commands.epics_demo import EPICS_DRIVER

    for name in [name for name in sys.modules if name == "caproto" or name.startswith(("caproto.", "drivers.epics"))]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "caproto", None)  # import caproto raises ImportError
    config = demo_config_text().replace('[axis_driver]\ntype = "sim"', EPICS_DRIVER).replace("cycles = 5", "cycles = 1")
    (tmp_path / "epics.toml").write_text(config)
    (tmp_path / "x.corr").write_text("PREC=10\n0 0\n300 0\n600 0\n")
    assert main(["verify", str(tmp_path / "epics.toml"), "--comp", str(tmp_path / "x.corr"),
                 "--out", str(tmp_path / "after")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "caproto" in lines[0], lines

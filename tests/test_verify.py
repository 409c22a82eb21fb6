"""Closed loop: measure, compensate, write the table into the (simulated) PLC over ADS, measure
again with the compensation applied as FB_AxiscalCompensation does, compare before and after."""

import json
import re

import pytest

from campaign.compensation.table_file import read_comp_json
from tests.conftest import ROOT, assert_one_line_error, once_per_run
from tests.test_demo_e2e import axiscal

CONFIGS = ROOT / "data" / "configs"


@pytest.fixture(scope="module")
def vertical(tmp_path_factory):
    """The vertical axis of Li et al. 2022 (490 µm reversal): baseline, bidirectional table, verification.
    Made once per run (once_per_run), read only."""

    def make(base):
        assert axiscal("run", CONFIGS / "vertical-sim.toml", "--out", base / "before").returncode == 0
        comp = axiscal("compensate", base / "before" / "points.csv", "--format", "json", "-o", base / "t.json",
                       "--overrun", "5")
        assert comp.returncode == 0, comp.stderr
        proc = axiscal("verify", CONFIGS / "vertical-sim.toml", "--comp", base / "t.json", "--before",
                       base / "before", "--out", base / "after", "--json")
        assert proc.returncode == 0, proc.stderr
        (base / "verify.json").write_text(proc.stdout)

    base = once_per_run(tmp_path_factory, "vertical", make)
    return base, json.loads((base / "verify.json").read_text())


@pytest.mark.machine
def test_compensation_removes_the_systematic_error(vertical):
    _base, data = vertical
    before, after = data["before"], data
    assert before["A"] > 700 and before["B"] > 350  # the paper's vertical axis: ~800 µm, ~490 µm reversal
    assert after["points"] == 110 and after["status"] == "completed"
    assert after["verdict"] == "pass"  # the shared verdict: A + U within the config's 40 µm (700 µm before)
    floor = max(after["R_up"], after["R_down"])  # 4 s_max: what is left once every mean is removed
    assert after["A"] < 1.5 * floor
    # what is left of the reversal and the systematic deviation is the means' own scatter: B is a
    # difference of two 5-run means (sd √2·s/√5 ≈ 0.16 of 4s), E a spread of 22 means
    assert after["B"] < 0.5 * floor and after["E"] < 0.75 * floor
    assert before["B"] / after["B"] > 100


@pytest.mark.machine
def test_verification_is_recorded_with_its_baseline(vertical):
    base, _ = vertical
    meta = json.loads((base / "after" / "meta.json").read_text())
    assert meta["baseline_dir"] == str((base / "before").resolve())
    assert meta["compensation"]["mode"] == "bi"
    table = json.loads((base / "after" / "plc-compensation.json").read_text())
    written = read_comp_json(base / "t.json")
    assert table["forward"] == pytest.approx(list(written.forward * 1e-3))  # µm -> mm in the PLC
    md = (base / "after" / "verification.md").read_text()
    assert "Before compensation: forward (+) deviations" in md and "| A | accuracy, bidirectional |" in md and "| A_up | accuracy, + direction |" in md
    assert (base / "after" / "verification.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.machine
def test_report_shows_before_and_after(vertical, tmp_path):
    base, _ = vertical
    proc = axiscal("report", base / "after", "-o", tmp_path / "r.html")
    assert proc.returncode == 0, proc.stderr
    html = (tmp_path / "r.html").read_text()
    assert "Before" in html and "After" in html


@pytest.mark.machine
def test_write_plc_round_trip(vertical, tmp_path):
    base, _ = vertical
    proc = axiscal("compensate", base / "before" / "points.csv", "--format", "json", "-o", tmp_path / "t.json",
                   "--write-plc", CONFIGS / "vertical-sim.toml")
    assert proc.returncode == 0, proc.stderr
    assert "read back equal, enabled" in proc.stdout


def test_verify_bad_input(cli, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"position_unit": "mm", "forward": [1]}')
    assert_one_line_error(cli("verify", CONFIGS / "vertical-sim.toml", "--comp", bad), "bad.json")
    assert_one_line_error(cli("verify", CONFIGS / "vertical-sim.toml", "--comp", tmp_path / "none.json"),
                          "no such file")
    rotary = tmp_path / "rot.json"
    rotary.write_text(json.dumps({"position_unit": "deg", "start": 0, "spacing": 10, "forward": [0, 1],
                                  "reverse": [0, 1], "common": [0, 1], "mode": "uni"}))
    assert_one_line_error(cli("verify", CONFIGS / "vertical-sim.toml", "--comp", rotary), "rotary")


@pytest.mark.machine
def test_simulated_plc_takes_a_rewritten_table(tmp_path):
    """Like FB_AxiscalCompensation, which reads stComp every cycle: a table written while another is
    active is applied, approached with the planner's bounded rate."""
    import numpy as np

    from campaign.config import parse_config
    from drivers.factory import open_hardware
    from protocols.plc_contract import CompTable

    config = parse_config((ROOT / "campaign" / "demo.toml").read_text(), "demo.toml")
    hardware, sim = open_hardware(config.driver)
    try:
        def table(value_mm):
            return CompTable((value_mm,) * 3, (value_mm,) * 3, 0.0, 300.0, 0.0, 0.01, 0.1, True)

        hardware.axis.write_comp_table(table(0.002))
        hardware.clock.sleep(1.0)
        assert sim.plc.correction == pytest.approx(0.002)
        hardware.axis.write_comp_table(table(-0.003))
        hardware.clock.sleep(0.1)
        assert 0.002 > sim.plc.correction > -0.003  # on its way, rate-limited
        hardware.clock.sleep(2.0)
        assert sim.plc.correction == pytest.approx(-0.003)
        assert np.isfinite(sim.plc.correction)
    finally:
        hardware.close()


@pytest.mark.machine
def test_verify_takes_a_linuxcnc_table_like_the_json_one(vertical, tmp_path):
    """The same compensation written as a LinuxCNC comp file (1 nm resolution) verifies to the
    same result as the JSON table: the simulated machine draws the same readings."""
    base, from_json = vertical
    comp = axiscal("compensate", base / "before" / "points.csv", "--format", "linuxcnc", "-o", tmp_path / "t.comp",
                   "--overrun", "5")
    assert comp.returncode == 0, comp.stderr
    proc = axiscal("verify", CONFIGS / "vertical-sim.toml", "--comp", tmp_path / "t.comp", "--out", tmp_path / "after-lcnc",
                   "--json")
    assert proc.returncode == 0, proc.stderr
    from_file = json.loads(proc.stdout)
    assert from_file["points"] == 110
    for key in ("A", "B", "E", "R"):
        assert from_file[key] == pytest.approx(from_json[key], abs=0.01), key


def comp_json(path, start, spacing, points, **provenance):
    """A compensate JSON table of `points` zero corrections, with the provenance given."""
    zeros = [0.0] * points
    path.write_text(json.dumps({"position_unit": "mm", "start": start, "spacing": spacing, "forward": zeros,
                                "reverse": zeros, "common": zeros, "mode": "uni", "provenance": provenance}))
    return path


def test_verify_refuses_another_axis_table_before_writing_to_the_controller(cli, tmp_path, monkeypatch):
    """A 600 mm X table on the 300 mm Z config: exit 2 with one line naming what disagrees, and the
    controller is never opened, so nothing is written to it (the old code warned, wrote the table
    and ran the whole campaign)."""
    from tests.fakes import FakeMachine

    machine = FakeMachine()
    monkeypatch.setattr("campaign.commands.verify.hardware_opener", lambda: machine)
    table = comp_json(tmp_path / "x.json", 0.0, 60.0, 11, machine="sim-press", axis="X")
    result = cli("verify", CONFIGS / "vertical-sim.toml", "--comp", table, "--out", tmp_path / "after")
    assert_one_line_error(result, "x.json", "axis 'X'", "axis 'Z'", "0 to 600 mm", "--force")
    assert machine.openings == [] and not (tmp_path / "after").exists()
    # the same travel, but made for another machine: refused too
    other = comp_json(tmp_path / "m.json", 0.0, 30.0, 11, machine="mill-2", axis="Z")
    assert_one_line_error(cli("verify", CONFIGS / "vertical-sim.toml", "--comp", other), "machine 'mill-2'")
    assert machine.openings == []


def test_verify_refuses_a_table_whose_correction_leaves_the_soft_limits_even_with_force(cli, tmp_path, monkeypatch):
    """With the table active the motor goes to the command plus the correction: one mistyped reverse
    value (599.996 mm where a few µm were meant) would take it to 1,200 mm on a 610 mm axis. A new
    user's trial did so: the old code warned of a spike, wrote the table and drove the simulated axis
    to 753 mm. Refused with exit 2 before the controller is opened, --force or not."""
    from tests.fakes import SMALL, FakeMachine

    machine = FakeMachine()
    monkeypatch.setattr("campaign.commands.verify.hardware_opener", lambda: machine)
    config = tmp_path / "small.toml"
    config.write_text(SMALL)
    good = comp_json(tmp_path / "ok.json", 0.0, 25.0, 5, machine="fake", axis="X")
    bad = json.loads(good.read_text())
    bad["mode"], bad["reverse"][-1] = "bi", 599_996.0  # µm: the table's unit
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    for force in ((), ("--force",)):
        result = cli("verify", config, "--comp", tmp_path / "bad.json", "--out", tmp_path / "after", *force)
        assert_one_line_error(result, "bad.json", "moving - at 100 mm", "outside the soft limits")
    assert machine.openings == [] and not (tmp_path / "after").exists()
    # the same table with the value meant loads
    bad["reverse"][-1] = 3.0
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    assert cli("verify", config, "--comp", tmp_path / "bad.json", "--out", tmp_path / "after").code == 0


def test_verify_force_loads_another_axis_table_and_says_so(cli, tmp_path, monkeypatch):
    from tests.fakes import SMALL, FakeMachine

    machine = FakeMachine()
    monkeypatch.setattr("campaign.commands.verify.hardware_opener", lambda: machine)
    config = tmp_path / "small.toml"
    config.write_text(SMALL)
    table = comp_json(tmp_path / "y.json", 0.0, 25.0, 5, machine="fake", axis="Y")
    result = cli("verify", config, "--comp", table, "--out", tmp_path / "after", "--force")
    assert result.code == 0, result.err
    assert "made for axis 'Y'" in result.out and "loaded anyway: --force" in result.out
    assert machine.openings and machine.openings[0].axis.comp is not None


@pytest.mark.machine
def test_the_report_of_a_verification_names_its_table_and_campaigns(cli, tmp_path, monkeypatch):
    """The verification campaign keeps the table it wrote and records its file, format, checksum and
    source campaign; the report names them, and the before and after campaigns by id and relative to
    the report (the old report said neither, and gave the before campaign as an absolute path)."""
    import hashlib

    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from tests.fakes import SMALL, FakeMachine

    machine = FakeMachine()
    monkeypatch.setattr("campaign.commands.verify.hardware_opener", lambda: machine)
    config = tmp_path / "small.toml"
    config.write_text(SMALL)
    before = tmp_path / "runs" / "fake-X-before"
    start_campaign(parse_config(SMALL, "small.toml"), before, opener=machine)
    table = tmp_path / "tables" / "x.comp"
    table.parent.mkdir()
    assert cli("compensate", before / "points.csv", "--format", "linuxcnc", "-o", table).code == 0
    after = tmp_path / "runs" / "fake-X-after"
    result = cli("verify", config, "--comp", table, "--before", before, "--out", after)
    assert result.code == 0, result.err
    assert "A_up" in result.out and "A↑" not in result.out  # the summary's names (the old table said A↑)
    assert (after / "compensation-table.comp").read_bytes() == table.read_bytes()
    digest = hashlib.sha256(table.read_bytes()).hexdigest()
    meta = json.loads((after / "meta.json").read_text())
    assert meta["compensation"]["table"]["format"] == "linuxcnc"
    assert meta["compensation"]["table"]["sha256"] == digest
    report = tmp_path / "filed" / "report.html"
    assert cli("report", after, "-o", report).code == 0
    html = report.read_text()
    for text in ("Compensation table verified", "x.comp", "linuxcnc", digest, "fake-X-before",
                 "../runs/fake-X-before", "../runs/fake-X-after", "compensation-table.comp", "Sign-off",
                 "Checked by", "Approved by", "Page &quot;", "counter(pages)"):
        assert text in html or text.replace("&quot;", '"') in html, text
    assert str(tmp_path) not in html  # no absolute path of this PC
    assert "not said by the table" in html  # a LinuxCNC file has no comments to name its campaign
    json_table = tmp_path / "tables" / "x.json"
    assert cli("compensate", before / "points.csv", "--format", "json", "-o", json_table).code == 0
    assert cli("verify", config, "--comp", json_table, "--out", tmp_path / "runs" / "json-after").code == 0
    assert cli("report", tmp_path / "runs" / "json-after", "-o", report).code == 0
    assert re.search(r"Computed from</th><td>campaign fake-X-before, measured 20\d\d-", report.read_text())

"""LinuxCNC as a second real controller: a headless instance (Debian linuxcnc-uspace, installed by
tests/setup_system.sh), the demo campaign through linuxcncrsh, and the closed loop through
LinuxCNC's own COMP_FILE loader and motion module. axiscal applies nothing itself on this path:
the compensation can only come from LinuxCNC."""

import json
import shutil

import pytest

from tests.conftest import assert_one_line_error
from tests.test_demo_e2e import axiscal

INSTALLED = all(shutil.which(tool) for tool in ("linuxcnc", "linuxcncrsh", "halcmd"))


@pytest.mark.machine
@pytest.mark.skipif(not INSTALLED, reason="LinuxCNC is not installed (tests/setup_system.sh installs "
                                          "linuxcnc-uspace where apt is available)")
def test_demo_on_linuxcnc_with_its_own_compensation(tmp_path):
    # the whole demo campaign (5 cycles) each way, as the acceptance asks
    proc = axiscal("demo", "--controller", "linuxcnc", "--verify", "--json", "--out", tmp_path / "lc", timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    data = json.loads(proc.stdout)
    assert data["points"] == 110 and data["points_after"] == 110
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

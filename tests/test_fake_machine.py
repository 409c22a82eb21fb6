"""The fake machine shipped in the product (drivers/fake.py): `axiscal demo --fake` runs the demo
campaign in-process, without a socket or a pty, and a run-time import never reaches it unless asked."""

import json
import socket
import subprocess
import sys

import pytest

from tests.conftest import events


def test_demo_fake_completes_without_a_socket_and_ends_stopped(cli, tmp_path, monkeypatch):
    def no_socket(*args, **kwargs):
        raise AssertionError("demo --fake opened a socket")

    monkeypatch.setattr(socket.socket, "__init__", no_socket)  # the fast tier's guard already refuses the ADS server and ptys
    out = tmp_path / "fake"
    result = cli("demo", "--fake", "--cycles", "1", "--out", out, "--json")
    assert result.code == 0, result.err[-2000:]
    summary = json.loads(result.out)
    assert (summary["status"], summary["points"], summary["planned"]) == ("completed", 22, 22)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["driver"] == "fake" and meta["machine"] == "fake-press"
    states = events(out, "state")
    assert states[-1]["data"] == {"state": "stopped", "previous": "idle", "reason": "completed"}
    # the demo's error model through the simulated machine's physics: the deviation at 600 mm is the
    # linear scale error (-12.4 ppm: -7.44 µm) within its scatter, not the tests' 10 µm/m default
    at_end = [e["data"]["deviation"] for e in events(out, "point") if e["data"]["target"] == 600.0]
    assert at_end and all(-9.5 < d < -5.5 for d in at_end), at_end


@pytest.mark.parametrize("option", [["--inject", "beam_break@100"], ["--controller", "linuxcnc"], ["--speed", "2"]])
def test_demo_fake_refuses_what_needs_the_simulated_machine(cli, tmp_path, option):
    result = cli("demo", "--fake", *option, "--out", tmp_path / "x")
    assert result.code == 2 and "error: --fake:" in result.err
    assert not (tmp_path / "x").exists()


def test_a_run_time_import_does_not_load_the_fake_machine():
    code = ("import sys, campaign.cli, campaign.commands.demo, drivers.factory; "
            "from campaign.commands import hardware_opener; hardware_opener(); "
            "assert 'drivers.fake' not in sys.modules, 'imported'; "
            "hardware_opener(fake=True); assert 'drivers.fake' in sys.modules")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_demo_fake_syncs_no_point_to_disk_while_a_real_campaign_syncs_every_point(cli, tmp_path, monkeypatch):
    """Where demo --fake's wall time went: four fsyncs per point (455 for the demo, about 5 s of a
    6 s campaign on a busy disk, for a machine that does not exist). The fake demo's recording is
    not synced per point; a campaign on a machine (the default) still syncs every point."""
    import os

    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from drivers.fake import FakeMachine
    from tests.fakes import SMALL

    synced: list[int] = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real_fsync(fd))[1])
    result = cli("demo", "--fake", "--cycles", "1", "--out", tmp_path / "fake", "--json")
    assert result.code == 0, result.err[-2000:]
    assert json.loads(result.out)["points"] == 22
    assert len(synced) <= 10, f"{len(synced)} fsyncs for 22 fake points"
    synced.clear()
    outcome = start_campaign(parse_config(SMALL, "small.toml"), tmp_path / "real", opener=FakeMachine())
    assert outcome.points == 12 and len(synced) >= 3 * 12, "a campaign's points are no longer synced one by one"

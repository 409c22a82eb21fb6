"""`axiscal replay`: the recorded timeline through the same capture code, offline."""

import json
import shutil

import pytest

from tests.conftest import assert_one_line_error
from tests.test_demo_e2e import axiscal


@pytest.fixture(scope="module")
def recorded(tmp_path_factory, demo_campaign):
    base = tmp_path_factory.mktemp("replay")
    for method in ("dwell", "stable"):  # the demo's own capture is the dwell
        shutil.copytree(demo_campaign(*(("--capture", method) if method != "dwell" else ()))[1], base / method)
    return base


@pytest.mark.machine
@pytest.mark.parametrize("method", ["dwell", "stable"])
def test_recorded_settings_reproduce_the_point_table(cli, recorded, method):
    result = cli("replay", recorded / method, "--json")
    data = json.loads(result.out)
    assert result.code == 0
    assert data["identical"] and data["differences"] == [] and data["points"] == 110
    assert data["summary_replayed"] == pytest.approx(data["summary_recorded"])


@pytest.mark.machine
def test_a_demo_directory_replays_without_its_config_toml(cli, recorded, tmp_path):
    """plan.jsonl describes the campaign (plan format 2): config.toml is not needed."""
    import shutil

    copy = tmp_path / "no-config"
    shutil.copytree(recorded / "stable", copy)
    (copy / "config.toml").unlink()
    data = json.loads(cli("replay", copy, "--json").out)
    assert data["identical"] and data["points"] == 110 and data["capture"] == "stable"
    assert cli("analyze", copy, "--json").code == 0


@pytest.mark.machine
def test_other_capture_settings_show_what_changes(cli, recorded):
    data = json.loads(cli("replay", recorded / "dwell", "--capture", "stable", "--json").out)
    assert not data["identical"] and data["capture"] == "stable"
    assert len(data["differences"]) > 50
    assert all(d["wait_s"] < 4.0 for d in data["differences"] if d["wait_s"] is not None)
    # captured earlier, while the axis still settles: the summary moves
    assert data["summary_replayed"]["A"] != pytest.approx(data["summary_recorded"]["A"], abs=1e-3)
    text = cli("replay", recorded / "dwell", "--average-s", "2.0").out
    assert "change with dwell capture" in text and "recorded" in text


@pytest.mark.machine
def test_window_longer_than_the_recording_is_reported(cli, recorded):
    """A stable-trigger recording stops soon after arrival: a 3 s dwell average cannot be had."""
    data = json.loads(cli("replay", recorded / "stable", "--capture", "dwell", "--average-s", "3",
                          "--json").out)
    assert data["points"] == 0
    assert all("holds only" in d["note"] for d in data["differences"])


@pytest.mark.machine
def test_replay_of_a_resumed_campaign(cli, tmp_path):
    """kill -9, resume, replay: the raw stream of both processes reproduces the point table."""
    import signal

    from tests.test_crash_safety import start_slow_demo, wait_for_points

    out = tmp_path / "r"
    proc = start_slow_demo(out)
    wait_for_points(out / "points.csv", 6, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    assert axiscal("resume", out).returncode == 0
    data = json.loads(cli("replay", out, "--json").out)
    assert data["identical"] and data["points"] == 110, data["differences"][:3]


def test_replay_bad_input(cli, tmp_path):
    assert_one_line_error(cli("replay", tmp_path), str(tmp_path))
    assert_one_line_error(cli("replay", tmp_path, "--average-s", "-1"), "--average-s")


def test_an_average_longer_than_the_dwell_is_refused(cli, tmp_path):
    """--average-s 100 on a 1 s dwell: one error line (the old replay took it and averaged the
    dwell it had); a window within the dwell is replayed."""
    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from tests.fakes import SMALL, FakeMachine

    start_campaign(parse_config(SMALL, "small.toml"), tmp_path / "c", opener=FakeMachine())
    assert_one_line_error(cli("replay", tmp_path / "c", "--average-s", "100"), "--average-s 100",
                          "recorded dwell of 1 s")
    assert cli("replay", tmp_path / "c", "--average-s", "0.8", "--json").code == 0


def test_a_setting_the_capture_does_not_read_is_refused(cli, tmp_path):
    """--stable-tolerance on a dwell capture (and --average-s on a stable one) changed nothing, and the
    replay said it reproduced the table: the user believed the setting made no difference."""
    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from tests.fakes import SMALL, FakeMachine

    start_campaign(parse_config(SMALL, "small.toml"), tmp_path / "c", opener=FakeMachine())
    assert_one_line_error(cli("replay", tmp_path / "c", "--stable-tolerance", "0.1"), "--stable-tolerance",
                          "not read by the dwell capture", "--capture")
    assert_one_line_error(cli("replay", tmp_path / "c", "--capture", "stable", "--average-s", "0.5"),
                          "--average-s", "not read by the stable capture")
    assert cli("replay", tmp_path / "c", "--capture", "stable", "--stable-tolerance", "5", "--json").code == 0


@pytest.mark.machine
def test_a_band_the_recording_never_meets_is_said_per_point(cli, recorded):
    """A stable band far below the reading noise: no point is stable within its timeout. Each is
    said as such, as the live campaign's fault would be (it was an internal error, exit 1)."""
    result = cli("replay", recorded / "stable", "--stable-tolerance", "0.0001", "--json")
    assert result.code == 0, result.err
    data = json.loads(result.out)
    assert data["points"] < 110
    assert any("not stable" in d["note"] for d in data["differences"])

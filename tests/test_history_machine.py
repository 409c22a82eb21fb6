"""The store under stress, with real processes (machine tier): two `axiscal history import`
processes writing at once lose nothing, on SQLite and on PostgreSQL; a campaign killed with
SIGKILL mid-run is not lost: importing its directory records it as it stands, and its resume
records it complete, once."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from tests.conftest import ROOT
from tests.test_crash_safety import start_slow_demo, wait_for_points
from tests.test_history import db  # noqa: F401 - the store fixture, SQLite and PostgreSQL

pytestmark = pytest.mark.machine


def axiscal(*args: object, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "campaign", *map(str, args)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_two_writers_at_once_lose_nothing(db, tmp_path):  # noqa: F811
    from campaign.history.simulated import simulate_history

    _, dirs = simulate_history(tmp_path / "h", campaigns=12)
    env = {**os.environ, "AXISCAL_DB": db}
    first = axiscal("history", "import", *dirs[:8], "--json", env=env)  # 4 in common with the second
    second = axiscal("history", "import", *dirs[4:], "--json", env=env)
    results = []
    for proc in (first, second):
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        results.append(json.loads(out))
    assert results[0]["added"] + results[1]["added"] == 12, results
    assert results[0]["unchanged"] + results[1]["unchanged"] == 4, results
    store = axiscal("history", "store", "--json", env=env)
    counts = json.loads(store.communicate(timeout=60)[0])
    assert (counts["campaigns"], counts["points"]) == (12, 12 * 110)


def test_killed_campaign_is_not_lost(tmp_path, monkeypatch):
    """kill -9 in the middle of a campaign: the store cannot have been told, the directory keeps
    it; `history import` records it as it stands (running, some points), and `resume` records it
    complete: one campaign in the store, 110 points."""
    store = tmp_path / "store.sqlite"
    monkeypatch.setenv("AXISCAL_DB", str(store))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    out = tmp_path / "k"
    proc = start_slow_demo(out)
    wait_for_points(out / "points.csv", 8, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    env = dict(os.environ)
    imported = axiscal("history", "import", out, "--json", env=env)
    assert json.loads(imported.communicate(timeout=60)[0])["added"] == 1
    listed = json.loads(axiscal("history", "list", "--json", env=env).communicate(timeout=60)[0])["campaigns"]
    assert len(listed) == 1 and listed[0]["status"] == "running" and 8 <= listed[0]["points"] < 110
    resumed = axiscal("resume", out, "--yes", env=env)
    _, err = resumed.communicate(timeout=120)
    assert resumed.returncode == 0, err
    assert [line for line in err.splitlines() if line.startswith("history:")] == [
        f"history: updated in sqlite:///{store}"]
    listed = json.loads(axiscal("history", "list", "--json", env=env).communicate(timeout=60)[0])["campaigns"]
    assert len(listed) == 1 and listed[0]["status"] == "completed" and listed[0]["points"] == 110
    assert listed[0]["command"] == "resume"

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


def hold_write_lock(store: str):
    """Hold the store's write lock from here (SQLite: BEGIN IMMEDIATE; PostgreSQL: an EXCLUSIVE
    lock on campaigns, which lets readers through): (release, waiting(pids) -> whether both
    writers are inside the store and cannot have written yet)."""
    from campaign.history.location import store_url
    from campaign.history.store import open_store

    url = store_url(store)
    open_store(url).close()  # made and migrated before the writers start
    if store.startswith("postgresql"):
        import psycopg

        holder = psycopg.connect(store)
        holder.execute("LOCK TABLE campaigns IN EXCLUSIVE MODE")
        watcher = psycopg.connect(store, autocommit=True)

        def waiting(pids: list[int]) -> bool:  # both blocked on the lock held
            return watcher.execute("SELECT count(*) FROM pg_locks WHERE NOT granted").fetchone()[0] >= len(pids)

        def release() -> None:
            holder.commit()
            holder.close()
            watcher.close()
        return release, waiting
    import sqlite3
    from pathlib import Path

    path = Path(url.removeprefix("sqlite:///"))
    holder = sqlite3.connect(path, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")

    def opened(pid: int) -> bool:
        try:
            return any(os.readlink(fd) == str(path) for fd in Path(f"/proc/{pid}/fd").iterdir())
        except OSError:
            return False

    def sqlite_release() -> None:
        holder.execute("ROLLBACK")
        holder.close()
    return sqlite_release, lambda pids: all(opened(pid) for pid in pids)


def test_two_writers_at_once_lose_nothing(db, tmp_path):  # noqa: F811
    """Two `history import` processes, 4 campaigns in common: both are inside the store while the
    test holds its write lock (so both started before either wrote anything, let alone finished),
    then write at once; every campaign is recorded once."""
    import time

    from campaign.history.simulated import simulate_history

    _, dirs = simulate_history(tmp_path / "h", campaigns=12)
    env = {**os.environ, "AXISCAL_DB": db}
    release, waiting = hold_write_lock(db)
    try:
        first = axiscal("history", "import", *dirs[:8], "--json", env=env)  # 4 in common with the second
        second = axiscal("history", "import", *dirs[4:], "--json", env=env)
        for _ in range(1200):
            if waiting([first.pid, second.pid]):
                break
            assert first.poll() is None and second.poll() is None, "a writer ended while the store was locked"
            time.sleep(0.05)
        else:
            raise AssertionError("the two writers never both reached the store")
        assert first.poll() is None and second.poll() is None
    finally:
        release()
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
        f"history: updated in {store.name}"]  # the store's label, never a URL
    listed = json.loads(axiscal("history", "list", "--json", env=env).communicate(timeout=60)[0])["campaigns"]
    assert len(listed) == 1 and listed[0]["status"] == "completed" and listed[0]["points"] == 110
    assert listed[0]["command"] == "resume"

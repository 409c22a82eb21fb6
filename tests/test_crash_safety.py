"""Crash safety: a campaign killed with SIGKILL, or stopped with Ctrl-C (SIGINT), leaves only
whole, fsynced point rows; Ctrl-C halts the axis and marks the campaign interrupted."""

import os
import signal
import subprocess
import sys
import time

import pytest

from campaign.pointtable import read_points
from campaign.record.directory import open_campaign
from tests.conftest import ROOT, events, status


def start_slow_demo(out, *options):
    # --speed 100: the 20-minute campaign takes about 12 s of wall time (two runs, --cycles 2: about 5 s), slow enough to interrupt
    return subprocess.Popen([sys.executable, "-m", "campaign", "demo", "--speed", "100", "--out", str(out), *options],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def data_rows(path):
    """Whole data rows in a point table (comment lines and the header left out)."""
    lines = [line for line in path.read_text().split("\n")[:-1] if line and not line.startswith("#")]
    return max(len(lines) - 1, 0)


def wait_for_points(path, n, proc, limit_s=60.0):
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        if path.exists() and data_rows(path) >= n:
            return
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.05)
    raise AssertionError(f"fewer than {n} points after {limit_s} s")


@pytest.mark.machine
def test_kill_9_leaves_only_whole_rows(tmp_path):
    out = tmp_path / "k"
    proc = start_slow_demo(out)
    wait_for_points(out / "points.csv", 8, proc)
    assert open_campaign(out).recording_now  # the demo holds the directory's lock
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    recorded = open_campaign(out)
    assert not recorded.recording_now and "killed or crashed" in recorded.message  # the kernel dropped it
    data = (out / "points.csv").read_bytes()
    assert data.endswith(b"\n")
    table = read_points(out / "points.csv")
    assert 8 <= len(table) < 110
    assert list(table.optional) == ["time_s", "air_temp_c", "air_pressure_hpa", "humidity_pct", "material_temp_c"]
    assert status(out) == "running"  # a start record, never a stop


@pytest.mark.machine
def test_ctrl_c_halts_flushes_and_marks_interrupted(tmp_path):
    out = tmp_path / "c"
    proc = start_slow_demo(out)
    wait_for_points(out / "points.csv", 5, proc)
    os.kill(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert f"continue with: axiscal resume {out}" in err  # the script says how to go on, as the guide does
    assert status(out) == "interrupted"
    assert events(out, "interrupt", by="Ctrl-C")
    assert events(out, "halt", ok=True, why="interrupted")
    assert 5 <= len(read_points(out / "points.csv")) < 110

"""`axiscal resume`: after kill -9 or Ctrl-C the final point table equals that of an uninterrupted
run with the same seed, in count and order; the first missing point is re-approached from the
overrun in its own direction."""

import json
import os
import shutil
import signal

import pytest

from tests.conftest import assert_one_line_error, events, status
from tests.test_crash_safety import start_slow_demo, wait_for_points
from tests.test_demo_e2e import axiscal


def point_keys(path):
    rows = [ln.split(",") for ln in path.read_text().splitlines() if ln[:1].isdigit()]
    return [(r[0], r[1], r[2]) for r in rows]


TWO_RUNS = ("--cycles", "2")
"""Interrupted and resumed campaigns run two of the demo's five runs (44 points): what resume must
keep and continue is the same, at 40 % of the CPU."""


@pytest.fixture(scope="module")
def uninterrupted(demo_campaign):
    return point_keys(demo_campaign()[1] / "points.csv")


@pytest.fixture(scope="module")
def uninterrupted_two_runs(demo_campaign):
    return point_keys(demo_campaign(*TWO_RUNS)[1] / "points.csv")


@pytest.mark.machine
@pytest.mark.parametrize("how", ["kill -9", "ctrl-c"])
def test_resume_gives_the_uninterrupted_point_table(tmp_path, uninterrupted_two_runs, how):
    out = tmp_path / "r"
    proc = start_slow_demo(out, *TWO_RUNS)
    wait_for_points(out / "points.csv", 7, proc)
    if how == "kill -9":
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    else:
        os.kill(proc.pid, signal.SIGINT)
        proc.communicate(timeout=30)
        assert status(out) == "interrupted"
    before = point_keys(out / "points.csv")
    assert 7 <= len(before) < 44
    result = axiscal("resume", out, "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["status"] == "completed" and data["points"] == 44
    after = point_keys(out / "points.csv")
    assert after == uninterrupted_two_runs  # no point lost, none duplicated, same order
    assert after[: len(before)] == before  # appended, not rewritten
    assert events(out, "resume", first_point=len(before))
    assert status(out) == "completed"


@pytest.mark.machine
def test_resume_reapproaches_from_the_overrun(tmp_path):
    out = tmp_path / "r"
    proc = start_slow_demo(out, *TWO_RUNS)
    wait_for_points(out / "points.csv", 3, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    done = len(point_keys(out / "points.csv"))
    raw_before = len((out / "raw.csv").read_text().splitlines())
    assert axiscal("resume", out).returncode == 0
    raw = [ln.split(",") for ln in (out / "raw.csv").read_text().splitlines()[raw_before:]]
    # samples of the point's own approach carry its index; before them the axis goes to the overrun
    first_own = next(i for i, r in enumerate(raw) if r[2] == str(done))
    before = [float(r[3]) for r in raw[:first_own] if r[3]]
    approach = [float(r[3]) for r in raw[first_own:] if r[2] == str(done) and r[3]]
    # run 1 goes up through 11 targets, so the next point is approached in +: from target - L1 (5 mm)
    target = 60.0 * done
    assert done < 11
    assert before[-1] == pytest.approx(target - 5.0, abs=0.1)  # last poll, braking into the overrun
    assert approach == sorted(approach) and approach[-1] == pytest.approx(target, abs=0.01)


@pytest.mark.machine
def test_resume_refuses_completed_and_non_campaign(cli, tmp_path, demo_campaign):
    assert_one_line_error(cli("resume", tmp_path), "not a campaign directory")
    out = shutil.copytree(demo_campaign()[1], tmp_path / "done")  # a completed demo
    assert_one_line_error(cli("resume", out), "already completed")


@pytest.mark.machine
def test_demo_refuses_to_overwrite_a_campaign(tmp_path, demo_campaign):
    out = shutil.copytree(demo_campaign()[1], tmp_path / "d")  # a completed demo
    again = axiscal("demo", "--out", out)
    assert again.returncode == 2 and again.stderr.startswith("error: ") and "resume" in again.stderr


@pytest.mark.machine
def test_a_point_skipped_after_a_fault_is_measured_on_resume(tmp_path, uninterrupted):
    from campaign.pointtable import read_points

    out = tmp_path / "s"
    first = axiscal("demo", "--inject", "axis_error@300", "--on-fault", "skip", "--json", "--out", out)
    assert first.returncode == 0, first.stderr
    data = json.loads(first.stdout)
    assert data["points"] == 109 and data["verdict"] == "not judged"  # completed, but one point short
    assert "1 of 110 planned points are missing" in data["reasons"][0]
    skipped = events(out, "skip")
    assert len(skipped) == 1
    result = axiscal("resume", out, "--yes", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["points"] == 110
    assert json.loads(result.stdout)["verdict"] == "pass"  # the demo's tolerance, 10 µm
    table = read_points(out / "points.csv")
    keys = [(str(r), "+" if d > 0 else "-", f"{t:.6f}") for r, d, t in zip(table.run, table.direction, table.target)]
    assert keys == uninterrupted  # the plan's order, nothing duplicated
    assert list(table.extra["point"]) == list(range(110))
    assert point_keys(out / "points.csv")[-1] == uninterrupted[skipped[0]["point"]]  # appended, file untouched
    assert status(out) == "completed"

"""Bad input in a recorded scan (sweeps.csv, positions.csv): `axiscal resume` and `axiscal replay`
exit 2 with one `error:` line naming the file and the line, never a traceback; resume checks each
sweep recorded against the plan before anything moves."""

from __future__ import annotations

import shutil

import pytest

from campaign.config import parse_config
from campaign.errors import CampaignInterrupted
from campaign.measure import Control, Observer, resume_campaign, start_campaign
from drivers.factory import open_hardware
from tests.conftest import once_per_run
from tests.test_demo_e2e import axiscal
from tests.test_scan_run import SCAN, draw


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    """(a scan interrupted after pass 1, the same scan resumed to its end), recorded once for the whole
    run (once_per_run); the tests copy them before they change anything."""

    def make(directory):
        config = parse_config(SCAN.format(**{**draw(9), "velocity": 20.0}), "scan.toml")
        control = Control()

        class AbortAfterPass1(Observer):
            def emit(self, event):
                if event.kind == "sweep" and event.point == 1:
                    control.request_abort("key a")

        with pytest.raises(CampaignInterrupted):
            start_campaign(config, directory / "stopped", opener=open_hardware, observer=AbortAfterPass1(),
                           control=control)
        shutil.copytree(directory / "stopped", directory / "done")
        assert resume_campaign(directory / "done", opener=open_hardware).status == "completed"

    base = once_per_run(tmp_path_factory, "scan-input", make)
    return base / "stopped", base / "done"


def _one_error(proc, *words):
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    errors = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(errors) == 1 and errors[0].startswith("error:") and "Traceback" not in proc.stderr, proc.stderr
    for word in words:
        assert word in errors[0], (word, errors[0])


@pytest.mark.machine
@pytest.mark.parametrize(("row", "words"), [
    ("7,4,+,64.0,30.0,10,10", ["line 4", "point 7 is not in the plan"]),
    ("1,2,-,-4.0,30.0,10,10", ["line 4", "point 1 is pass 2 -", "pass 1 -"]),
    ("1,1,+,-4.0,30.0,10,10", ["line 4", "point 1 is pass 1 +"]),
    ("1,1,-,-4.0,x,10,10", ["line 4", "not a sweep record"]),
    ("1,1", ["line 4", "not a sweep record"]),
])
def test_resume_refuses_a_sweep_row_the_plan_does_not_have_before_anything_moves(tmp_path, scans, row, words):
    stopped, _ = scans
    shutil.copytree(stopped, tmp_path / "c")
    sweeps = tmp_path / "c" / "sweeps.csv"
    sweeps.write_text(sweeps.read_text() + row + "\n")
    raw_before = (tmp_path / "c" / "raw.csv").stat().st_size
    _one_error(axiscal("resume", tmp_path / "c"), "sweeps.csv", *words)
    assert (tmp_path / "c" / "raw.csv").stat().st_size == raw_before  # nothing moved, nothing recorded


@pytest.mark.machine
@pytest.mark.parametrize(("change", "words"), [
    (lambda lines: ["t_s,step,time,position", *lines[1:]], ["positions.csv", "line 1"]),
    (lambda lines: [*lines[:5], "1.0,2,zz,3.0", *lines[5:]], ["positions.csv", "line 6"]),
    (lambda lines: [*lines[:5], "1.0,2", *lines[5:]], ["positions.csv", "line 6"]),
    (None, ["no positions.csv"]),
])
def test_replay_of_a_scan_with_a_bad_or_missing_positions_file_is_one_error_line(tmp_path, scans, change, words):
    _, done = scans
    shutil.copytree(done, tmp_path / "c")
    path = tmp_path / "c" / "positions.csv"
    if change is None:
        path.unlink()
    else:
        path.write_text("\n".join(change(path.read_text().splitlines())) + "\n")
    _one_error(axiscal("replay", tmp_path / "c"), *words)


def _killed_before_its_stop(directory):
    """The directory as a kill -9 leaves it after the last sweep: no stop record, no stop events."""
    for name in ("runs.jsonl", "events.jsonl"):
        path = directory / name
        lines = path.read_text().splitlines(keepends=True)
        keep = [ln for ln in lines if '"record": "stop"' not in ln and '"kind": "stop"' not in ln
                and '"state": "stopped"' not in ln]
        path.write_text("".join(keep))


@pytest.mark.machine
@pytest.mark.parametrize("lost", ["profile.csv", "points.csv"])
def test_resume_writes_what_a_kill_between_the_table_and_the_profile_left_out(tmp_path, scans, lost):
    _, done = scans
    shutil.copytree(done, tmp_path / "c")
    table, profile = (tmp_path / "c" / "points.csv").read_text(), (tmp_path / "c" / "profile.csv").read_text()
    _killed_before_its_stop(tmp_path / "c")
    if lost == "profile.csv":  # the old order: the table written, killed before the profile
        (tmp_path / "c" / "profile.csv").unlink()
    else:  # the order now: the profile written, killed before the table
        (tmp_path / "c" / "points.csv").write_text("")
    proc = axiscal("resume", tmp_path / "c")
    assert proc.returncode == 0, (proc.stdout, proc.stderr)
    assert (tmp_path / "c" / "points.csv").read_text() == table
    assert (tmp_path / "c" / "profile.csv").read_text() == profile


@pytest.mark.machine
def test_a_table_that_cannot_be_made_is_said_as_such_not_as_an_alignment_failure(scans):
    from campaign.errors import InputError
    from campaign.measure import analyse_recorded_scan
    from campaign.plan import build_plan
    from campaign.record import open_campaign

    _, done = scans
    config = open_campaign(done).config()
    plan = build_plan(config)
    elsewhere = type(plan)(plan.steps, tuple(t + 500.0 for t in plan.targets), plan.offsets, plan.seed)
    with pytest.raises(InputError) as refused:  # the streams align; no target lies in the scanned travel
        analyse_recorded_scan(done, config, elsewhere)
    assert "no point table (no target lies within the scanned travel)" in str(refused.value)
    assert "could not be aligned" not in str(refused.value)


@pytest.mark.machine
@pytest.mark.parametrize(("name", "line", "words"), [
    ("events.jsonl", '{"t_s": 1.0}', ["events.jsonl", "not an axiscal event"]),
    ("runs.jsonl", '{"record": "start"}', ["runs.jsonl", "without a time"]),
])
def test_replay_of_a_scan_with_a_bad_event_or_run_record_is_one_error_line(tmp_path, scans, name, line, words):
    _, done = scans
    shutil.copytree(done, tmp_path / "c")
    path = tmp_path / "c" / name
    path.write_text(path.read_text() + line + "\n")
    _one_error(axiscal("replay", tmp_path / "c"), *words)

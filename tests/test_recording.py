"""The recorder: torn tails are cut on reopen, short writes complete, a full disk on any file
stops the campaign as a RecordingError (resumable), and every handle is closed."""

import errno
import os

import pytest

from campaign.commands.demo import demo_config_text
from campaign.config import parse_config, recorded_sections
from campaign.errors import InputError
from campaign.plan import build_plan, plan_records
from campaign.pointtable import read_points
from campaign.record.events import Event
from campaign.record.recorder import Recorder, RecordingError, cut_torn_tail
from protocols.hardware import Reading

META = {"machine": "m", "axis": "X", "kind": "linear"}
ENV = {"air_temp_c": 20.0, "air_pressure_hpa": 1013.0, "humidity_pct": 50.0, "material_temp_c": 20.0}
EXTRA = {"point": 0, "reading": 0.001, "air_correction_um": 0.0, "material_correction_um": 0.0,
         "capture_wait_s": 4.0, "samples": 10}


def new_recorder(tmp_path):
    plan = build_plan(parse_config(demo_config_text(), "demo.toml"))
    return Recorder.create(tmp_path / "c", "# config\n", {}, plan_records(plan), dict(META), "linear")


def write_points(rec, n, first=0):
    for i in range(first, first + n):
        rec.sample(float(i), 1, i, 0.0, Reading(float(i), 0.001, True, 90.0, 20.0, 1013.0, 50.0, 20.0))
        rec.point(1, 1, float(10 * i), 1.0 + i, float(i), ENV, {**EXTRA, "point": i})


def open_fds():
    return len(os.listdir("/proc/self/fd"))


def test_torn_tails_are_cut_on_reopen(tmp_path):
    rec = new_recorder(tmp_path)
    write_points(rec, 3)
    rec.close()
    directory = tmp_path / "c"
    with open(directory / "points.csv", "ab") as f:
        f.write(b"1,+,30.000000,2.5\x00\x00")  # a power cut in the middle of a row
    with open(directory / "raw.csv", "ab") as f:
        f.write(b"3.0,1,3,0.0,0.00")
    rec = Recorder.reopen(directory)
    assert rec.points_written == 3
    write_points(rec, 1, first=3)
    rec.close()
    table = read_points(directory / "points.csv")
    assert len(table) == 4 and list(table.deviation) == [1.0, 2.0, 3.0, 4.0]
    assert (directory / "raw.csv").read_bytes().endswith(b"\n")
    assert cut_torn_tail(directory / "points.csv") == 0


def test_short_writes_are_completed(tmp_path, monkeypatch):
    real_write = os.write

    def short_write(fd, data):  # the kernel may take fewer bytes than asked
        return real_write(fd, bytes(data[: max(1, len(data) // 3)]))

    rec = new_recorder(tmp_path)
    monkeypatch.setattr(os, "write", short_write)
    write_points(rec, 2)
    monkeypatch.undo()
    rec.close()
    assert len(read_points(tmp_path / "c" / "points.csv")) == 2


@pytest.mark.parametrize("where", ["raw", "events", "points"])
def test_full_disk_is_a_recording_error(tmp_path, where):
    rec = new_recorder(tmp_path)
    write_points(rec, 1)
    before = open_fds()

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(RecordingError, match="No space left"):
        if where == "raw":
            rec._raw.write = full  # the buffered file flushes onto the full disk
            write_points(rec, 1, first=1)
        elif where == "events":
            rec._events.flush = full
            rec.emit(Event(1.0, "beam", "beam lost", None, {"ok": False, "signal_pct": 0.0}))
        else:
            rec.inject_disk_full()
            write_points(rec, 1, first=1)
    if where == "events":
        with pytest.raises(OSError):
            rec.close()  # the events file still cannot be flushed: reported, after closing the rest
    else:
        rec.close()
    assert open_fds() == before - 5  # every handle closed, even after the failure
    reopened = Recorder.reopen(tmp_path / "c")  # a torn row is cut; the campaign can resume
    assert reopened.points_written == 1
    reopened.close()
    assert len(read_points(tmp_path / "c" / "points.csv")) == 1


def test_one_process_at_a_time(tmp_path, cli):
    """While one recorder holds a campaign, neither a resume nor a new campaign in the same
    directory may write to it: a second writer would append a second copy of the points."""
    text = demo_config_text()
    config = parse_config(text, "demo.toml")
    plan = build_plan(config)
    rec = Recorder.create(tmp_path / "c", text, recorded_sections(config), plan_records(plan), dict(META), "linear")
    rec.start(0.0, 0, 110)
    write_points(rec, 2)
    directory = tmp_path / "c"
    with pytest.raises(InputError, match=rf"another axiscal process is recording here \(pid {os.getpid()}"):
        Recorder.reopen(directory)
    r = cli("resume", directory, "--yes")
    assert r.code == 2 and r.err.startswith("error: ") and "another axiscal process" in r.err
    assert len(r.err.strip().splitlines()) == 1
    with pytest.raises(InputError, match="another axiscal process"):
        new_recorder(tmp_path)
    assert len(read_points(directory / "points.csv")) == 2  # untouched by the refused writers
    rec.close()
    again = Recorder.reopen(directory)  # the lock goes with the holder
    assert again.points_written == 2
    again.close()


def test_an_out_that_cannot_be_a_directory_is_bad_input(cli, tmp_path):
    """`--out` naming a file, or a path under one: exit 2 with one line before anything moves (it was an
    internal error, FileExistsError or NotADirectoryError)."""
    from tests.conftest import assert_one_line_error

    taken = tmp_path / "points.csv"
    taken.write_text("not a campaign\n")
    assert_one_line_error(cli("demo", "--fake", "--out", taken), str(taken), "is a file, not a campaign directory")
    assert_one_line_error(cli("demo", "--fake", "--out", taken / "sub"), "cannot make the campaign directory")
    assert taken.read_text() == "not a campaign\n"


def test_a_plot_that_fails_at_the_end_loses_nothing_else(cli, tmp_path, monkeypatch):
    """The plot is checked before the campaign; a disk that fails when it is written after still
    leaves the summary, the verdict and the campaign's end: a warning says the plot is missing."""
    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("campaign.commands.run.plot_evaluation", full_disk)
    result = cli("demo", "--fake", "--out", tmp_path / "c", "--plot", tmp_path / "p.png")
    assert result.code == 0, result.err
    assert "the plot was not written" in result.out and "No space left on device" in result.out
    assert "campaign completed" in result.out and "accuracy A =" in result.out  # the verdict line


def test_a_torn_last_line_is_left_out_by_every_reader_and_kept_in_the_file(cli, tmp_path):
    """A crash in the middle of writing a point leaves its line without a newline (and its numbers
    perhaps cut). analyze, report and replay of the directory, and discover of its points.csv, read what was recorded before it, as
    the docs promise, and leave the file as it is for `resume` to cut (they refused it before:
    "expected 15 fields, found 11")."""
    directory = tmp_path / "c"
    assert cli("demo", "--fake", "--out", directory).code == 0
    points, raw = directory / "points.csv", directory / "raw.csv"
    text = points.read_bytes()
    last = text.rstrip(b"\n").rfind(b"\n") + 1
    points.write_bytes(text[:last] + text[last:last + 25])  # the last point's line, cut mid-number
    raw.write_bytes(raw.read_bytes()[:-17])
    torn = points.read_bytes()
    analyzed = cli("analyze", directory)
    assert analyzed.code == 0, analyzed.err
    assert "1 of 110 planned points are missing" in " ".join(analyzed.out.split())
    assert cli("report", directory, "-o", tmp_path / "r.html").code == 0
    replayed = cli("replay", directory)
    assert replayed.code == 0, replayed.err
    discovered = cli("discover", points)  # a campaign's points.csv: read as recorded, incomplete said
    assert discovered.code == 0, discovered.err
    assert "incomplete campaign: 1 of 110 planned points are missing" in " ".join(discovered.out.split())
    assert points.read_bytes() == torn

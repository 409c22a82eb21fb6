"""LinuxCNC as a second real controller: a headless instance (Debian linuxcnc-uspace, installed by
tests/setup_system.sh), the demo campaign through linuxcncrsh, and the closed loop through
LinuxCNC's own COMP_FILE loader and motion module. axiscal applies nothing itself on this path:
the compensation can only come from LinuxCNC."""

import configparser
import json
import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

from campaign.commands.demo import demo_config_text
from campaign.commands.linuxcnc_demo import linuxcnc_config
from campaign.config import parse_config
from campaign.plan import check_plan, make_plan
from campaign.specs import AxisSpec
from drivers.linuxcnc import process
from drivers.linuxcnc.process import ini_text
from protocols.hardware import AxisError
from tests.conftest import assert_one_line_error
from tests.test_demo_e2e import axiscal

INSTALLED = all(shutil.which(tool) for tool in ("linuxcnc", "linuxcncrsh", "halcmd"))


@pytest.mark.linuxcnc  # a real-time LinuxCNC: one per machine, so one after another on one worker
@pytest.mark.xdist_group("linuxcnc")
@pytest.mark.machine
@pytest.mark.skipif(not INSTALLED, reason="LinuxCNC is not installed (tests/setup_system.sh installs "
                                          "linuxcnc-uspace where apt is available)")
def test_demo_on_linuxcnc_with_its_own_compensation(tmp_path):
    # two of the demo's five cycles each way: LinuxCNC runs in real time and, with the demo's own
    # 50 mm/s limit, the five cycles each way take about 7.5 minutes, most of `make test`'s budget
    # (docs/linuxcnc.md gives the full run's figures: 110 points each way, A 9.40 -> 2.24 µm)
    proc = axiscal("demo", "--controller", "linuxcnc", "--verify", "--json", "--cycles", "2",
                   "--out", tmp_path / "lc", timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    data = json.loads(proc.stdout)
    assert data["points"] == 44 and data["points_after"] == 44
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
    assert _axiscal_linuxcnc_processes() == []  # nothing of either LinuxCNC runs on


@pytest.mark.skipif(INSTALLED, reason="checks the message when LinuxCNC is missing")
def test_without_linuxcnc_the_demo_says_how_to_install(cli):
    assert_one_line_error(cli("demo", "--controller", "linuxcnc"), "apt-get install linuxcnc-uspace")


def test_verify_needs_the_linuxcnc_controller(cli):
    assert_one_line_error(cli("demo", "--verify"), "--controller linuxcnc")


def test_the_generated_ini_has_the_demo_configs_limits_and_the_quick_plan_keeps_within_them():
    """The LinuxCNC demo's joint is the demo's axis: soft limits, maximum velocity and acceleration
    from demo.toml's [axis] (issue 26 item 6; it had 300 mm/s and 3000 mm/s² of its own). Only the
    plan is made quick, within those limits."""
    demo = parse_config(demo_config_text(), "demo.toml").axis
    config = linuxcnc_config(demo_config_text())
    ini = configparser.ConfigParser()
    ini.read_string(ini_text(config.axis, None))
    for section in ("JOINT_0", "AXIS_X"):
        got = {key: float(ini[section][key]) for key in ("MIN_LIMIT", "MAX_LIMIT", "MAX_VELOCITY", "MAX_ACCELERATION")}
        assert got == {"MIN_LIMIT": demo.soft_limit_min, "MAX_LIMIT": demo.soft_limit_max,
                       "MAX_VELOCITY": demo.max_velocity, "MAX_ACCELERATION": demo.max_acceleration}, section
    assert float(ini["TRAJ"]["MAX_LINEAR_VELOCITY"]) == demo.max_velocity
    assert float(ini["TRAJ"]["MAX_LINEAR_ACCELERATION"]) == demo.max_acceleration
    assert ini["TRAJ"]["LINEAR_UNITS"] == "mm" and "COMP_FILE" not in ini["JOINT_0"]
    # every move of the demo's plan on LinuxCNC keeps within the joint's limits as the INI states them
    joint = AxisSpec(name="X", kind="linear", unit="mm", soft_limit_min=float(ini["JOINT_0"]["MIN_LIMIT"]),
                     soft_limit_max=float(ini["JOINT_0"]["MAX_LIMIT"]),
                     max_velocity=float(ini["JOINT_0"]["MAX_VELOCITY"]),
                     max_acceleration=float(ini["JOINT_0"]["MAX_ACCELERATION"]))
    check_plan(make_plan(config.plan, config.capture), joint)
    assert config.plan.velocity == demo.max_velocity  # made quick: the fastest the demo's axis allows


def test_the_generated_ini_takes_a_configs_own_limits_and_comp_file(tmp_path):
    text = demo_config_text().replace("soft_limit_min = -10.0", "soft_limit_min = -2.5").replace(
        "max_acceleration = 200.0", "max_acceleration = 150.0")
    ini = configparser.ConfigParser()
    ini.read_string(ini_text(linuxcnc_config(text).axis, tmp_path / "comp.txt"))
    assert (ini["JOINT_0"]["MIN_LIMIT"], ini["AXIS_X"]["MAX_ACCELERATION"]) == ("-2.5", "150.0")
    assert (ini["JOINT_0"]["COMP_FILE"], ini["JOINT_0"]["COMP_FILE_TYPE"]) == (str(tmp_path / "comp.txt"), "0")


# --- the LinuxCNC axiscal starts, axiscal can find (issue 32 item 6) -----------------------------
# The fast tests below run the record and the leftover logic on real processes (`sleep` in a
# session of its own, as the linuxcnc script runs) with a record, lock and port of their own, so
# they never touch a LinuxCNC running on this machine; the machine-tier test at the end kills a
# real `axiscal demo --controller linuxcnc`.


@pytest.fixture
def files(tmp_path):
    """A record file and a lock file of the test's own."""
    return tmp_path / "record.json", tmp_path / "lock"


@pytest.fixture
def group(tmp_path):
    """A process leading a group of its own, as the linuxcnc script does; ended after the test."""
    directory = tmp_path / "axiscal-linuxcnc-test"
    directory.mkdir()
    proc = subprocess.Popen(["sleep", "60"], cwd=directory, start_new_session=True)
    yield proc, directory
    proc.kill()
    proc.wait()


def test_a_recorded_group_still_running_is_a_leftover_and_stopping_it_ends_it_and_its_record(files, group):
    record_file, lock_file = files
    proc, directory = group
    record = process._write_record(proc.pid, directory, record_file)
    assert (record.pgid, record.axiscal_pid, record.dir) == (proc.pid, os.getpid(), str(directory))
    leftover = process.find_leftover(record_file, lock_file)
    assert leftover is not None and leftover.pids == (proc.pid,)
    assert f"process group {proc.pid}, 1 processes" in leftover.describe()
    leftover.stop()
    assert proc.wait(5) == -signal.SIGINT  # SIGINT first: the linuxcnc script cleans up on it
    assert not record_file.exists() and process.find_leftover(record_file, lock_file) is None


def test_a_record_of_a_group_that_ended_or_of_another_process_is_not_a_leftover(files, group):
    record_file, lock_file = files
    proc, directory = group
    record = process._write_record(proc.pid, directory, record_file)
    # the pid now another process (another start time): not axiscal's, the stale record removed
    record_file.write_text(json.dumps({**record.__dict__, "start_ticks": record.start_ticks + 1}))
    assert process.find_leftover(record_file, lock_file) is None and not record_file.exists()
    if os.geteuid() == 0:  # a record another user wrote is not trusted (as root the test can make one)
        process._write_record(proc.pid, directory, record_file)
        os.chown(record_file, 65534, -1)
        assert process.find_leftover(record_file, lock_file) is None
        record_file.unlink()
    process._write_record(proc.pid, directory, record_file)
    proc.kill()
    proc.wait()
    assert process.find_leftover(record_file, lock_file) is None and not record_file.exists()


def test_while_an_axiscal_holds_the_lock_its_linuxcnc_is_not_a_leftover(files, group):
    record_file, lock_file = files
    proc, directory = group
    process._write_record(proc.pid, directory, record_file)
    with process._held(lock_file) as held:
        assert held is not None
        assert process.find_leftover(record_file, lock_file) is None
    assert record_file.exists() and process.find_leftover(record_file, lock_file) is not None


def test_a_leftover_is_refused_unless_confirmed_then_stopped(files, group):
    record_file, lock_file = files
    proc, directory = group
    process._write_record(proc.pid, directory, record_file)
    port = free_port()
    asked: list[str] = []
    with pytest.raises(AxisError) as refused:
        process._one_instance(lambda what: asked.append(what) or False, lock_file, record_file, port)
    message = str(refused.value)
    assert message.startswith("a LinuxCNC that axiscal started at") and "is still running" in message
    assert "--yes" in message and f"kill -INT -{proc.pid}" in message and len(asked) == 1
    assert proc.poll() is None  # not stopped without a yes
    lock = process._one_instance(lambda what: True, lock_file, record_file, port)
    lock.close()
    assert proc.wait(5) == -signal.SIGINT and not record_file.exists()


def test_a_linuxcnc_axiscal_did_not_start_is_refused_even_with_yes(files):
    """Something answers on linuxcncrsh's port and no record of axiscal's says it is its own."""
    record_file, lock_file = files
    with socket.create_server(("127.0.0.1", 0)) as listener:
        port = listener.getsockname()[1]
        asked: list[str] = []
        with pytest.raises(AxisError) as refused:
            process._one_instance(lambda what: asked.append(what) or True, lock_file, record_file, port)
    assert str(refused.value).startswith("a LinuxCNC that axiscal did not start is running here")
    assert asked == []  # nothing was offered to stop


def test_the_record_is_never_written_through_a_link(tmp_path):
    """The record lives in the shared temporary directory: a link put where axiscal writes it first
    is replaced, not followed (axiscal runs LinuxCNC as root)."""
    record_file, precious = tmp_path / "record.json", tmp_path / "precious"
    precious.write_text("keep")
    (tmp_path / f".record.json.{os.getpid()}").symlink_to(precious)
    process._write_record(os.getpid(), tmp_path, record_file)
    assert precious.read_text() == "keep" and process._read_record(record_file).axiscal_pid == os.getpid()
    record_file.unlink()
    record_file.symlink_to(precious)  # and a record that is a link is not read
    assert process._read_record(record_file) is None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.linuxcnc  # a real-time LinuxCNC: one per machine, so one after another on one worker
@pytest.mark.xdist_group("linuxcnc")
@pytest.mark.machine
@pytest.mark.skipif(not INSTALLED, reason="LinuxCNC is not installed (tests/setup_system.sh installs "
                                          "linuxcnc-uspace where apt is available)")
def test_after_kill_9_of_the_demo_the_next_run_stops_the_linuxcnc_it_left_and_completes(tmp_path):
    """Issue 32's done-when: `kill -9` of `axiscal demo --controller linuxcnc` leaves its LinuxCNC
    running (the demo cannot stop it); the next run without --yes and without a terminal is
    refused, saying what runs and how to stop it; with --yes it stops it and completes. The same
    through `axiscal resume DIR --yes` of the killed campaign. A LinuxCNC with no record of
    axiscal's is refused even with --yes, and left running."""
    from tests.test_crash_safety import data_rows
    from tests.test_demo_e2e import AXISCAL, ROOT

    def killed_when_measuring(command: list[str], table: Path, proc: subprocess.Popen | None = None) -> int:
        """Start `command` (or take `proc`), SIGKILL it once its point table has two points (it is
        measuring on LinuxCNC's axis: no cleanup of its own runs); its pid."""
        proc = proc or subprocess.Popen(command, cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                        stderr=open(table.parent.with_suffix(".stderr"), "w"))  # noqa: SIM115
        try:
            deadline = time.monotonic() + 180
            while not (table.exists() and data_rows(table) >= 2):
                if proc.poll() is not None or time.monotonic() > deadline:
                    said = table.parent.with_suffix(".stderr").read_text()[-2000:]
                    pytest.fail(f"the demo did not measure (exit {proc.poll()}): {said}")
                time.sleep(0.5)
        finally:
            proc.kill()
            proc.wait()
        return proc.pid

    first = subprocess.Popen([*AXISCAL, "demo", "--controller", "linuxcnc", "--cycles", "1", "--out",
                              str(tmp_path / "first")], cwd=ROOT, stdin=subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=open(tmp_path / "first.stderr", "w"))  # noqa: SIM115
    leftover = None
    try:
        killed_when_measuring([], tmp_path / "first" / "points.csv", first)
        leftover = process.find_leftover()
        assert leftover is not None and leftover.record.axiscal_pid == first.pid
        socket.create_connection(("127.0.0.1", process.PORT), timeout=2).close()  # LinuxCNC still answers

        refused = axiscal("demo", "--controller", "linuxcnc", "--cycles", "1", "--out", tmp_path / "refused",
                          timeout=120)
        assert refused.returncode == 3, refused.stderr[-2000:]
        assert refused.stderr.startswith(f"error: a LinuxCNC that axiscal started at {leftover.record.started} "
                                         f"(axiscal pid {first.pid}"), refused.stderr
        assert "--yes" in refused.stderr and process._group(leftover.record.pgid)  # still running, untouched

        done = axiscal("demo", "--controller", "linuxcnc", "--cycles", "1", "--yes", "--json", "--out",
                       tmp_path / "second", timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        assert f"stopping a LinuxCNC that axiscal started at {leftover.record.started}" in done.stderr
        result = json.loads(done.stdout)
        assert result["status"] == "completed" and result["points"] == result["planned"] == 22
        assert process._group(leftover.record.pgid) == [] and not Path(leftover.record.dir).exists()
        assert process.find_leftover() is None and not process.RECORD_FILE.exists()

        # the same after `axiscal run` killed: `axiscal resume DIR --yes` stops its LinuxCNC and finishes
        third = killed_when_measuring([*AXISCAL, "demo", "--controller", "linuxcnc", "--cycles", "1", "--out",
                                       str(tmp_path / "third")], tmp_path / "third" / "points.csv")
        leftover = process.find_leftover()
        assert leftover is not None and leftover.record.axiscal_pid == third
        resumed = axiscal("resume", tmp_path / "third", "--yes", "--json", timeout=600)
        assert resumed.returncode == 0, resumed.stderr[-2000:]
        assert f"stopping a LinuxCNC that axiscal started at {leftover.record.started}" in resumed.stderr
        result = json.loads(resumed.stdout)
        assert result["status"] == "completed" and result["points"] == result["planned"] == 22
        assert process._group(leftover.record.pgid) == [] and process.find_leftover() is None
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
        if leftover is not None and process._group(leftover.record.pgid):
            leftover.stop()

    # a LinuxCNC axiscal did not start: one running with no record of axiscal's and no axiscal
    # holding the lock (made here from axiscal's own by taking both away) is refused even with --yes
    foreign = process.LinuxCnc(parse_config(demo_config_text(), "demo.toml").axis)
    try:
        process._remove_record(foreign._record)
        assert foreign._lock is not None
        foreign._lock.close()
        foreign._lock = None
        other = axiscal("demo", "--controller", "linuxcnc", "--cycles", "1", "--yes", "--out", tmp_path / "other",
                        timeout=120)
        assert other.returncode == 3 and other.stderr.startswith(
            "error: a LinuxCNC that axiscal did not start is running here"), other.stderr[-2000:]
        assert foreign.proc.poll() is None  # left running
        # the simulated laser's HAL reads go through one halcmd session (a halcmd started per read cost
        # ~10 ms, more on a loaded machine): one process answers every read; a name HAL refuses is an
        # AxisError saying so, and the reads after it answer from a new session
        assert foreign.getp("joint.0.motor-pos-cmd") == "0"  # not homed, not moved
        session = foreign._hal
        assert session is not None and {foreign.getp("joint.0.motor-pos-cmd") for _ in range(200)} == {"0"}
        assert foreign._hal is session and session.poll() is None
        with pytest.raises(AxisError, match="halcmd getp no.such.pin: pin or parameter 'no.such.pin' not found"):
            foreign.getp("no.such.pin")
        assert foreign.getp("joint.0.homed") == "FALSE" and foreign.getp("joint.0.motor-pos-cmd") == "0"
        assert foreign._hal is not session and session.poll() is not None
    finally:
        foreign.stop()
    assert _axiscal_linuxcnc_processes() == []


@pytest.mark.parametrize("whose", ["ours", "zero", "init"])
def test_a_record_naming_axiscals_own_group_or_no_group_is_never_a_leftover(files, whose):
    """A hand-edited or foreign record (the same user: root writes /tmp's record) whose process group
    is axiscal's own, 0 (killpg(0) signals the caller's own group) or 1 is not a leftover: stopping it
    would SIGINT and SIGKILL axiscal itself and the shell's group. The record is dropped."""
    record_file, lock_file = files
    pgid = {"ours": os.getpgrp(), "zero": 0, "init": 1}[whose]
    ticks = process._start_ticks(pgid) or 0 if pgid else 0
    record = process.Record(pgid, ticks, process._boot_id(), "/tmp/axiscal-linuxcnc-x", 1, "2026-01-01 00:00:00")
    record_file.write_text(json.dumps(record.__dict__))
    assert process.find_leftover(record_file, lock_file) is None
    assert not record_file.exists()


@pytest.mark.parametrize("kind", ["fifo", "directory", "huge"])
def test_a_record_path_that_is_no_record_is_none_without_a_hang_or_a_traceback(files, kind):
    """/tmp is everyone's: another user may put a FIFO there (opening it for reading waited for a
    writer for good), a directory (reading it raised IsADirectoryError) or a huge file. None of
    them is a record; find_leftover says none, within a second."""
    import threading

    record_file, lock_file = files
    if kind == "fifo":
        os.mkfifo(record_file)
    elif kind == "directory":
        record_file.mkdir()
    else:
        record_file.write_text("[" * 100_000 + "]" * 100_000)
    found: list[object] = []
    worker = threading.Thread(target=lambda: found.append(process.find_leftover(record_file, lock_file)), daemon=True)
    worker.start()
    worker.join(5.0)
    if worker.is_alive():  # let the blocked open go, so the test process can end
        with open(record_file, "w"):
            pass
        pytest.fail("find_leftover hung on a FIFO at the record's path")
    assert found == [None]


def test_a_directory_at_the_records_path_is_refused_before_linuxcnc_starts(files):
    record_file, _ = files
    process._check_record_path(record_file)  # nothing there: fine
    record_file.write_text("{}")
    process._check_record_path(record_file)  # a stale record: replaced
    record_file.unlink()
    record_file.mkdir()
    with pytest.raises(process.AxisError, match="is a directory"):
        process._check_record_path(record_file)


@pytest.mark.linuxcnc  # a real-time LinuxCNC: one per machine, so one after another on one worker
@pytest.mark.xdist_group("linuxcnc")
@pytest.mark.machine
@pytest.mark.skipif(not INSTALLED, reason="LinuxCNC is not installed (tests/setup_system.sh installs "
                    "linuxcnc-uspace)")
def test_a_linuxcnc_whose_record_cannot_be_written_is_stopped_again(monkeypatch):
    """The record is written after LinuxCNC starts: when that fails (a full /tmp), the LinuxCNC
    nothing could find after a crash is stopped again and the error says why (it was left running,
    with a traceback)."""
    import errno

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(process, "_write_record", full)
    started: list[int] = []
    real_popen = subprocess.Popen

    def popen(*args, **kwargs):
        proc = real_popen(*args, **kwargs)
        started.append(proc.pid)
        return proc

    monkeypatch.setattr(process.subprocess, "Popen", popen)
    axis = linuxcnc_config(demo_config_text()).axis
    with pytest.raises(AxisError, match="cannot record the LinuxCNC axiscal starts"):
        process.LinuxCnc(axis)
    assert started and process._group(started[0]) == []
    assert process.find_leftover() is None and _axiscal_linuxcnc_processes() == []


def _axiscal_linuxcnc_processes() -> list[int]:
    """Every live process of a LinuxCNC axiscal started (INI_FILE_NAME in one of its directories)."""
    import tempfile

    return sorted(pid for entry in Path(tempfile.gettempdir()).glob(f"{process.DIR_PREFIX}*")
                  for pid in process.instance_processes(entry))


@pytest.mark.linuxcnc  # a real-time LinuxCNC: one per machine, so one after another on one worker
@pytest.mark.xdist_group("linuxcnc")
@pytest.mark.machine
@pytest.mark.skipif(not INSTALLED, reason="LinuxCNC is not installed (tests/setup_system.sh installs "
                    "linuxcnc-uspace)")
def test_a_linuxcnc_whose_script_is_killed_before_its_cleanup_leaves_no_realtime_running():
    """When the linuxcnc script does not end within the wait after SIGINT, it is killed before its
    cleanup ends; its rtapi_app (the servo thread) and linuxcncsvr run in sessions of their own and
    ran on after every such stop, loading the machine for everything after (the suite grew by a
    minute a run). Stopping ends them too, and the next LinuxCNC starts as before; a leftover whose
    script is gone but whose realtime runs on is still found and stopped."""
    axis = linuxcnc_config(demo_config_text()).axis
    for leftover_found in (False, True):
        linuxcnc = process.LinuxCnc(axis)
        try:
            realtime = process.instance_processes(linuxcnc.dir)
            os.killpg(linuxcnc.proc.pid, signal.SIGKILL)  # as when its cleanup outlasts the wait: killed
            linuxcnc.proc.wait(10)
            deadline = time.monotonic() + 10
            while process._group(linuxcnc.proc.pid) and time.monotonic() < deadline:
                time.sleep(0.1)
            stragglers = process.instance_processes(linuxcnc.dir)
            assert stragglers and set(stragglers) < set(realtime), "the script's group alone was not killed"
            if leftover_found:  # axiscal itself killed too: the next run finds what is left
                assert linuxcnc._lock is not None
                linuxcnc._lock.close()
                linuxcnc._lock = None
                leftover = process.find_leftover()
                assert leftover is not None and set(stragglers) <= set(leftover.pids)
                leftover.stop()
                assert process.find_leftover() is None
        finally:
            linuxcnc.stop()
        assert process.instance_processes(linuxcnc.dir) == [] and _axiscal_linuxcnc_processes() == []

"""A headless LinuxCNC: a generated INI and HAL file for one linear joint whose motor position
loops back as its feedback, with the campaign config's axis limits (soft limits, maximum velocity
and acceleration: the joint, the X axis and the trajectory planner all get the same), linuxcncrsh as the display (it keeps LinuxCNC up without a GUI and
is the command interface), started as root with an unprivileged RTAPI_UID and a writable
RTAPI_FIFO_PATH. With `comp_file` the joint gets COMP_FILE / COMP_FILE_TYPE = 0 and LinuxCNC's
own loader and motion module apply it.

One LinuxCNC per machine (LOCK_FILE). The LinuxCNC axiscal starts records itself in RECORD_FILE
(its process group, the start time of its leader, the boot, its directory, the axiscal that
started it) until axiscal stops it. An axiscal killed before it could (kill -9) leaves LinuxCNC
running; the next run finds that leftover by its record (`find_leftover`: the lock free, so no
axiscal runs it; the group alive, its leader the very process recorded) and stops it when the user
agrees or says `--yes` (`Leftover.stop`). A LinuxCNC without such a record, one axiscal did not
start, is refused as before: it is not axiscal's to stop."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import pwd
import select
import shutil
import signal
import socket
import stat
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Self, TextIO

from campaign.specs import AxisSpec
from protocols.hardware import AxisError

HAL = """loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
addf motion-command-handler servo-thread
addf motion-controller servo-thread
net j0pos joint.0.motor-pos-cmd => joint.0.motor-pos-fb
net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed
"""
PORT = 5007
"""linuxcncrsh's default TCP port."""
START_TIMEOUT_S = 60.0
HAL_TIMEOUT_S = 10.0
"""How long a HAL read (LinuxCnc.getp) may take, s."""
INSTALL_HINT = ("LinuxCNC is not installed: apt-get install linuxcnc-uspace (Debian; tests/setup_system.sh "
                "does it where apt is available)")


def installed() -> bool:
    return all(shutil.which(tool) for tool in ("linuxcnc", "linuxcncrsh", "halcmd"))


def ini_text(axis: AxisSpec, comp_file: Path | None) -> str:
    """The INI of one linear joint X in mm with the limits of `axis` (the config's [axis]: soft limits
    in mm, max_velocity in mm/s, max_acceleration in mm/s²)."""
    comp = f"COMP_FILE = {comp_file}\nCOMP_FILE_TYPE = 0\n" if comp_file else ""
    limits = (f"MIN_LIMIT = {axis.soft_limit_min!r}\nMAX_LIMIT = {axis.soft_limit_max!r}\n"
              f"MAX_VELOCITY = {axis.max_velocity!r}\nMAX_ACCELERATION = {axis.max_acceleration!r}\n")
    return f"""[EMC]
VERSION = 1.1
MACHINE = axiscal-linuxcnc
[DISPLAY]
DISPLAY = linuxcncrsh
[TASK]
TASK = milltask
CYCLE_TIME = 0.010
[RS274NGC]
PARAMETER_FILE = linuxcnc.var
[EMCMOT]
EMCMOT = motmod
SERVO_PERIOD = 1000000
COMM_TIMEOUT = 1.0
[EMCIO]
EMCIO = io
CYCLE_TIME = 0.100
TOOL_TABLE = tool.tbl
[HAL]
HALFILE = axiscal.hal
[TRAJ]
COORDINATES = X
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
MAX_LINEAR_VELOCITY = {axis.max_velocity!r}
MAX_LINEAR_ACCELERATION = {axis.max_acceleration!r}
[KINS]
KINEMATICS = trivkins coordinates=X
JOINTS = 1
[AXIS_X]
{limits}[JOINT_0]
TYPE = LINEAR
{limits}HOME = 0
HOME_OFFSET = 0
HOME_SEARCH_VEL = 0
HOME_LATCH_VEL = 0
HOME_SEQUENCE = 0
{comp}"""


class LinuxCnc:
    """One running LinuxCNC; `stop()` (or the context manager) ends it and cleans up."""

    def __init__(self, axis: AxisSpec, comp_file: Path | None = None):
        """`axis`: the config's [axis], whose limits the joint gets (a linear axis in mm)."""
        if not installed():
            raise AxisError(INSTALL_HINT)
        self._hal: subprocess.Popen[bytes] | None = None
        self._hal_lock = threading.Lock()
        self._hal_buffer = b""
        self._lock: TextIO | None = _one_instance()
        try:
            _check_record_path()
        except AxisError:
            self._lock.close()
            raise
        self.dir = Path(tempfile.mkdtemp(prefix=DIR_PREFIX))
        os.chmod(self.dir, 0o755)
        self.env = dict(os.environ)
        if os.geteuid() == 0:  # rtapi_app refuses root without a fallback uid
            self.env["RTAPI_UID"] = str(_unprivileged_uid())
            sock_dir = self.dir / "rtapi"
            sock_dir.mkdir()
            os.chown(sock_dir, int(self.env["RTAPI_UID"]), -1)
            self.env["RTAPI_FIFO_PATH"] = str(sock_dir / "fifo")
        if comp_file is not None:
            shutil.copy(comp_file, self.dir / "comp.txt")
        (self.dir / "axiscal.ini").write_text(ini_text(axis, self.dir / "comp.txt" if comp_file else None))
        (self.dir / "axiscal.hal").write_text(HAL)
        (self.dir / "tool.tbl").write_text("")
        self.log = open(self.dir / "linuxcnc.log", "w")  # noqa: SIM115 (open while LinuxCNC runs)
        # SIGINT at its default: a process started with it ignored (a pytest-xdist worker, nohup) would
        # pass that on, and the script cannot trap an ignored signal to clean up (coreutils env).
        self.proc = subprocess.Popen(["env", "--default-signal=INT", "linuxcnc", str(self.dir / "axiscal.ini")],
                                     cwd=self.dir, env=self.env,
                                     stdin=subprocess.DEVNULL, stdout=self.log, stderr=subprocess.STDOUT,
                                     start_new_session=True)
        try:
            self._record = _write_record(self.proc.pid, self.dir)
        except OSError as exc:  # e.g. /tmp full: stop the LinuxCNC nothing would find after a crash
            self._record = Record(self.proc.pid, 0, "", str(self.dir), os.getpid(), "")
            self.stop()
            raise AxisError(f"{RECORD_FILE}: cannot record the LinuxCNC axiscal starts ({exc.strerror or exc}); "
                            "LinuxCNC stopped again") from None
        self._wait_for_port()

    def _wait_for_port(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                break
            try:
                socket.create_connection(("127.0.0.1", PORT), timeout=0.5).close()
                return
            except OSError:
                time.sleep(0.3)
        self.stop()
        raise AxisError(f"LinuxCNC did not start within {START_TIMEOUT_S:g} s (see ~/linuxcnc_debug.txt)")

    def getp(self, name: str) -> str:
        """The value of HAL pin or parameter `name` as `halcmd getp` prints it. One `halcmd -s -k -f`
        session answers every read, started at the first: a halcmd started per read took about
        10 ms of a quiet machine, far more of a loaded one, and the simulated laser reads HAL at its
        rate_hz. AxisError when halcmd refuses the name (the session is started again for the next
        read) or does not answer within HAL_TIMEOUT_S."""
        with self._hal_lock:
            if self._hal is None:
                self._hal = subprocess.Popen(["halcmd", "-s", "-k", "-f"], env=self.env, stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, bufsize=0)
                self._hal_buffer = b""
            hal = self._hal
            assert hal.stdin is not None and hal.stdout is not None
            try:
                hal.stdin.write(f"getp {name}\n".encode("ascii"))
                deadline = time.monotonic() + HAL_TIMEOUT_S
                while b"\n" not in self._hal_buffer:
                    ready, _, _ = select.select([hal.stdout], [], [], max(0.0, deadline - time.monotonic()))
                    chunk = os.read(hal.stdout.fileno(), 4096) if ready else b""
                    if not chunk:
                        raise AxisError(f"halcmd getp {name}: " + ("halcmd ended" if ready else
                                                                   f"no answer within {HAL_TIMEOUT_S:g} s"))
                    self._hal_buffer += chunk
            except (OSError, AxisError) as exc:
                self._end_hal()
                raise exc if isinstance(exc, AxisError) else AxisError(f"halcmd getp {name}: {exc}") from None
            line, self._hal_buffer = self._hal_buffer.split(b"\n", 1)
            answer = line.decode("ascii", "replace").strip()
            if not answer or answer.startswith("<stdin>") or self._hal_buffer:
                self._end_hal()  # an error message (of one line or more): start afresh, in step
                raise AxisError(f"halcmd getp {name}: {answer.split(': ', 1)[-1] or 'no value'}")
            return answer

    def _end_hal(self) -> None:
        """End the halcmd session, if any (called with _hal_lock held, or once LinuxCNC stops)."""
        if self._hal is None:
            return
        hal, self._hal = self._hal, None
        with contextlib.suppress(OSError):
            assert hal.stdin is not None
            hal.stdin.close()
        try:
            hal.wait(timeout=2)
        except subprocess.TimeoutExpired:
            hal.kill()
            hal.wait()
        if hal.stdout is not None:
            hal.stdout.close()

    def stop(self) -> None:
        with self._hal_lock:
            self._end_hal()
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)  # the linuxcnc script cleans up on SIGINT/TERM
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        _end_stragglers(self.dir)
        self.log.close()
        shutil.rmtree(self.dir, ignore_errors=True)
        _remove_record(self._record)
        if self._lock is not None:
            self._lock.close()  # the next instance may start
            self._lock = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


LOCK_FILE = Path(tempfile.gettempdir()) / "axiscal-linuxcnc.lock"
"""Held while axiscal runs a LinuxCNC: one machine runs one (its HAL, its shared memory and
linuxcncrsh's port 5007 are machine-wide), and a second would take over the first one's axis."""
RECORD_FILE = Path(tempfile.gettempdir()) / "axiscal-linuxcnc.json"
"""The LinuxCNC axiscal started and has not stopped yet (JSON: pgid, start_ticks, boot_id, dir,
axiscal_pid, started), written by the axiscal that holds LOCK_FILE, removed when it stops it."""
RECORD_LIMIT_BYTES = 4096
"""The largest record file read (a record is about 250 bytes)."""
DIR_PREFIX = "axiscal-linuxcnc-"
"""The start of the name of each LinuxCNC's temporary directory (its INI, HAL file and log)."""
STOP_TIMEOUT_S = 30.0
"""How long LinuxCNC gets to clean up after SIGINT before its processes are killed, s."""


@dataclass(frozen=True)
class Record:
    """What RECORD_FILE says of a LinuxCNC axiscal started: its process group (the `linuxcnc`
    script's pid: it leads a session of its own), the script's start time in clock ticks after
    boot (/proc/PID/stat: a pid used again by another process has another), the boot it ran in,
    its directory, and the axiscal process that started it and when (ISO 8601, local time)."""

    pgid: int
    start_ticks: int
    boot_id: str
    dir: str
    axiscal_pid: int
    started: str


@dataclass(frozen=True)
class Leftover:
    """A LinuxCNC that an axiscal started and did not stop (it was killed), still running."""

    record: Record
    pids: tuple[int, ...]
    """Its processes now (the members of its process group)."""
    record_file: Path = RECORD_FILE
    lock_file: Path = LOCK_FILE

    def describe(self) -> str:
        r = self.record
        return (f"a LinuxCNC that axiscal started at {r.started} (axiscal pid {r.axiscal_pid}, ended before it "
                f"could stop it; LinuxCNC's process group {r.pgid}, {len(self.pids)} processes; its files in {r.dir})")

    def stop(self) -> None:
        """Stop it as axiscal stops its own: SIGINT to its process group (the linuxcnc script
        cleans up), SIGKILL after STOP_TIMEOUT_S; then its directory and the record go. Holds
        LOCK_FILE meanwhile; AxisError when an axiscal now holds it or the group will not end."""
        with _held(self.lock_file) as lock:
            if lock is None:
                raise AxisError("another axiscal is running LinuxCNC on this machine now; wait for it to end")
            pgid = self.record.pgid
            for sig, wait_s in ((signal.SIGINT, STOP_TIMEOUT_S), (signal.SIGKILL, 10.0)):
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(pgid, sig)
                deadline = time.monotonic() + wait_s
                while _group(pgid) and time.monotonic() < deadline:
                    time.sleep(0.2)
                if not _group(pgid):
                    break
            else:
                raise AxisError(f"LinuxCNC's process group {pgid} did not end after SIGKILL")
            directory = Path(self.record.dir)
            if _started_here(directory):
                _end_stragglers(directory)
                shutil.rmtree(directory, ignore_errors=True)
            _remove_record(self.record, self.record_file)


def find_leftover(record_file: Path = RECORD_FILE, lock_file: Path = LOCK_FILE) -> Leftover | None:
    """The LinuxCNC an earlier axiscal started and left running, or None: none recorded, an
    axiscal holds the lock (it runs its LinuxCNC and will stop it), or the recorded one has ended
    (the stale record is removed then). Trusted only as written by this user, in this boot, its
    process group (or its realtime, found by instance_processes) alive, not axiscal's own nor 0 or
    1, and, while its leader lives, the leader the very process recorded."""
    with _held(lock_file) as lock:
        if lock is None:
            return None
        record = _read_record(record_file)
        if record is None:
            return None
        # never a group of its own or none (killpg(0) signals the caller's group): a hand-edited or
        # foreign record would have axiscal stop itself and its shell
        pids: list[int] = []
        if record.pgid > 1 and record.pgid != os.getpgrp():
            pids = _group(record.pgid)
            if _started_here(Path(record.dir)):  # with its realtime, out of the group (the script may be gone)
                pids = sorted({*pids, *instance_processes(Path(record.dir))})
        leader_ok = record.pgid not in pids or _start_ticks(record.pgid) == record.start_ticks
        if record.boot_id != _boot_id() or not pids or not leader_ok or os.getpid() in pids:
            _remove_record(record, record_file)
            return None
        return Leftover(record, tuple(pids), record_file, lock_file)


@contextlib.contextmanager
def _held(lock_file: Path) -> Iterator[TextIO | None]:
    """LOCK_FILE held (the open file) for the block, or None when another process holds it."""
    lock = open(lock_file, "a")  # noqa: SIM115
    try:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield None
            return
        yield lock
    finally:
        lock.close()


def _one_instance(confirm: Callable[[str], bool] | None = None, lock_file: Path = LOCK_FILE,
                  record_file: Path = RECORD_FILE, port: int = PORT) -> TextIO:
    """The lock of the one LinuxCNC this machine may run, as an open file. AxisError when another
    axiscal runs LinuxCNC here, when a LinuxCNC an earlier axiscal left is still running and
    `confirm(what it is)` does not say to stop it (stopped when it does), or when any other
    LinuxCNC with linuxcncrsh on `port` runs here."""
    leftover = find_leftover(record_file, lock_file)
    if leftover is not None:
        if confirm is None or not confirm(leftover.describe()):
            raise AxisError(f"{leftover.describe()} is still running; run again with --yes to stop it, or stop it "
                            f"yourself: kill -INT -{leftover.record.pgid}")
        leftover.stop()
    lock = open(lock_file, "a")  # noqa: SIM115 (held until stop())
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        raise AxisError("another axiscal is running LinuxCNC on this machine (one LinuxCNC per machine: "
                        "its HAL and port 5007 are shared); wait for it to end") from None
    try:
        socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
    except OSError:
        return lock
    lock.close()
    raise AxisError(f"a LinuxCNC that axiscal did not start is running here (linuxcncrsh answers on port {port}, "
                    f"and {record_file} records none of axiscal's); stop it first (axiscal would otherwise drive "
                    "its axis)")


def _check_record_path(record_file: Path = RECORD_FILE) -> None:
    """AxisError, before LinuxCNC starts, when `record_file` is there and not a file axiscal can
    replace with its record (a directory, e.g. another user's in /tmp: the record's rename failed
    with LinuxCNC already running)."""
    with contextlib.suppress(FileNotFoundError):
        if stat.S_ISDIR(os.lstat(record_file).st_mode):
            raise AxisError(f"{record_file} is a directory, not axiscal's record of the LinuxCNC it starts; "
                            "remove it (axiscal records there the LinuxCNC it starts, to find it after a crash)")


def _write_record(pgid: int, directory: Path, record_file: Path = RECORD_FILE) -> Record:
    """Record the LinuxCNC just started (its `linuxcnc` script's pid leads its process group)."""
    record = Record(pgid, _start_ticks(pgid) or 0, _boot_id(), str(directory), os.getpid(),
                    time.strftime("%Y-%m-%d %H:%M:%S"))
    temporary = record_file.with_name(f".{record_file.name}.{os.getpid()}")
    with contextlib.suppress(FileNotFoundError):
        temporary.unlink()  # a stale one, or a link someone put there: never written through
    fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
    with os.fdopen(fd, "w") as f:
        f.write(json.dumps(record.__dict__) + "\n")
    os.replace(temporary, record_file)
    return record


def _read_record(record_file: Path) -> Record | None:
    """The record in `record_file` when this user wrote it as a plain file (not a link, a FIFO,
    whose opening would wait for a writer, or a directory), of at most RECORD_LIMIT_BYTES, and it
    reads whole."""
    try:
        fd = os.open(record_file, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_uid != os.geteuid() or info.st_size > RECORD_LIMIT_BYTES:
        os.close(fd)  # before fdopen: it refuses a directory
        return None
    with os.fdopen(fd, "rb") as f:
        try:
            fields = json.loads(f.read(RECORD_LIMIT_BYTES))
            return Record(int(fields["pgid"]), int(fields["start_ticks"]), str(fields["boot_id"]), str(fields["dir"]),
                          int(fields["axiscal_pid"]), str(fields["started"]))
        except (OSError, ValueError, KeyError, TypeError, RecursionError):
            return None


def _remove_record(record: Record, record_file: Path = RECORD_FILE) -> None:
    """Remove `record_file` when it still holds `record` (not a later LinuxCNC's)."""
    if _read_record(record_file) == record:
        with contextlib.suppress(FileNotFoundError):
            record_file.unlink()


def _stat_fields(pid: int) -> list[str] | None:
    """/proc/PID/stat after the command name (field 3, the state, first), or None when it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat[stat.rindex(")") + 2:].split()


def _start_ticks(pid: int) -> int | None:
    """When process `pid` started, clock ticks after boot (field 22 of /proc/PID/stat)."""
    fields = _stat_fields(pid)
    return int(fields[19]) if fields else None


def _group(pgid: int) -> list[int]:
    """The live processes of process group `pgid` (field 5 of /proc/PID/stat; zombies, which have
    ended and wait for their parent, left out)."""
    members = []
    for entry in Path("/proc").iterdir():
        if (entry.name.isdigit() and (fields := _stat_fields(int(entry.name))) and int(fields[2]) == pgid
                and fields[0] != "Z"):
            members.append(int(entry.name))
    return members


def _started_here(directory: Path) -> bool:
    """Whether `directory` is one LinuxCnc makes (DIR_PREFIX in the temporary directory)."""
    return directory.parent == Path(tempfile.gettempdir()) and directory.name.startswith(DIR_PREFIX)


def instance_processes(directory: Path) -> list[int]:
    """The live processes of the LinuxCNC whose files are in `directory`: every process the
    `linuxcnc` script starts inherits INI_FILE_NAME (its INI there), including the realtime's
    rtapi_app and linuxcncsvr, which run in sessions of their own, outside the script's process
    group. Processes this user cannot read are not counted (they are not axiscal's)."""
    tag = f"INI_FILE_NAME={directory / 'axiscal.ini'}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = (entry / "environ").read_bytes()
        except OSError:
            continue
        if tag in environ.split(b"\0") and (fields := _stat_fields(int(entry.name))) and fields[0] != "Z":
            found.append(int(entry.name))
    return found


def _end_stragglers(directory: Path, wait_s: float = 5.0) -> None:
    """End what is left of the LinuxCNC in `directory` once its script has ended: when the script
    was killed before its cleanup finished (it did not end within the wait after SIGINT), its
    rtapi_app (the servo thread) and linuxcncsvr would run on, out of its process group, taking a
    core's share from everything after. SIGTERM, then SIGKILL after `wait_s`."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        pids = instance_processes(directory)
        for pid in pids:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)
        deadline = time.monotonic() + wait_s
        while pids and instance_processes(directory) and time.monotonic() < deadline:
            time.sleep(0.1)


def _boot_id() -> str:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return ""


def _unprivileged_uid() -> int:
    for name in ("nobody", "daemon"):
        try:
            return pwd.getpwnam(name).pw_uid
        except KeyError:
            continue
    return 65534

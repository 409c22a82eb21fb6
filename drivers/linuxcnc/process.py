"""A headless LinuxCNC: a generated INI and HAL file for one linear joint whose motor position
loops back as its feedback, with the campaign config's axis limits (soft limits, maximum velocity
and acceleration: the joint, the X axis and the trajectory planner all get the same), linuxcncrsh as the display (it keeps LinuxCNC up without a GUI and
is the command interface), started as root with an unprivileged RTAPI_UID and a writable
RTAPI_FIFO_PATH. With `comp_file` the joint gets COMP_FILE / COMP_FILE_TYPE = 0 and LinuxCNC's
own loader and motion module apply it."""

from __future__ import annotations

import fcntl
import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
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
        self._lock: TextIO | None = _one_instance()
        self.dir = Path(tempfile.mkdtemp(prefix="axiscal-linuxcnc-"))
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
        self.proc = subprocess.Popen(["linuxcnc", str(self.dir / "axiscal.ini")], cwd=self.dir, env=self.env,
                                     stdin=subprocess.DEVNULL, stdout=self.log, stderr=subprocess.STDOUT,
                                     start_new_session=True)
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

    def halcmd(self, *args: str) -> str:
        """Run `halcmd ARGS` against this instance; its output, stripped."""
        done = subprocess.run(["halcmd", *args], env=self.env, capture_output=True, text=True, timeout=10, check=False)
        if done.returncode != 0:
            raise AxisError(f"halcmd {' '.join(args)}: {done.stderr.strip() or done.stdout.strip()}")
        return done.stdout.strip()

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)  # the linuxcnc script cleans up on SIGINT/TERM
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        self.log.close()
        shutil.rmtree(self.dir, ignore_errors=True)
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


def _one_instance() -> TextIO:
    """The lock of the one LinuxCNC this machine may run, as an open file; AxisError when another
    axiscal, or any LinuxCNC with linuxcncrsh, already runs here."""
    lock = open(LOCK_FILE, "a")  # noqa: SIM115 (held until stop())
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        raise AxisError("another axiscal is running LinuxCNC on this machine (one LinuxCNC per machine: "
                        "its HAL and port 5007 are shared); wait for it to end") from None
    try:
        socket.create_connection(("127.0.0.1", PORT), timeout=0.5).close()
    except OSError:
        return lock
    lock.close()
    raise AxisError(f"a LinuxCNC is already running here (linuxcncrsh answers on port {PORT}); stop it first "
                    "(axiscal would otherwise drive its axis)")


def _unprivileged_uid() -> int:
    for name in ("nobody", "daemon"):
        try:
            return pwd.getpwnam(name).pw_uid
        except KeyError:
            continue
    return 65534

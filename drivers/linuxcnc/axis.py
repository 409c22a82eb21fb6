"""The LinuxCNC joint as an Axis (protocols.hardware), over linuxcncrsh: a line-based text protocol
on TCP (`hello`, `set …`, `get …`; with `set verbose on` every command is answered). A move is an
MDI `G1 X… F…`; the status comes from `get abs_act_pos`, `get program_status` and `get error`.
The limit and velocity checks happen before every motion in the executor, as for every axis."""

from __future__ import annotations

import socket
import time

from drivers.linuxcnc.process import PORT
from protocols.hardware import AxisError, AxisStatus
from protocols.plc_contract import CompTable

TIMEOUT_S = 5.0


class LinuxCncShell:
    """A linuxcncrsh session: `ask(command)` sends one line and returns the answer line."""

    def __init__(self, host: str = "127.0.0.1", port: int = PORT):
        try:
            self.sock = socket.create_connection((host, port), timeout=TIMEOUT_S)
        except OSError as exc:
            raise AxisError(f"LinuxCNC at {host}:{port}: cannot connect ({exc})") from None
        self._buffer = b""
        self._send("hello EMC axiscal 1.1")
        if not self._line().startswith("HELLO ACK"):
            raise AxisError("linuxcncrsh refused the session")
        self._send("set echo off")
        self._line()
        self.ask("set verbose on")
        self.ask("set enable EMCTOO")

    def _send(self, line: str) -> None:
        try:
            self.sock.sendall((line + "\r\n").encode("ascii"))
        except OSError as exc:
            raise AxisError(f"LinuxCNC: connection lost ({exc})") from None

    def _line(self) -> str:
        while b"\n" not in self._buffer:
            try:
                chunk = self.sock.recv(4096)
            except OSError as exc:
                raise AxisError(f"LinuxCNC: no answer ({exc})") from None
            if not chunk:
                raise AxisError("LinuxCNC: connection closed")
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return line.decode("ascii", "replace").strip()

    def ask(self, command: str) -> str:
        self._send(command)
        answer = self._line()
        if answer.endswith("NAK"):
            raise AxisError(f"LinuxCNC refused '{command}': {answer}")
        return answer

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


class LinuxCncAxis:
    """Axis X of a running LinuxCNC: switched on and homed when opened."""

    def __init__(self, shell: LinuxCncShell):
        self.shell = shell
        self.shell.ask("set estop off")
        self.shell.ask("set machine on")
        self.shell.ask("set home 0")
        deadline = time.monotonic() + 10
        while "YES" not in self.shell.ask("get joint_homed").split()[1:2]:
            if time.monotonic() > deadline:
                raise AxisError("LinuxCNC: joint 0 did not home")
            time.sleep(0.05)
        self.shell.ask("set mode mdi")
        self._target: float | None = None

    def status(self) -> AxisStatus:
        position = float(self.shell.ask("get abs_act_pos").split()[1])
        running = self.shell.ask("get program_status").split()[-1] != "IDLE"
        arrived = self._target is None or abs(position - self._target) < 1e-6
        error = self.shell.ask("get error").split(None, 1)[-1]  # "ERROR OK" when there is none
        failed = error.upper() not in ("OK", "ERROR", "")
        machine_on = self.shell.ask("get machine").split()[-1] == "ON"
        return AxisStatus(busy=running or not arrived, done=not running and arrived, error=failed,
                          error_id=1 if failed else 0, actual_position=position, enabled=machine_on, homed=True)

    def start_move(self, position: float, velocity: float) -> None:
        self._target = position
        self.shell.ask(f"set mdi G1 X{position:.6f} F{velocity * 60.0:.4f}")

    def halt(self) -> None:
        self.shell.ask("set abort")
        self._target = None

    def reset(self) -> None:
        self.shell.ask("set estop off")
        self.shell.ask("set machine on")
        self.shell.ask("set mode mdi")

    def close(self) -> None:
        self.shell.close()

    def write_comp_table(self, table: CompTable) -> None:
        raise AxisError("LinuxCNC reads its compensation from COMP_FILE at start: restart it with the file")

    def read_comp_table(self) -> CompTable | None:
        return None

"""A simulated TwinCAT PLC that runs FB_AxiscalAxis for one axis.

Its variables are GVL_Axiscal (`protocols.plc_contract`), held in `SimPLC.memory` with TwinCAT's
layout (`protocols.plc_layout`); `SimPLC.handler` answers ADS requests on that memory as a TwinCAT
PLC runtime does (`drivers.sim.ads_device`), so a real ADS client can talk to it through
`drivers.sim.ads_server.SimAdsServer`. It runs the FB for its own axis; the other axes' entries
exist and stay as written.

There is no PLC thread: `scan(t)` is one PLC cycle at simulated time t (s); attach it to the
simulated clock with `clock.attach(plc.scan)`. The ADS server answers requests on its own threads,
so every scan and every request holds the same lock: a request sees the variables between two
cycles, as on a real PLC. Each scan also samples the clients' device notifications
(`drivers.sim.ads_notifications`) and, after releasing the lock, hands those due to each client's
connection, which queues them and never makes the scan wait (`drivers.sim.ads_server`).

The motion is computed analytically from the start of each move: a trapezoidal velocity profile
with the commanded velocity and the constructor's acceleration (also used to decelerate on a halt).
Positions are in the axis unit (mm or deg), velocities in axis unit/s, accelerations in axis
unit/s², times in s.
"""

from __future__ import annotations

import math
import struct
import threading
from dataclasses import dataclass
from typing import Any

from drivers.sim.ads_device import AdsDevice
from protocols import plc_contract, plc_layout
from protocols.plc_contract import Command, PlcErrorId, Symbol

_FORMATS = {"BOOL": "?", "INT": "h", "UINT": "H", "UDINT": "I", "LREAL": "d"}
"""IEC elementary type -> struct format character."""


@dataclass(frozen=True)
class _Phase:
    """A stretch of constant acceleration: starts at t0 (s) at p0 (axis unit) with v0 (unit/s)."""

    t0: float
    p0: float
    v0: float
    a: float
    duration: float


class _Motion:
    """Piecewise constant-acceleration motion that ends at rest at `end_position` at `end_time`."""

    def __init__(self, t0: float, p0: float, v0: float, steps: list[tuple[float, float]]):
        """steps: (acceleration, duration) pairs, in order."""
        self.phases: list[_Phase] = []
        t, p, v = t0, p0, v0
        for a, duration in steps:
            self.phases.append(_Phase(t, p, v, a, duration))
            t, p, v = t + duration, p + v * duration + 0.5 * a * duration**2, v + a * duration
        self.end_time = t
        self.end_position = p

    def state(self, t: float) -> tuple[float, float]:
        """(position, velocity) at time t; before the start the first point, after the end at rest."""
        if t >= self.end_time or not self.phases:
            return self.end_position, 0.0
        for phase in reversed(self.phases):
            if t >= phase.t0:
                dt = t - phase.t0
                return phase.p0 + phase.v0 * dt + 0.5 * phase.a * dt**2, phase.v0 + phase.a * dt
        first = self.phases[0]
        return first.p0, first.v0


def _stop_steps(v0: float, decel: float) -> list[tuple[float, float]]:
    """Steps that brake from v0 (unit/s) to rest at decel (unit/s², > 0)."""
    if v0 == 0:
        return []
    return [(-math.copysign(decel, v0), abs(v0) / decel)]


def _trapezoid_steps(distance: float, velocity: float, accel: float) -> list[tuple[float, float]]:
    """Steps of a rest-to-rest move over `distance` (signed, unit) at `velocity` and `accel`."""
    d = abs(distance)
    if d == 0:
        return []
    a = math.copysign(accel, distance)
    t_ramp = velocity / accel
    if d >= velocity * t_ramp:  # long enough to reach the velocity: accelerate, cruise, brake
        return [(a, t_ramp), (0.0, (d - velocity * t_ramp) / velocity), (-a, t_ramp)]
    t_ramp = math.sqrt(d / accel)  # triangle: brake as soon as half the distance is covered
    return [(a, t_ramp), (-a, t_ramp)]


class SimPLC:
    """The PLC side of one axis: FB_AxiscalAxis with a simulated drive behind it.

    axis: the axis number n in GVL_Axiscal.astAxes[n] (1-based).
    max_velocity: highest velocity a move may ask for, axis unit/s (FB input fMaxVelocity).
    acceleration: acceleration and deceleration of every move and halt, axis unit/s².
    position: position of the axis at the start, axis unit.
    start_time: simulated time at which the PLC starts, s (the clock's start time).
    """

    def __init__(
        self,
        axis: int = 1,
        max_velocity: float = 100.0,
        acceleration: float = 500.0,
        position: float = 0.0,
        enabled: bool = True,
        homed: bool = True,
        start_time: float = 0.0,
    ):
        if max_velocity <= 0 or acceleration <= 0:
            raise ValueError("max_velocity and acceleration must be > 0")
        self.axis = axis
        self.max_velocity = max_velocity
        self.acceleration = acceleration
        self.correction = 0.0
        """Added to the motor setpoint by the compensation feature, axis unit."""
        self.last_direction = 1
        """+1 or -1: direction of the current or last move (a move to where the axis is keeps it)."""
        self.arrival_time: float | None = None
        """Simulated time the last move finished, s; None while moving and before the first move."""
        self._enabled = enabled
        self._homed = homed
        self._lock = threading.Lock()
        self.memory = bytearray(plc_layout.GVL_TYPE.size)
        """GVL_Axiscal's bytes, laid out as TwinCAT does (`protocols.plc_layout`)."""
        self.handler = AdsDevice(self.memory, self._lock, start_time=float(start_time))
        self._control = plc_contract.control_symbols(axis)
        self._status = plc_contract.status_symbols(axis)
        self._symbols = {
            s.name: s
            for group in (self._control, self._status, plc_contract.comp_symbols(axis))
            for s in group.values()
        }
        self._places = {name: plc_layout.require(name) for name in self._symbols}
        self._t = float(start_time)  # time of the last scan, s
        self._rest_position = float(position)  # where the axis is when no motion is running
        self._motion: _Motion | None = None
        self._halting = False  # the running motion is a halt
        self._arrived = False  # the last move reached its target
        self._error_id = 0  # latched error, 0 when none
        self._write_status()

    # --- the PLC cycle -----------------------------------------------------------------------

    def scan(self, t: float) -> None:
        """Run the PLC from the last scan up to simulated time t (s).

        Requests written since the last scan are taken at the time of the last scan, when the PC
        wrote them (the simulated clock stands still between scans), so a move starts at once
        however long the next clock step is. Then the motion runs on to t.
        """
        with self._lock:
            taken_at = min(self._t, t)
            self._finish_motion(taken_at)
            for request in self._take_requests():
                self._apply(request, taken_at)
            self._t = t
            self._finish_motion(t)
            self._write_status()
            self.handler.time_s = t
            due = self.handler.collect_notifications(t)
        for client, packet in due:
            client.send_notification(packet)

    def _take_requests(self) -> list[int]:
        """Read and clear the request flags, like FB_AxiscalAxis (separate MC_Reset and MC_Halt):
        a reset is applied first, and a halt wins over a move requested in the same cycle."""
        flags = {name: bool(self._get(name)) for name in ("bExecute", "bReset", "bHalt")}
        for name, raised in flags.items():
            if raised:
                self._set(name, False)
        requests: list[int] = [Command.RESET] if flags["bReset"] else []
        if flags["bHalt"]:
            requests.append(Command.HALT)
        elif flags["bExecute"]:
            requests.append(self._get("eCommand"))
        return requests

    def _apply(self, request: int, t: float) -> None:
        if request == Command.NONE:
            return
        if request == Command.MOVE_ABSOLUTE:
            velocity = self._get("fVelocity")
            if self._error_id:
                return  # ignored until a reset
            if not self._enabled:
                self._latch_error(PlcErrorId.NOT_ENABLED)
            elif not 0 < velocity <= self.max_velocity:
                self._latch_error(PlcErrorId.INVALID_VELOCITY)
            else:
                self._start_move(self._get("fPosition"), velocity, t)
        elif request == Command.HALT:
            self._start_halt(t)
        elif request == Command.RESET:
            self._error_id = 0
        else:
            self._latch_error(PlcErrorId.UNKNOWN_COMMAND)

    def _start_move(self, target: float, velocity: float, t: float) -> None:
        """Brake to rest if moving, then a trapezoidal move to target."""
        p, v = self._motor_state(t)
        steps = _stop_steps(v, self.acceleration)
        stop_at = _Motion(t, p, v, steps).end_position
        if target != stop_at:
            self.last_direction = 1 if target > stop_at else -1
        steps += _trapezoid_steps(target - stop_at, velocity, self.acceleration)
        self._motion = _Motion(t, p, v, steps)
        self._motion.end_position = target  # exact, whatever the float sum of the steps gives
        self._halting = False
        self._arrived = False
        self.arrival_time = None

    def _start_halt(self, t: float) -> None:
        self._arrived = False
        if self._motion is None:
            return
        p, v = self._motor_state(t)
        self._motion = _Motion(t, p, v, _stop_steps(v, self.acceleration))
        self._halting = True

    def _finish_motion(self, t: float) -> None:
        if self._motion is not None and t >= self._motion.end_time:
            self._rest_position = self._motion.end_position
            self.arrival_time = self._motion.end_time
            self._arrived = not self._halting
            self._motion = None
            self._halting = False

    def _stop_now(self) -> None:
        """Stop where the axis is at the last scan time, as when the drive drops out."""
        if self._motion is not None:
            self._rest_position = self._motor_state(self._t)[0]
            self.arrival_time = self._t
        self._motion = None
        self._halting = False
        self._arrived = False

    def _latch_error(self, error_id: int) -> None:
        """Keep the first error until a reset, like FB_AxiscalAxis. Any error clears bDone."""
        self._arrived = False
        if self._error_id == 0:
            self._error_id = int(error_id)

    def _motor_state(self, t: float) -> tuple[float, float]:
        """(position without correction, velocity) at time t."""
        if self._motion is None:
            return self._rest_position, 0.0
        return self._motion.state(t)

    def _write_status(self) -> None:
        busy = self._motion is not None
        self._set("bBusy", busy)
        self._set("bDone", self._arrived and not busy)
        self._set("bError", self._error_id != 0)
        self._set("nErrorId", self._error_id)
        self._set("fActPosition", self._motor_state(self._t)[0])
        self._set("bEnabled", self._enabled)
        self._set("bHomed", self._homed)

    # --- for the rest of the simulated machine -----------------------------------------------

    def setpoint_position(self, t: float) -> float:
        """The commanded motor position at simulated time t (s), axis unit, including `correction`.

        fActPosition is the same without the correction: the NC reaches the target exactly, the
        correction moves the motor away from it."""
        with self._lock:
            return self._motor_state(t)[0] + self.correction

    def inject_error(self, error_id: int) -> None:
        """A drive fault now: the axis stops where it is and bError/nErrorId are set (the first
        error is kept until a reset)."""
        with self._lock:
            self._stop_now()
            self._latch_error(error_id)
            self._write_status()

    @property
    def enabled(self) -> bool:
        """The drive is powered (bEnabled at the next scan). Setting False stops the axis where it is."""
        return self._enabled

    @enabled.setter
    def enabled(self, value: bool) -> None:
        with self._lock:
            if not value:
                self._stop_now()
            self._enabled = bool(value)

    @property
    def homed(self) -> bool:
        """The axis is referenced (bHomed at the next scan)."""
        return self._homed

    @homed.setter
    def homed(self, value: bool) -> None:
        with self._lock:
            self._homed = bool(value)

    def value(self, name: str) -> bool | int | float | list:
        """The current value of a contract symbol of this axis (a list for an array)."""
        with self._lock:
            return self._decode(name)

    # --- PLC variables -----------------------------------------------------------------------

    @staticmethod
    def _encode(symbol: Symbol, value: float | bool | list[float]) -> bytes:
        fmt = _FORMATS[symbol.iec_type]
        if symbol.array_length is None:
            return struct.pack("<" + fmt, value)
        values = [value] * symbol.array_length if not isinstance(value, list) else value
        return struct.pack(f"<{symbol.array_length}{fmt}", *values)

    def _decode(self, name: str) -> Any:
        symbol, place = self._symbols[name], self._places[name]
        raw = self.memory[place.offset:place.offset + place.size]
        fmt = _FORMATS[symbol.iec_type]
        if symbol.array_length is None:
            return struct.unpack("<" + fmt, raw)[0]
        return list(struct.unpack(f"<{symbol.array_length}{fmt}", raw))

    def _get(self, member: str) -> Any:
        """Value of a control or status member of this axis, e.g. "bExecute"."""
        symbol = self._control.get(member) or self._status[member]
        return self._decode(symbol.name)

    def _set(self, member: str, value: float | bool | list[float]) -> None:
        symbol = self._control.get(member) or self._status[member]
        place = self._places[symbol.name]
        self.memory[place.offset:place.offset + place.size] = self._encode(symbol, value)

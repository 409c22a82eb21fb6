"""A simulated TwinCAT PLC that runs FB_AxiscalAxis for one axis.

Its variables are the symbols of `protocols.plc_contract` for that axis, held as
`pyads.testserver.PLCVariable`s on an `AdvancedHandler` (`SimPLC.handler`), so a real pyads client
can talk to it through `drivers.sim.ads_server.SimAdsServer`.

There is no PLC thread: `scan(t)` is one PLC cycle at simulated time t (s); attach it to the
simulated clock with `clock.attach(plc.scan)`. The ADS server answers requests on its own threads,
so every scan and every request holds the same lock: a request sees the variables between two
cycles, as on a real PLC.

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

from pyads import constants
from pyads.testserver import AdvancedHandler, PLCVariable
from pyads.testserver.handler import AmsPacket, AmsResponseData

from protocols import plc_contract
from protocols.plc_contract import Command, PlcErrorId, Symbol

_ADS_TYPES = {
    "BOOL": (constants.ADST_BIT, "?"),
    "INT": (constants.ADST_INT16, "h"),
    "UINT": (constants.ADST_UINT16, "H"),
    "UDINT": (constants.ADST_UINT32, "I"),
    "LREAL": (constants.ADST_REAL64, "d"),
}
"""IEC type -> (ADS data type id, struct format character)."""

_ADS_SYMBOL_NOT_FOUND = 0x710
"""ADS error code a real PLC returns for an unknown symbol name."""


_ADS_COMMAND_WRITE = 3
"""The ADS Write command id (a write by handle, as pyads' write_by_name sends it)."""
_ADS_COMMAND_READ, _ADS_COMMAND_READ_WRITE = 2, 9
_ADS_INVALID_SIZE = 0x705
"""ADSERR_DEVICE_INVALIDSIZE: what TwinCAT answers to a write whose length is not the variable's."""
_ADSIGRP_SYM_VALBYHND, _ADSIGRP_SYM_RELEASEHND = 0xF005, 0xF006


class _LockedHandler(AdvancedHandler):
    """An AdvancedHandler that answers each request while holding the PLC's lock.

    An unknown symbol gets the ADS error a real PLC gives; the plain handler raises KeyError
    instead, which kills the server's connection thread and leaves the client waiting. A write
    whose length is not the variable's size is refused with 0x705, as TwinCAT does: the plain
    handler would store it, and the next PLC scan could not decode the variable. The error goes in
    the reply's result field (the AMS header's error stays 0), as TwinCAT answers ADS requests.
    """

    def __init__(self, lock: threading.Lock):
        super().__init__()
        self._lock = lock
        self.writes = 0
        """ADS write requests answered so far (a cheap 'a variable may have changed' marker)."""

    def handle_request(self, request: AmsPacket) -> AmsResponseData:
        with self._lock:
            command = struct.unpack("<H", request.ams_header.command_id)[0]
            try:
                if command == _ADS_COMMAND_WRITE:
                    self.writes += 1
                    if not self._size_fits(request.ams_header.data):
                        return self._error(request, command, _ADS_INVALID_SIZE)
                return super().handle_request(request)
            except KeyError:
                return self._error(request, command, _ADS_SYMBOL_NOT_FOUND)

    def _size_fits(self, data: bytes) -> bool:
        """Does a Write request's length match its variable's size? (KeyError: no such variable)"""
        group, offset, length = struct.unpack("<III", data[:12])
        if group == _ADSIGRP_SYM_RELEASEHND:
            return True
        var = (self.get_variable_by_handle(offset) if group == _ADSIGRP_SYM_VALBYHND
               else self.get_variable_by_indices(group, offset))
        return length == var.size

    @staticmethod
    def _error(request: AmsPacket, command: int, code: int) -> AmsResponseData:
        """A reply carrying `code` in its result field; read replies also carry a length of 0."""
        state = struct.unpack("<H", request.ams_header.state_flags)[0] | 0x0001
        body = struct.pack("<I", code)
        if command in (_ADS_COMMAND_READ, _ADS_COMMAND_READ_WRITE):
            body += struct.pack("<I", 0)
        return AmsResponseData(struct.pack("<H", state), struct.pack("<I", 0), body)


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
        self.handler = _LockedHandler(self._lock)
        self._control = plc_contract.control_symbols(axis)
        self._status = plc_contract.status_symbols(axis)
        self._symbols = {
            s.name: s
            for group in (self._control, self._status, plc_contract.comp_symbols(axis))
            for s in group.values()
        }
        self._vars = {name: self._register(s) for name, s in self._symbols.items()}
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

    def _take_requests(self) -> list[int]:
        """Read and clear the request flags, like FB_AxiscalAxis (separate MC_Reset and MC_Halt):
        a reset is applied first, and a halt wins over a move requested in the same cycle."""
        flags = {name: bool(self._get(name)) for name in ("bExecute", "bReset", "bHalt")}
        for name, raised in flags.items():
            if raised:
                self._set(name, False)
        requests = [Command.RESET] if flags["bReset"] else []
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

    def _register(self, symbol: Symbol) -> PLCVariable:
        ads_type, _ = _ADS_TYPES[symbol.iec_type]
        type_name = symbol.iec_type
        if symbol.array_length is not None:
            type_name = f"ARRAY [0..{symbol.array_length - 1}] OF {symbol.iec_type}"
        var = PLCVariable(symbol.name, self._encode(symbol, 0), ads_type, type_name)
        self.handler.add_variable(var)
        return var

    @staticmethod
    def _encode(symbol: Symbol, value) -> bytes:
        fmt = _ADS_TYPES[symbol.iec_type][1]
        if symbol.array_length is None:
            return struct.pack("<" + fmt, value)
        values = [value] * symbol.array_length if not isinstance(value, list) else value
        return struct.pack(f"<{symbol.array_length}{fmt}", *values)

    def _decode(self, name: str):
        symbol = self._symbols[name]
        fmt = _ADS_TYPES[symbol.iec_type][1]
        if symbol.array_length is None:
            return struct.unpack("<" + fmt, self._vars[name].value)[0]
        return list(struct.unpack(f"<{symbol.array_length}{fmt}", self._vars[name].value))

    def _get(self, member: str):
        """Value of a control or status member of this axis, e.g. "bExecute"."""
        symbol = self._control.get(member) or self._status[member]
        return self._decode(symbol.name)

    def _set(self, member: str, value) -> None:
        symbol = self._control.get(member) or self._status[member]
        self._vars[symbol.name].write(self._encode(symbol, value))

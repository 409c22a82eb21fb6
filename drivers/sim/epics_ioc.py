"""The simulated axis served as an EPICS motor record over Channel Access on loopback (caproto's server).

The axis is the simulated PLC (`drivers.sim.plc.SimPLC`) with its compensation
(`drivers.sim.compensation`), the same one the ADS machine runs: the IOC translates the motor
record's fields into the PLC's command handshake and its status back into the record's fields, so
the physics, the interferometer and the error model are the ones of the ADS machine.

Served under the prefix P (e.g. "SIM:M1"):
- the motor record P: VAL (writing it moves), RBV, DRBV, DMOV, MOVN, TDIR, HLM/LLM, DHLM/DLLM,
  LVIO, HLS/LLS, VELO, VMAX, ACCL, BDST, RDBD, STOP, SPMG, MSTA, EGU, and the record's alarm (SEVR);
- with `measure` (the simulated interferometer's reading at a time: `SimAxisPhysics.measure`), the
  laser's position as P:Laser (axis unit), posted at every scan (for a beamline's own plans; an
  axiscal campaign reads its laser on the serial line);
- axiscal's compensation table, P:Comp:Forward, P:Comp:Reverse (waveforms of
  `plc_contract.MAX_COMP_POINTS`), P:Comp:Start, P:Comp:Spacing, P:Comp:Points, P:Comp:Overrun,
  P:Comp:MaxRate, P:Comp:MaxAccel, P:Comp:Enable: the table of `protocols.plc_contract`, applied
  by the simulated controller as the simulated PLC applies it (docs/epics.md).

Time: the IOC does not run on its own clock. `scan(t)` (attach it to the SimClock after the PLC
scan and the compensation) posts the PLC's state into the record at simulated time t and returns
only when the server has taken it, so a client reading after a clock step sees that step. A write
from a client (VAL, STOP, SPMG) is handed to the PLC at once; the PLC takes it at its next scan, as
on the ADS machine. `run_free(speed)` lets the time run by itself (for clients nobody here wrote,
e.g. ophyd, that expect a motor to move without being stepped).

Faults (`drivers.sim.faults`, `campaign.faults`): `stop()`/`start()` take the CA server away and
bring it back (the disconnect); `trip_limit_switch()` stops the motor on the limit switch of its
direction of motion; `stall()` stops the motor short of its target with DMOV held at 0 and, after
`STALL_DETECT_S`, the record's problem bit and a MAJOR alarm (as a controller's stall monitor
reports it). Positions in the axis unit, times in s.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from caproto import AlarmSeverity, AlarmStatus, ChannelType, get_beacon_address_list
from caproto.asyncio.server import Context
from caproto.server import PVGroup, pvproperty

from campaign.faults import Fault
from drivers.sim.faults import FaultScheduler
from drivers.sim.interferometer import SimInterferometer
from drivers.sim.machine import SimAxisPhysics
from drivers.sim.plc import SimPLC
from protocols import plc_contract, plc_layout
from protocols.motor_record import (
    MSTA_DIRECTION,
    MSTA_DONE,
    MSTA_HOMED,
    MSTA_MINUS_LS,
    MSTA_MOVING,
    MSTA_PLUS_LS,
    MSTA_POSITION,
    MSTA_PRESENT,
    MSTA_PROBLEM,
    SPMG_GO,
    SPMG_PAUSE,
    SPMG_STOP,
)
from protocols.plc_contract import Command
from protocols.tables import ecmc

LOOPBACK = "127.0.0.1"

STALL_DETECT_S = 1.0
"""How long a stalled motor stands before the simulated controller reports the problem, s."""


_FORMATS = {"BOOL": "?", "INT": "h", "UINT": "H", "UDINT": "I", "LREAL": "d"}

_ENV_LOCK = threading.Lock()


def _not_a_beacon_failure(record: logging.LogRecord) -> bool:
    """Nobody listens for beacons on loopback (no CA repeater runs here): caproto's server logs every
    beacon that finds no listener on loopback as an error; those lines say nothing about the IOC. A
    failure to send a beacon anywhere else is let through (it would mean one was sent off loopback)."""
    if not record.getMessage().startswith("Failed to send beacon"):
        return True
    address = record.args[0] if isinstance(record.args, tuple) and record.args else None
    return not (isinstance(address, tuple) and address and address[0] == LOOPBACK)


logging.getLogger("caproto.ctx").addFilter(_not_a_beacon_failure)
logging.getLogger("caproto").addHandler(logging.NullHandler())  # a command's output keeps its own lines


def loopback_environment(port: int) -> dict[str, str]:
    """The Channel Access settings that keep a server and its clients on loopback, on UDP and TCP
    port `port` (searches, circuits), with beacons and the repeater on port + 1 of loopback."""
    return {
        "EPICS_CA_ADDR_LIST": LOOPBACK, "EPICS_CA_AUTO_ADDR_LIST": "NO", "EPICS_CA_SERVER_PORT": str(port),
        "EPICS_CA_REPEATER_PORT": str(port + 1), "EPICS_CAS_INTF_ADDR_LIST": LOOPBACK,
        "EPICS_CAS_BEACON_ADDR_LIST": LOOPBACK, "EPICS_CAS_AUTO_BEACON_ADDR_LIST": "NO",
        "EPICS_CAS_BEACON_PORT": str(port + 1), "EPICS_CAS_SERVER_PORT": str(port),
    }


def beacon_addresses() -> list[tuple[str, int]]:
    """The (host, port) a caproto server made now would send its beacons to, as this process's
    EPICS_CAS_* variables say."""
    return [(str(host), int(port)) for host, port in get_beacon_address_list()]


def free_loopback_port() -> int:
    """A port that is free on loopback for both TCP and UDP (CA searches use UDP, circuits TCP)."""
    for _ in range(64):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as tcp:
            tcp.bind((LOOPBACK, 0))
            port = int(tcp.getsockname()[1])
            if port > 65000:
                continue
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
                try:
                    udp.bind((LOOPBACK, port))
                except OSError:
                    continue
            return port
    raise OSError("no free loopback port for the simulated IOC")


@contextlib.contextmanager
def environment(values: dict[str, str]) -> Iterator[None]:
    """Set `values` in os.environ while a caproto context reads them (caproto reads the EPICS_*
    variables when a context is made), then put the old ones back."""
    with _ENV_LOCK:
        saved = {key: os.environ.get(key) for key in values}
        os.environ.update(values)
        try:
            yield
        finally:
            for key, old in saved.items():
                if old is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = old


class _MotorGroup(PVGroup):
    """The PVs: the motor record and axiscal's compensation table."""

    motor = pvproperty(value=0.0, name="", record="motor", precision=4)
    comp_forward = pvproperty(value=[0.0] * plc_contract.MAX_COMP_POINTS, name=":Comp:Forward",
                              dtype=ChannelType.DOUBLE, max_length=plc_contract.MAX_COMP_POINTS)
    comp_reverse = pvproperty(value=[0.0] * plc_contract.MAX_COMP_POINTS, name=":Comp:Reverse",
                              dtype=ChannelType.DOUBLE, max_length=plc_contract.MAX_COMP_POINTS)
    comp_start = pvproperty(value=0.0, name=":Comp:Start", precision=6)
    comp_spacing = pvproperty(value=0.0, name=":Comp:Spacing", precision=6)
    comp_points = pvproperty(value=0, name=":Comp:Points", dtype=ChannelType.LONG)
    comp_overrun = pvproperty(value=0.0, name=":Comp:Overrun", precision=6)
    comp_max_rate = pvproperty(value=0.0, name=":Comp:MaxRate", precision=6)
    comp_max_accel = pvproperty(value=0.0, name=":Comp:MaxAccel", precision=6)
    comp_enable = pvproperty(value=0, name=":Comp:Enable", dtype=ChannelType.LONG)
    laser = pvproperty(value=0.0, name=":Laser", precision=7, read_only=True)

    def __init__(self, *args: Any, ioc: SimMotorIoc, **kwargs: Any) -> None:
        self.ioc = ioc
        super().__init__(*args, **kwargs)

    @motor.putter  # type: ignore[no-redef]  # caproto's decorator pattern: the putter keeps the name
    async def motor(self, instance: Any, value: float) -> float:
        return await self.ioc._request_move(float(value))


COMP_PVS = {"afForward": "comp_forward", "afReverse": "comp_reverse", "fStart": "comp_start",
            "fSpacing": "comp_spacing", "nPoints": "comp_points", "fOverrun": "comp_overrun",
            "fMaxRate": "comp_max_rate", "fMaxAccel": "comp_max_accel", "bEnable": "comp_enable"}
"""PLC compensation member -> the group's attribute serving it."""


class SimMotorIoc:
    """The simulated PLC's axis as the motor record `prefix` on loopback port `port` (0: a free one).

    low, high: the record's soft limits HLM/LLM, axis unit. velocity: VELO at the start, unit/s.
    unit: EGU. The server runs on its own thread and event loop; `close()` ends both.
    """

    def __init__(self, plc: SimPLC, prefix: str, *, low: float, high: float, velocity: float,
                 unit: str = "mm", port: int = 0, measure: Callable[[float], dict] | None = None):
        self.plc, self.prefix, self.unit = plc, prefix, unit
        self.measure = measure
        self.port = port or free_loopback_port()
        self.environment = loopback_environment(self.port)
        self._low, self._high, self._velocity = low, high, velocity
        self.group = _MotorGroup(prefix=prefix, ioc=self)
        self.fields: Any = self.group.motor.field_inst
        self._new_loop()
        self._server: asyncio.Task[None] | None = None
        self._context: Any = None
        self._t = plc.handler.time_s
        self._limit_switch = 0  # +1 / -1: the switch of that side is active
        self._stalled_at: float | None = None  # simulated time the motor stalled
        self._stall_next = False
        self._problem = False
        self._pending = False  # a move request the PLC has not shown busy for yet
        self._published: dict[str, Any] = {}
        self._lut: tuple[list[float], list[float], float] | None = None  # ecmc's encoder table
        self._free: threading.Thread | None = None
        self._free_stop = threading.Event()
        self.requests: list[tuple[float, float, str]] = []
        """Every VAL a client wrote: (simulated time s, target, what the record did: "moved" or
        "refused: ..."), for the tests' check that nothing unsafe was asked for."""
        self._call(self._setup())
        self.start()

    # --- the server ----------------------------------------------------------------------------

    def start(self) -> None:
        """Serve the PVs (again): the other side of `stop()`."""
        if self._server is not None:
            return
        async def spawn() -> asyncio.Task[None]:
            # caproto reads the EPICS_* variables twice: when the context is made and again inside
            # run(), where it makes its beacon sockets; the loopback settings stay in os.environ
            # until those sockets exist (or run() ended), or beacons would go to 255.255.255.255.
            with environment(self.environment):
                if (beacons := beacon_addresses()) and any(host != LOOPBACK for host, _ in beacons):
                    raise OSError(f"the simulated IOC would send beacons off loopback: {beacons}")
                context = self._context = Context(self.group.pvdb, interfaces=[LOOPBACK])
                context.ca_server_port = self.port
                task = asyncio.get_running_loop().create_task(context.run())
                deadline = time.monotonic() + 5.0
                while not context.beacon_socks and not task.done():
                    if time.monotonic() > deadline:
                        task.cancel()
                        raise OSError(f"the simulated IOC made no beacon socket on {LOOPBACK}")
                    await asyncio.sleep(0.001)
            return task

        server = self._server = self._call(spawn())
        deadline = time.monotonic() + 5.0
        while not self._listening():
            if server.done():
                self._call(self._wait_for(server))  # raises the server's error
            if time.monotonic() > deadline:
                raise OSError(f"the simulated IOC did not start on {LOOPBACK}:{self.port}")
            time.sleep(0.005)

    def _listening(self) -> bool:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            probe.settimeout(0.2)
            return probe.connect_ex((LOOPBACK, self.port)) == 0

    def stop(self) -> None:
        """The IOC goes off the network: the server closes its circuits and sockets (the record and
        the PLC go on). The event loop goes with it: caproto's server closes its listening socket
        under asyncio's feet, and a server started again on the same loop would never accept."""
        server, self._server = self._server, None
        if server is not None:
            server_task = server

            context = self._context

            async def cancel() -> None:
                for circuit in list(context.circuits):  # the clients see their circuits close
                    circuit.client.writer.transport.abort()
                server_task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await server_task
                await asyncio.sleep(0.05)  # asyncio closes the sockets in callbacks of its own

            self._call(cancel())
            self._end_loop()
            self._new_loop()

    def close(self) -> None:
        self.stop_free()
        self.stop()
        self._end_loop()

    @staticmethod
    async def _wait_for(task: asyncio.Task[None]) -> None:
        await task

    def _new_loop(self) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, daemon=True, name=f"ioc {self.prefix}")
        self._thread.start()

    def _end_loop(self) -> None:
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(timeout=5.0)
        if not self._thread.is_alive():
            self.loop.close()

    def _call(self, coroutine: Any) -> Any:
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(timeout=10.0)

    # --- simulated time ------------------------------------------------------------------------

    def scan(self, t: float) -> None:
        """Post the axis's state at simulated time t (s) into the record; returns once posted."""
        self._t = t
        if self._stalled_at is not None and not self._problem and t - self._stalled_at >= STALL_DETECT_S:
            self._problem = True
        self._call(self._publish())

    def run_free(self, speed: float = 1.0, step_s: float = 0.02) -> None:
        """Let simulated time run by itself at `speed` × real time, in steps of `step_s` simulated
        seconds, on a thread of its own (for clients that expect a motor to move by itself)."""
        from drivers.sim.compensation import SimCompensation

        compensation = SimCompensation(self.plc, self._t)

        def run() -> None:
            t = self._t
            while not self._free_stop.wait(step_s / speed):
                t += step_s
                self.plc.scan(t)
                compensation.tick(t)
                self.scan(t)

        self._free_stop.clear()
        self._free = threading.Thread(target=run, daemon=True, name=f"ioc {self.prefix} time")
        self._free.start()

    def stop_free(self) -> None:
        if self._free is not None:
            self._free_stop.set()
            self._free.join(timeout=5.0)
            self._free = None

    # --- faults --------------------------------------------------------------------------------

    def moving(self) -> bool:
        return self.plc.arrival_time is None and bool(self.plc.value(plc_contract.status_symbols(self.plc.axis)
                                                                     ["bBusy"].name))

    def trip_limit_switch(self) -> None:
        """The limit switch ahead of the moving motor trips: the motor stops there at once (HLS or
        LLS, the MSTA limit bit and a MAJOR alarm) until it moves away from it."""
        self._limit_switch = self.plc.last_direction
        self._drop_drive()

    def stall(self) -> None:
        """The motor stalls: it stands where it is, DMOV stays 0 (the record waits for it), and after
        STALL_DETECT_S the controller reports the problem. STOP ends the wait; SPMG Go (or a new
        move) clears the problem."""
        self._stalled_at = self._t
        self._drop_drive()

    def _drop_drive(self) -> None:
        self.plc.enabled = False  # the SimPLC stops the axis where it is
        self.plc.enabled = True

    # --- ecmc's encoder lookup table -----------------------------------------------------------

    def load_encoder_table(self, text: str, path: str = "lookup table", scale: float = 1.0) -> None:
        """Load an ecmc encoder correction file (`encoder: lookuptable: filename:`, with `scale:`) as
        ecmc does: read as ecmc's loader reads it, then applied as ecmc's encoder applies it, the
        record's position being raw − scale·value(raw) for the drive's raw position, the loop closed
        on that (protocols.tables.ecmc). FormatError for a file ecmc's loader refuses."""
        rows = ecmc.read_rows(text, path)
        self._lut = ([p for p, _ in rows], [v for _, v in rows], scale)

    def _encoder_position(self, raw: float) -> float:
        if self._lut is None:
            return raw
        positions, values, scale = self._lut
        return ecmc.apply_encoder_table(raw, positions, values, scale)

    def _raw_target(self, target: float) -> float:
        """The raw position whose corrected position is `target` (where ecmc's loop stops)."""
        raw = target
        for _ in range(50):
            miss = target - self._encoder_position(raw)
            raw += miss
            if abs(miss) < 1e-12:
                break
        return raw

    # --- the record ----------------------------------------------------------------------------

    async def _setup(self) -> None:
        f = self.fields
        f.stop.putter = self._put_stop
        f.stop_pause_move_go.putter = self._put_spmg
        for member, attr in COMP_PVS.items():
            getattr(self.group, attr).putter = self._comp_putter(member)
        position = self._encoder_position(self._status()["fActPosition"])
        await self.group.motor.write(position, verify_value=False)
        # as the motor record: VAL's control and display limits are the soft limits (ophyd reads them)
        await self.group.motor.write_metadata(lower_ctrl_limit=self._low, upper_ctrl_limit=self._high,
                                              lower_disp_limit=self._low, upper_disp_limit=self._high,
                                              units=self.unit)
        await f.user_high_limit.write(self._high)
        await f.user_low_limit.write(self._low)
        await f.dial_high_limit.write(self._high)
        await f.dial_low_limit.write(self._low)
        await f.velocity.write(self._velocity)
        await f.max_velocity.write(self.plc.max_velocity)
        await f.seconds_to_velocity.write(self._velocity / self.plc.acceleration)
        await f.engineering_units.write(self.unit)
        await f.bl_distance.write(0.0)
        await f.retry_deadband.write(1e-6)
        await f.motor_step_size.write(1e-6)
        await f.limit_violation.write(0, verify_value=False)
        await self._publish()

    def _status(self) -> dict[str, Any]:
        return {member: self.plc.value(s.name) for member, s in plc_contract.status_symbols(self.plc.axis).items()}

    async def _publish(self) -> None:
        s = self._status()
        busy = bool(s["bBusy"])
        if busy:
            self._pending = False
        stalled = self._stalled_at is not None
        done = not (busy or self._pending or stalled)
        error = bool(s["bError"]) or self._problem
        msta = MSTA_PRESENT | MSTA_POSITION | MSTA_HOMED
        msta |= MSTA_DIRECTION if self.plc.last_direction > 0 else 0
        msta |= MSTA_DONE if done else 0
        msta |= MSTA_MOVING if busy else 0
        msta |= MSTA_PROBLEM if error else 0
        msta |= MSTA_PLUS_LS if self._limit_switch > 0 else 0
        msta |= MSTA_MINUS_LS if self._limit_switch < 0 else 0
        position = self._encoder_position(float(s["fActPosition"]))
        if self.measure is not None:
            await self.group.laser.write(float(self.measure(self._t)["position"]), verify_value=False)
        values = {"user_readback_value": position, "dial_readback_value": position,
                  "done_moving_to_value": int(done), "motor_is_moving": int(busy),
                  "direction_of_travel": int(self.plc.last_direction > 0), "motor_status": msta,
                  "user_high_limit_switch": int(self._limit_switch > 0),
                  "user_low_limit_switch": int(self._limit_switch < 0)}
        for name, value in values.items():
            if self._published.get(name) != value:
                self._published[name] = value
                await getattr(self.fields, name).write(value, verify_value=False)
        if error or self._limit_switch:
            alarm = (AlarmStatus.HIGH if self._limit_switch > 0 else AlarmStatus.LOW if self._limit_switch
                     else AlarmStatus.STATE, AlarmSeverity.MAJOR_ALARM)
        else:
            alarm = (AlarmStatus.NO_ALARM, AlarmSeverity.NO_ALARM)
        if self._published.get("alarm") != alarm:
            self._published["alarm"] = alarm
            await self.group.motor.alarm.write(status=alarm[0], severity=alarm[1])
            await self.fields.current_alarm_severity.write(int(alarm[1]), verify_value=False)

    async def _request_move(self, target: float) -> float:
        """VAL was written: refuse it (LVIO, SPMG not Go, into an active limit switch) or hand it to
        the PLC. Returns what VAL holds afterwards."""
        f = self.fields
        current = float(self.group.motor.value)
        position = self._encoder_position(float(self._status()["fActPosition"]))
        low, high = f.user_low_limit.value, f.user_high_limit.value
        if not math.isfinite(target) or (high > low and not low <= target <= high):  # HLM = LLM: no limits
            await f.limit_violation.write(1, verify_value=False)
            self.requests.append((self._t, target, "refused: outside the soft limits (LVIO)"))
            return current
        await f.limit_violation.write(0, verify_value=False)
        if f.stop_pause_move_go.value not in ("Go", SPMG_GO):
            self.requests.append((self._t, target, "refused: SPMG is not Go"))
            return current
        direction = 1 if target > position else -1 if target < position else 0
        if self._limit_switch and direction == self._limit_switch:
            self.requests.append((self._t, target, "refused: into the active limit switch"))
            return current  # the record does not drive further into an active limit switch
        if direction and direction != self._limit_switch:
            self._limit_switch = 0
        self._stalled_at, self._problem = None, False
        velocity = min(float(f.velocity.value), self.plc.max_velocity)
        self._write_plc({"fPosition": self._raw_target(target), "fVelocity": velocity, "eCommand": int(Command.MOVE_ABSOLUTE),
                         "bExecute": True})
        self._pending = True
        self.requests.append((self._t, target, "moved"))
        self._published.pop("done_moving_to_value", None)
        await f.done_moving_to_value.write(0, verify_value=False)
        self._published["done_moving_to_value"] = 0
        return target

    async def _put_stop(self, instance: Any, value: int) -> int:
        if value:
            self._write_plc({"bHalt": True})
            self._pending = False
            self._stalled_at = None  # the record stops waiting for a stalled motor
        return 0

    async def _put_spmg(self, instance: Any, value: Any) -> Any:
        choice = value if isinstance(value, int) else instance.enum_strings.index(value)
        if choice in (SPMG_STOP, SPMG_PAUSE):
            self._write_plc({"bHalt": True})
            self._pending = False
            self._stalled_at = None
        elif choice == SPMG_GO:
            self._write_plc({"bReset": True})  # the controller's error reset
            self._problem = False
        return value

    def _comp_putter(self, member: str) -> Callable[[Any, Any], Any]:
        async def put(instance: Any, value: Any) -> Any:
            self._write_plc({member: value}, comp=True)
            return value
        return put

    def _write_plc(self, values: dict[str, Any], comp: bool = False) -> None:
        """Write PLC variables of this axis as the PC's ADS writes do (the PLC takes them at its next
        scan; a compensation write makes the simulated compensation read the table again)."""
        symbols = plc_contract.comp_symbols(self.plc.axis) if comp else plc_contract.control_symbols(self.plc.axis)
        with self.plc.handler.lock:
            for member, value in values.items():
                symbol = symbols[member]
                place = plc_layout.require(symbol.name)
                fmt = _FORMATS[symbol.iec_type]
                if symbol.array_length is None:
                    raw = struct.pack("<" + fmt, value)
                else:
                    items = list(value)[:symbol.array_length]
                    items += [0] * (symbol.array_length - len(items))
                    raw = struct.pack(f"<{symbol.array_length}{fmt}", *items)
                self.plc.memory[place.offset:place.offset + place.size] = raw
            self.plc.handler.writes += 1


class IocFaultScheduler(FaultScheduler):
    """The simulated machine's faults (drivers.sim.faults) on the simulated IOC, and the IOC's own:
    ca_lost (as ads_lost: the CA server goes away for duration_s), limit_switch and stall (during
    the first move at or after at_s)."""

    def __init__(self, faults: list[Fault], plc: SimPLC, ioc: SimMotorIoc, instrument: SimInterferometer,
                 physics: SimAxisPhysics) -> None:
        super().__init__(faults, plc, ioc, instrument, physics)  # type: ignore[arg-type]  # the IOC stops like the ADS server
        self.ioc = ioc

    def tick(self, t: float) -> None:
        for fault in self.faults:
            if fault.name in ("limit_switch", "stall") and not fault.fired and t >= fault.at_s \
                    and not self.ioc.moving():
                fault.at_s = t  # wait for a move
        super().tick(t)

    def _fire(self, fault: Fault, t: float) -> None:
        if fault.name == "ca_lost":
            self.log.append((t, fault.name, "injected"))
            self.ioc.stop()
        elif fault.name == "limit_switch":
            self.log.append((t, fault.name, "injected"))
            self.ioc.trip_limit_switch()
        elif fault.name == "stall":
            self.log.append((t, fault.name, "injected"))
            self.ioc.stall()
        else:
            super()._fire(fault, t)

    def _end(self, fault: Fault, t: float) -> None:
        if fault.name == "ca_lost":
            self.log.append((t, fault.name, "ended"))
            self.ioc.start()
        else:
            super()._end(fault, t)

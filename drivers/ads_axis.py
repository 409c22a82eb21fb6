"""An axis owned by a TwinCAT PLC (FB_AxiscalAxis), commanded over ADS with pyads.

The PC only writes the symbols of `protocols.plc_contract.writable_symbols(n)`: every write goes
through `AdsAxis._write`, which refuses anything else. Positions are in the axis unit (mm or deg),
velocities in axis unit/s, times in s.

Connection handling (pyads on Linux, where `Connection.open()` adds the route to the PLC and
`close()` deletes it again):
- every ADS call has a timeout (`timeout_s`);
- a read that returns None (pyads does so without an error when its port is not open) counts as a
  failed call;
- after a failed call the connection is closed (deleting the route) and a new one is opened
  (re-adding the route), and the call is tried again, up to `retries` more times with
  `retry_wait_s` between tries. Once pyads has lost the TCP connection, every call on that
  Connection fails at once, even after the PLC is back; only a new route reconnects. A call
  therefore fails after at most (retries + 1) * timeout_s + retries * retry_wait_s, and then
  raises AxisError (error_id 0).
The PLC needs a route back to this PC (set up once on the PLC, or with pyads.add_route_to_plc).
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from typing import Any, TypeVar

import pyads

from drivers.halting import HaltsOnClose
from protocols import plc_contract
from protocols.hardware import AxisError, AxisStatus
from protocols.plc_contract import Command, CompTable, Symbol

T = TypeVar("T")

TWINCAT3_PLC_PORT = 851
"""AMS port of the first PLC runtime of TwinCAT 3."""

_PLC_TYPES = {
    "BOOL": pyads.PLCTYPE_BOOL,
    "INT": pyads.PLCTYPE_INT,
    "UINT": pyads.PLCTYPE_UINT,
    "UDINT": pyads.PLCTYPE_UDINT,
    "LREAL": pyads.PLCTYPE_LREAL,
}
"""IEC type name -> pyads type."""


def _plc_type(symbol: Symbol) -> Any:
    base = _PLC_TYPES[symbol.iec_type]
    return base if symbol.array_length is None else base * symbol.array_length


_STDERR_LOCK = threading.Lock()


@contextmanager
def _native_stderr_silenced() -> Iterator[None]:
    """The ADS library's C++ code logs "connection closed by remote" and failed connects to
    stderr; keep those lines out of the command's output (an error must be one line). fd 2 is
    shared by the whole process, so one redirection at a time (a lock), kept short; Python code
    writing to sys.stderr meanwhile is held back by flushing before and after."""
    with _STDERR_LOCK:
        sys.stderr.flush()
        saved = os.dup(2)
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 2)
            yield
        finally:
            time.sleep(0.01)  # the library logs from its receive thread as the socket closes
            os.dup2(saved, 2)
            os.close(saved)
            os.close(devnull)


NATIVE_LOG_LEVEL = "_ZN6Logger8logLevelE"
"""The ADS library's (Beckhoff ADS, AdsLib.so) log threshold, `Logger::logLevel`: messages below it
are not written. It logs from its receive thread ("<date> Info: connection closed by remote"), at
any moment, in its own date format; every failure it logs reaches axiscal as an ADSError anyway."""
QUIET = 4
"""Above Error (0 verbose, 1 info, 2 warning, 3 error): the library writes nothing."""


def _quiet_native_log() -> None:
    """Raise the ADS library's log threshold so that its lines never appear in a command's output
    (an error must be one line). A library without that variable (TcAdsDll on Windows) is left as it is."""
    import ctypes

    library = getattr(pyads.pyads_ex, "_adsDLL", None)
    if library is None:
        return
    try:
        ctypes.c_size_t.in_dll(library, NATIVE_LOG_LEVEL).value = QUIET
    except ValueError:  # no such symbol
        pass


class _BadAnswer(Exception):
    """A read gave None or an error text instead of a value (port not open, broken connection)."""


class AdsAxis(HaltsOnClose):
    """Axis n of `GVL_Axiscal` on the PLC at ams_net_id / ip_address (implements campaign's Axis).

    read_only: a dry run against a real PLC. Status and table reads work, every write (including
        halt and reset) raises AxisError.
    timeout_s: timeout of each ADS call, s. retries, retry_wait_s (s): see the module docstring.
    Opening the connection fails with AxisError when the PLC cannot be reached.
    """

    def __init__(
        self,
        ams_net_id: str,
        ip_address: str,
        axis: int = 1,
        ams_port: int = TWINCAT3_PLC_PORT,
        *,
        read_only: bool = False,
        timeout_s: float = 1.0,
        retries: int = 2,
        retry_wait_s: float = 0.2,
    ):
        self.axis = axis
        self.read_only = read_only
        self._address = (ams_net_id, ams_port, ip_address)
        self._hinted = False  # the causes of a PLC that does not answer are said once per axis
        _quiet_native_log()
        self._timeout_ms = max(1, round(timeout_s * 1000))
        self._retries = retries
        self._retry_wait_s = retry_wait_s
        self._control = plc_contract.control_symbols(axis)
        self._status = plc_contract.status_symbols(axis)
        self._comp = plc_contract.comp_symbols(axis)
        writable = plc_contract.writable_symbols(axis)
        self._writable = {
            s.name: s for s in (*self._control.values(), *self._comp.values()) if s.name in writable
        }
        self._connection: pyads.Connection | None = None
        self._streams: list[AdsPositionStream] = []
        self._closed = False
        self._call(lambda connection: None, "open the connection")

    # --- Axis --------------------------------------------------------------------------------

    def status(self) -> AxisStatus:
        """One sum read of the status symbols."""
        v = self._read_list(self._status)
        return AxisStatus(
            busy=bool(v["bBusy"]),
            done=bool(v["bDone"]),
            error=bool(v["bError"]),
            error_id=int(v["nErrorId"]),
            actual_position=float(v["fActPosition"]),
            enabled=bool(v["bEnabled"]),
            homed=bool(v["bHomed"]),
        )

    def start_move(self, position: float, velocity: float) -> None:
        """Send an absolute move to `position` (axis unit) at `velocity` (axis unit/s).

        Raises AxisError with the PLC's error id when the axis is in error (the PLC would ignore
        the move until a reset), and AxisError when the command cannot be sent.
        """
        if not (math.isfinite(position) and math.isfinite(velocity)):
            raise ValueError(f"position and velocity must be finite, got {position}, {velocity}")
        status = self.status()
        if status.error:
            raise AxisError(
                f"axis {self.axis} is in error {status.error_id:#x}; reset it first", status.error_id
            )
        self._write_member("fPosition", position)
        self._write_member("fVelocity", velocity)
        self._write_member("eCommand", int(Command.MOVE_ABSOLUTE))
        self._write_member("bExecute", False)
        self._write_member("bExecute", True)

    def halt(self) -> None:
        """Ask for a controlled stop (bHalt). Harmless when the axis is at rest."""
        self._write_member("bHalt", True)

    def reset(self) -> None:
        """Ask the PLC to clear the axis error (bReset)."""
        self._write_member("bReset", True)

    def stream_positions(self, cycle_s: float = 0.0, max_delay_s: float = 0.05) -> AdsPositionStream:
        """The controller's actual position (fActPosition) as ADS device notifications: sampled by
        the PLC every `cycle_s` (0: every PLC cycle), each sample stamped with the PLC's time and
        sent at most `max_delay_s` later. Read them with `take()`; `close()` ends the notification
        (so does closing the axis). A reconnection ends it too: a scan that loses the connection
        stops (AxisError from `take`)."""
        if self._connection is None:
            self._call(lambda connection: None, "open the connection")
        connection = self._connection
        if connection is None:
            raise AxisError(f"axis {self.axis}: no connection to stream the position on")
        stream = AdsPositionStream(self, connection, self._status["fActPosition"].name, cycle_s, max_delay_s)
        self._streams.append(stream)
        return stream

    def close(self) -> None:
        """End the position streams, then close as every controller axis does (HaltsOnClose)."""
        if not self._closed:
            for stream in list(self._streams):
                stream.close()
        super().close()

    # --- compensation tables -----------------------------------------------------------------

    def write_comp_table(self, table: CompTable) -> None:
        """Write GVL_Axiscal.astComp[n], read it back and compare; then enable it if asked.

        The PLC's bEnable is cleared first, so a half-written table is never applied.
        Raises AxisError when the read-back differs.
        """
        pad = [0.0] * (plc_contract.MAX_COMP_POINTS - table.points)
        self._write_member("bEnable", False)
        self._write_member("afForward", list(table.forward) + pad)
        self._write_member("afReverse", list(table.reverse) + pad)
        self._write_member("fStart", table.start)
        self._write_member("fSpacing", table.spacing)
        self._write_member("nPoints", table.points)
        self._write_member("fOverrun", table.overrun)
        self._write_member("fMaxRate", table.max_rate)
        self._write_member("fMaxAccel", table.max_accel)
        stored = self.read_comp_table()
        if stored != replace(table, enabled=False):
            raise AxisError(
                f"compensation table of axis {self.axis} reads back different from what was written"
            )
        if table.enabled:
            self._write_member("bEnable", True)
            if self.read_comp_table() != table:
                raise AxisError(f"compensation table of axis {self.axis} did not stay as written")

    def read_comp_table(self) -> CompTable | None:
        """GVL_Axiscal.astComp[n] in one sum read; None when the PLC holds no table (nPoints 0)."""
        v = self._read_list(self._comp)
        points = int(v["nPoints"])
        if points == 0:
            return None
        try:
            return CompTable(
                forward=tuple(v["afForward"][:points]),
                reverse=tuple(v["afReverse"][:points]),
                start=v["fStart"],
                spacing=v["fSpacing"],
                overrun=v["fOverrun"],
                max_rate=v["fMaxRate"],
                max_accel=v["fMaxAccel"],
                enabled=bool(v["bEnable"]),
            )
        except ValueError as e:
            raise AxisError(f"the PLC holds an invalid compensation table for axis {self.axis}: {e}") from e

    # --- ADS ---------------------------------------------------------------------------------

    def _write_member(self, member: str, value: Any) -> None:
        symbol = self._control.get(member) or self._comp[member]
        self._write(symbol.name, value)

    def _write(self, name: str, value: Any) -> None:
        """The only way anything is written to the PLC."""
        symbol = self._writable.get(name)
        if symbol is None:
            raise ValueError(f"{name} is not a symbol the PC may write for axis {self.axis}")
        if self.read_only:
            raise AxisError(f"read-only connection: refusing to write {name}")
        plc_type = _plc_type(symbol)
        self._call(lambda connection: connection.write_by_name(name, value, plc_type), f"write {name}")

    def _read_list(self, symbols: dict[str, Symbol]) -> dict[str, Any]:
        """Sum read of `symbols`, keyed by member name."""
        names = [s.name for s in symbols.values()]

        def read(connection: pyads.Connection) -> dict[str, Any]:
            values = connection.read_list_by_name(names)
            if values is None:
                raise _BadAnswer("no answer")
            for name in names:
                if values.get(name) is None or isinstance(values[name], str):
                    raise _BadAnswer(f"{name}: {values.get(name)!r}")
            return values

        values = self._call(read, "status read" if symbols is self._status else "table read")
        return {member: values[s.name] for member, s in symbols.items()}

    def _call(self, action: Callable[[pyads.Connection], T], what: str) -> T:
        """Run `action` on the connection; on failure reconnect and retry (bounded)."""
        if self._closed:
            raise AxisError(f"axis {self.axis}: connection closed")
        error: Exception | None = None
        for attempt in range(self._retries + 1):
            if attempt:
                time.sleep(self._retry_wait_s)
            try:
                if self._connection is None:
                    with _native_stderr_silenced():  # the library logs every failed connect
                        self._connect()
                        result = action(self._connection)
                else:
                    result = action(self._connection)
                self._hinted = False  # it answers again: a later loss is said in full
                return result
            except (pyads.ADSError, _BadAnswer) as e:
                error = e
                self._disconnect()
        raise AxisError(
            f"axis {self.axis}: {what} failed {self._retries + 1} times, last: {str(error).strip().rstrip('.')}; "
            f"{self._where(error)}"
        ) from error

    def _where(self, error: Exception | None) -> str:
        """Where axiscal looked for the PLC, and what usually keeps it from answering: said in full
        the first time, then only where (a link that stays down fails every read: one long hint for
        each would bury the messages)."""
        net_id, port, ip = self._address
        if self._hinted:
            return f"PLC at IP {ip}, AMS Net ID {net_id}, port {port}: still not answering (the likely causes as said before)"
        self._hinted = True
        code: int = getattr(error, "err_code", None) or 0
        likely = {6: "the PLC runtime is not in RUN, or ams_port is wrong",
                  7: "there is no ADS route between this PC and the PLC (add it on both sides)",
                  1861: "no answer in time: check the cable, the IP address and the network"}.get(code, "")
        return (f"PLC at IP {ip}, AMS Net ID {net_id}, port {port}: "
                + (f"most likely {likely}; " if likely else "")
                + "the usual causes are a missing ADS route, the PLC not in RUN, and the network cable")

    def _connect(self) -> None:
        connection = pyads.Connection(*self._address)
        connection.open()
        try:
            connection.set_timeout(self._timeout_ms)
        except pyads.ADSError:
            connection.close()
            raise
        self._connection = connection

    def _disconnect(self) -> None:
        for stream in list(self._streams):
            stream.lost()
        connection, self._connection = self._connection, None
        if connection is not None:
            try:
                with _native_stderr_silenced():
                    connection.close()
            except pyads.ADSError:
                pass


KEPT_CALLBACKS: list[object] = []
"""The native callbacks of deleted notifications, kept for the process's life (one small object per
stream opened). pyads frees a notification's callback as soon as it is deleted, but the ADS library's
dispatch thread may be inside that callback then: it would return into freed code (a segfault, seen
about once in 200 streams ended by a lost connection)."""

FILETIME_AT_UNIX_EPOCH = 116_444_736_000_000_000
"""100-ns intervals from 1601-01-01 (a FILETIME's origin, the stamps of ADS notifications) to 1970-01-01."""


class AdsPositionStream:
    """One ADS device notification of the axis's actual position (see `AdsAxis.stream_positions`).

    The ADS library calls `_received` on its own thread, once per sample; `take` hands the samples
    over: (the PLC's time of the sample, s since 1970 from its FILETIME stamp, actual position in
    axis unit), in the order the PLC took them."""

    def __init__(self, axis: AdsAxis, connection: pyads.Connection, name: str, cycle_s: float,
                 max_delay_s: float) -> None:
        import ctypes

        self._axis, self._connection = axis, connection
        self._lock = threading.Lock()
        self._samples: list[tuple[float, float]] = []
        self._lost = False
        self._data_offset = pyads.structs.SAdsNotificationHeader.data.offset
        self._double = ctypes.POINTER(ctypes.c_double)
        attr = pyads.NotificationAttrib(8, trans_mode=pyads.constants.ADSTRANS_SERVERCYCLE,
                                        max_delay=max(0.0, max_delay_s * 1000.0), cycle_time=max(0.0, cycle_s * 1000.0))
        try:
            handles = connection.add_device_notification(name, attr, self._received)
        except pyads.ADSError as exc:
            raise AxisError(f"axis {axis.axis}: cannot stream {name}: {str(exc).strip()}") from exc
        if handles is None:
            raise AxisError(f"axis {axis.axis}: cannot stream {name}: no notification handle")
        self._handles: tuple[int, int] | None = handles
        self._callback = [c for (_, handle), c in pyads.pyads_ex.callback_store.items() if handle == handles[0]]

    def _received(self, notification: Any, _name: str) -> None:
        import ctypes

        header = notification.contents
        value = ctypes.cast(ctypes.addressof(header) + self._data_offset, self._double).contents.value
        stamp_s = (int(header.nTimeStamp) - FILETIME_AT_UNIX_EPOCH) / 10_000_000
        with self._lock:
            self._samples.append((stamp_s, float(value)))

    def take(self) -> list[tuple[float, float]]:
        """The samples received since the last call, oldest first. AxisError after the connection
        was lost (the notification is gone with it)."""
        with self._lock:
            samples, self._samples = self._samples, []
        if self._lost and not samples:
            raise AxisError(f"axis {self._axis.axis}: the position stream ended with the connection", 0)
        return samples

    def lost(self) -> None:
        """The connection it came on is about to close: delete the notification while it may still
        be open (the ADS library must call no callback after), no more samples."""
        self.close()
        self._lost = True

    def close(self) -> None:
        """Delete the notification (before the connection closes: the library calls no callback after)."""
        handles, self._handles = self._handles, None
        if self in self._axis._streams:
            self._axis._streams.remove(self)
        if handles is not None:
            KEPT_CALLBACKS.extend(self._callback)
            try:
                self._connection.del_device_notification(*handles)
            except pyads.ADSError:
                pass

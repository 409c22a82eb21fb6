"""An axis behind an EPICS motor record, over Channel Access with caproto's threading client.

The motor record's own fields do everything (reference: docs/epics.md):

- a move writes VELO, then VAL (no put-callback: on a motor record that completes only when the
  motion does); the record then shows DMOV 0 until it is done;
- `status()` reads DMOV, MOVN, MSTA and RBV with its alarm severity (and HLS, LLS when the record is
  in MAJOR alarm);
- `halt()` writes STOP = 1; `reset()` writes SPMG = Go (clears a Stop or Pause, and on the
  simulated IOC the controller's error);
- the soft limits HLM/LLM are read when the axis is opened, the config's limits must lie inside
  them (else InputError, before anything moves), and every target is checked against the record's
  limits of the moment before VAL is written (a record with HLM = LLM has its soft limits switched
  off, as the motor record has it: then the config's limits, checked before every move, are the
  only ones); BDST (the record's own backlash take-out) must be 0,
  since a bidirectional ISO 230-2 test measures the reversal the record would hide.

Faults, mapped onto the executor's one fault policy as the ADS axis maps its own:

| what the record shows | AxisStatus / exception | the executor |
|---|---|---|
| no answer within timeout_s, a disconnected channel, MSTA comm-error bit, alarm status COMM | AxisError, error_id 0 | waits for the connection (`reconnect_s`), then retries or skips |
| the MSTA limit bits, or HLS/LLS with the record in alarm | error, error_id `LIMIT_SWITCH` | halts, resets, retries from the overrun (which moves away) |
| MSTA problem bit (a drive or stall fault the controller reports) | error, error_id `PROBLEM` | halts, resets, retries |
| alarm severity MAJOR or INVALID with none of the above | error, error_id `ALARM` | halts, resets, retries |
| a stall the controller does not report (DMOV stays 0) | busy | `move_timeout_s`, then as a fault |

Positions in the record's user coordinates (EGU: the axis unit), velocities in EGU/s, times in s.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import replace
from typing import Any

from caproto import AlarmSeverity, AlarmStatus
from caproto.threading.client import PV, Context

from campaign.errors import InputError
from drivers.halting import HaltsOnClose
from protocols import plc_contract
from protocols.hardware import AxisError, AxisStatus
from protocols.motor_record import (
    MSTA_COMM_ERR,
    MSTA_HOMED,
    MSTA_MINUS_LS,
    MSTA_PLUS_LS,
    MSTA_PROBLEM,
    SPMG_GO,
)
from protocols.plc_contract import CompTable

LIMIT_SWITCH = 0xE001
"""error_id: the record shows a limit switch (HLS, LLS or the MSTA limit bits)."""
PROBLEM = 0xE002
"""error_id: the record's MSTA problem bit (the controller reports a drive fault or a stall)."""
ALARM = 0xE003
"""error_id: the record is in MAJOR or INVALID alarm for another reason."""
REFUSED = 0xE004
"""error_id: the record refused a move (LVIO, or a target outside HLM/LLM)."""


RECORD_FIELDS = ("DMOV", "MOVN", "RBV", "MSTA", "HLS", "LLS", "VAL", "VELO", "HLM", "LLM", "STOP", "SPMG", "BDST", "LVIO", "EGU")
COMP_PVS = {"afForward": ":Comp:Forward", "afReverse": ":Comp:Reverse", "fStart": ":Comp:Start",
            "fSpacing": ":Comp:Spacing", "nPoints": ":Comp:Points", "fOverrun": ":Comp:Overrun",
            "fMaxRate": ":Comp:MaxRate", "fMaxAccel": ":Comp:MaxAccel", "bEnable": ":Comp:Enable"}
"""The compensation table's PVs under the record's prefix (served by the simulated IOC; a real IOC
serves them only where its database and controller logic provide them, docs/epics.md)."""

UNIT_NAMES = {"mm": {"mm"}, "deg": {"deg", "degree", "degrees", "°"}}
"""The EGU spellings a motor record may use for each axis unit (compared in lower case)."""
MOVE_ACCEPT_S = 0.5
"""How long start_move waits for the record to show the move (DMOV 0), real s."""


class EpicsAxis(HaltsOnClose):
    """The motor record `prefix` (e.g. "SIM:M1"), found by Channel Access as EPICS_CA_ADDR_LIST etc.
    say (implements protocols.hardware.Axis).

    limits: the config's soft limits (low, high), axis unit: InputError when they reach beyond the
        record's LLM/HLM. unit: the config's axis unit ("mm", "deg"): InputError when the record's
        EGU names another one. read_only: a dry run: reads work, every write raises AxisError.
    timeout_s: how long each Channel Access read or write may take, real s.
    AxisError (error_id 0) when the record does not answer when opened.
    """

    def __init__(self, prefix: str, *, limits: tuple[float, float] | None = None, read_only: bool = False,
                 timeout_s: float = 2.0, where: str = "", unit: str | None = None):
        self.prefix = prefix
        self.read_only = read_only
        self.timeout_s = timeout_s
        self._where = where or "config"
        self._context = Context()
        self._closed = False
        self._comp: dict[str, PV] | None = None
        try:
            names = [f"{prefix}.{field}" for field in RECORD_FIELDS]
            pvs = self._context.get_pvs(*names, timeout=timeout_s)
            self._pv = dict(zip(RECORD_FIELDS, pvs))
            for pv in pvs:
                try:
                    pv.wait_for_connection(timeout=timeout_s)
                except TimeoutError:
                    raise AxisError(f"motor record {prefix}: {pv.name} did not connect within {timeout_s:g} s; "
                                    "check the IOC is running and EPICS_CA_ADDR_LIST reaches it", 0) from None
            self._check_record(limits, unit)
        except BaseException:
            self._disconnect()
            raise

    # --- Axis --------------------------------------------------------------------------------

    def status(self) -> AxisStatus:
        done, moving, msta = (int(self._read(field)) for field in ("DMOV", "MOVN", "MSTA"))
        position, severity, alarm = self._read_with_severity("RBV")
        if msta & MSTA_COMM_ERR or alarm == AlarmStatus.COMM:
            # the motor record raises COMM_ALARM (INVALID) for the controller's comm error and clears
            # the MSTA bit as it does: either one means the controller is out of reach
            raise AxisError(f"motor record {self.prefix}: the IOC lost its controller (MSTA comm error or "
                            "COMM alarm)", 0)
        alarmed = severity >= AlarmSeverity.MAJOR_ALARM
        # The MSTA limit bits come from the controller and are always there. A switch raises the
        # record's HIGH/LOW alarm only with severity HLSV, which a database may leave at NO_ALARM:
        # HLS/LLS are read as a second source when the record is in alarm (the simulated IOC sets
        # HLSV's equivalent to MAJOR).
        switches = alarmed and bool(self._read("HLS") or self._read("LLS"))
        limit = switches or bool(msta & (MSTA_PLUS_LS | MSTA_MINUS_LS))
        problem = bool(msta & MSTA_PROBLEM)
        error_id = LIMIT_SWITCH if limit else PROBLEM if problem else ALARM if alarmed else 0
        return AxisStatus(busy=bool(moving or not done), done=bool(done and not moving), error=error_id != 0,
                          error_id=error_id, actual_position=position, enabled=not problem,
                          homed=bool(msta & MSTA_HOMED))

    def start_move(self, position: float, velocity: float) -> None:
        """VELO, then VAL. AxisError (nothing written) when the record is in error (except on a limit
        switch, for a move away from it), the target lies outside its HLM/LLM of the moment, or when
        it refuses the move (LVIO)."""
        if not (math.isfinite(position) and math.isfinite(velocity)):
            raise ValueError(f"position and velocity must be finite, got {position}, {velocity}")
        self._refuse_writes("a move")
        low, high = self._read("LLM"), self._read("HLM")
        if high > low and not low <= position <= high:  # HLM = LLM: the record has no soft limits
            raise AxisError(f"motor record {self.prefix}: {position:g} lies outside its soft limits "
                            f"[{low:g}, {high:g}]; not moved", REFUSED)
        status = self.status()
        if status.error and not self._away_from_switch(status, position):
            raise AxisError(f"motor record {self.prefix} is in error {status.error_id:#x}; reset it first",
                            status.error_id)
        self._write("VELO", velocity, notify=True)
        self._write("VAL", position, notify=False)
        deadline = time.monotonic() + MOVE_ACCEPT_S
        while True:
            if self._read("LVIO"):
                raise AxisError(f"motor record {self.prefix} refused the move to {position:g} (LVIO)", REFUSED)
            if not self._read("DMOV") or time.monotonic() > deadline:
                return

    def _away_from_switch(self, status: AxisStatus, position: float) -> bool:
        """The record shows only a limit switch, and `position` lies on the side away from it (the
        one move a motor record lets an axis make off a switch)."""
        if status.error_id != LIMIT_SWITCH:
            return False
        msta = int(self._read("MSTA"))
        plus = bool(self._read("HLS")) or bool(msta & MSTA_PLUS_LS)
        minus = bool(self._read("LLS")) or bool(msta & MSTA_MINUS_LS)
        return (plus and not minus and position < status.actual_position) or \
            (minus and not plus and position > status.actual_position)

    def halt(self) -> None:
        self._refuse_writes("STOP")
        self._write("STOP", 1, notify=True)

    def reset(self) -> None:
        self._refuse_writes("SPMG")
        self._write("SPMG", SPMG_GO, notify=True)

    def _disconnect(self) -> None:
        """End the Channel Access context. caproto's disconnect closes the circuits first, then joins
        its threads, which end only at their next poll (up to 1.5 s after a campaign, measured):
        that wait runs on a daemon thread of its own, so closing the axis does not wait for it."""
        threading.Thread(target=self._context.disconnect, name=f"epics {self.prefix} disconnect", daemon=True).start()

    # --- compensation ------------------------------------------------------------------------

    def write_comp_table(self, table: CompTable) -> None:
        """Write the table into P:Comp:* (disabled first), read it back and compare, then enable it
        when asked. AxisError when the IOC has no such PVs or the read-back differs."""
        self._refuse_writes("the compensation table")
        pvs = self._comp_pvs()
        pad = [0.0] * (plc_contract.MAX_COMP_POINTS - table.points)
        self._put(pvs["bEnable"], 0)
        self._put(pvs["afForward"], list(table.forward) + pad)
        self._put(pvs["afReverse"], list(table.reverse) + pad)
        for member, value in (("fStart", table.start), ("fSpacing", table.spacing), ("nPoints", table.points),
                              ("fOverrun", table.overrun), ("fMaxRate", table.max_rate),
                              ("fMaxAccel", table.max_accel)):
            self._put(pvs[member], value)
        if self.read_comp_table() != replace(table, enabled=False):
            raise AxisError(f"motor record {self.prefix}: the compensation table reads back different from what "
                            "was written")
        if table.enabled:
            self._put(pvs["bEnable"], 1)
            if self.read_comp_table() != table:
                raise AxisError(f"motor record {self.prefix}: the compensation table did not stay as written")

    def read_comp_table(self) -> CompTable | None:
        """The table in P:Comp:*, None when it holds none (Points 0)."""
        pvs = self._comp_pvs()
        v = {member: self._get(pv) for member, pv in pvs.items()}
        points = int(v["nPoints"][0])
        if points == 0:
            return None
        try:
            return CompTable(forward=tuple(float(x) for x in v["afForward"][:points]),
                             reverse=tuple(float(x) for x in v["afReverse"][:points]),
                             start=float(v["fStart"][0]), spacing=float(v["fSpacing"][0]),
                             overrun=float(v["fOverrun"][0]), max_rate=float(v["fMaxRate"][0]),
                             max_accel=float(v["fMaxAccel"][0]), enabled=bool(v["bEnable"][0]))
        except ValueError as e:
            raise AxisError(f"motor record {self.prefix}: the IOC holds an invalid compensation table: {e}") from e

    def _comp_pvs(self) -> dict[str, PV]:
        if self._comp is None:
            names = [self.prefix + suffix for suffix in COMP_PVS.values()]
            pvs = self._context.get_pvs(*names, timeout=self.timeout_s)
            for pv in pvs:
                try:
                    pv.wait_for_connection(timeout=self.timeout_s)
                except TimeoutError:
                    raise AxisError(
                        f"motor record {self.prefix}: no compensation table PVs ({pv.name} does not answer): this "
                        "IOC takes its correction from its own configuration (for ecmc: axiscal compensate "
                        "--format ecmc, docs/epics.md)") from None
            self._comp = dict(zip(COMP_PVS, pvs))
        return self._comp

    # --- Channel Access ----------------------------------------------------------------------

    def _check_record(self, limits: tuple[float, float] | None, unit: str | None) -> None:
        if unit is not None:
            data = self._get(self._pv["EGU"])  # a DBF_STRING: [b"mm"]
            first = data[0] if len(data) else b""
            egu = (first.decode("latin-1") if isinstance(first, bytes) else str(first)).strip("\x00 ")
            if egu.lower() not in UNIT_NAMES.get(unit, {unit.lower()}):
                raise InputError(f"{self._where}: key 'axis.unit': '{unit}', but the motor record {self.prefix}'s "
                                 f"EGU is '{egu[:20]}'; positions would be read in the wrong unit: make them agree")
        low, high = self._read("LLM"), self._read("HLM")
        if limits is not None and high > low and not (low <= limits[0] and limits[1] <= high):
            raise InputError(f"{self._where}: axis soft limits [{limits[0]:g}, {limits[1]:g}] reach beyond the motor "
                             f"record {self.prefix}'s LLM/HLM [{low:g}, {high:g}]")
        backlash = self._read("BDST")
        if backlash != 0:
            raise InputError(f"{self._where}: motor record {self.prefix} has BDST = {backlash:g}: it takes out the "
                             "backlash itself, which hides the reversal error a bidirectional test measures; set "
                             "BDST = 0 for the campaign")

    def _refuse_writes(self, what: str) -> None:
        if self._closed:
            raise AxisError(f"motor record {self.prefix}: connection closed")
        if self.read_only:
            raise AxisError(f"read-only connection: refusing to write {what}")

    def _read(self, field: str) -> float:
        return float(self._get(self._pv[field])[0])

    def _read_with_severity(self, field: str) -> tuple[float, int, int]:
        """The field's value, its alarm severity and its alarm status."""
        pv = self._pv[field]
        if self._closed:
            raise AxisError(f"motor record {self.prefix}: connection closed")
        try:
            reading = pv.read(data_type="status", timeout=self.timeout_s)
        except (TimeoutError, OSError) as exc:
            raise self._lost(pv, exc) from None
        return float(reading.data[0]), int(reading.metadata.severity), int(reading.metadata.status)

    def _get(self, pv: PV) -> Any:
        if self._closed:
            raise AxisError(f"motor record {self.prefix}: connection closed")
        try:
            return pv.read(timeout=self.timeout_s).data
        except (TimeoutError, OSError) as exc:
            raise self._lost(pv, exc) from None

    def _write(self, field: str, value: float, *, notify: bool) -> None:
        self._put(self._pv[field], value, notify=notify)

    def _put(self, pv: PV, value: Any, *, notify: bool = True) -> None:
        data = value if isinstance(value, list) else [value]
        try:
            pv.write(data, wait=notify, notify=notify, timeout=self.timeout_s)
        except (TimeoutError, OSError) as exc:
            raise self._lost(pv, exc) from None
        except Exception as exc:  # noqa: BLE001 - the server's refusal comes as caproto's own errors
            raise AxisError(f"motor record {self.prefix}: writing {pv.name} failed: {exc}") from None

    def _lost(self, pv: PV, exc: BaseException) -> AxisError:
        return AxisError(f"motor record {self.prefix}: {pv.name} gave no answer within {self.timeout_s:g} s "
                         f"({type(exc).__name__}); the IOC or the network is down, or EPICS_CA_ADDR_LIST does not "
                         "reach it", 0)

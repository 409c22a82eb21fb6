"""The PLC symbol contract between axiscal and a TwinCAT PLC, as plain data (no I/O, no pyads).

The PLC side is `protocols/st/`: the GVL `GVL_Axiscal` holds, per axis n = 1..MAX_AXES,

- `astAxes[n].stControl`: written by the PC to command the axis (see `control_symbols`);
- `astAxes[n].stStatus`: written by the PLC, read by the PC (see `status_symbols`);
- `astComp[n]`: compensation tables, written by the PC (see `comp_symbols`).

Types are IEC 61131-3 type names; drivers map them to their own (e.g. pyads PLCTYPE_*).
Units: positions in the axis unit (mm for a linear axis, deg for a rotary axis), velocities in
axis unit/s, accelerations in axis unit/s², correction values in axis unit.

Command handshake: the PC writes fPosition, fVelocity and eCommand, then bExecute FALSE and TRUE.
The PLC takes the command when it sees bExecute TRUE and clears bExecute itself, so every command
the PC sends is taken exactly once, even when the PC's FALSE write falls between two PLC cycles.
bHalt and bReset are single requests handled the same way (the PLC clears them once taken).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

GVL = "GVL_Axiscal"
MAX_AXES = 4
"""Axes the GVL has room for: n = 1..MAX_AXES."""
MAX_COMP_POINTS = 256
"""Length of each compensation table array (indices 0..MAX_COMP_POINTS-1)."""


class Command(IntEnum):
    """`E_AxiscalCommand` (an INT enum): what a rising edge on bExecute asks for."""

    NONE = 0
    MOVE_ABSOLUTE = 1
    """Absolute move to fPosition at fVelocity."""
    HALT = 2
    """Controlled stop with the axis deceleration; the same as bHalt."""
    RESET = 3
    """Clear an axis error; the same as bReset."""


class PlcErrorId(IntEnum):
    """axiscal's own error ids for commands the PLC refuses (nErrorId). NC errors keep their own
    ids (16#4000..16#4FFF); these are outside that range. Mirrored as constants in GVL_Axiscal."""

    NOT_ENABLED = 0x8001
    """A move was commanded while the drive is not enabled."""
    INVALID_VELOCITY = 0x8002
    """fVelocity <= 0 or above the FB's fMaxVelocity."""
    UNKNOWN_COMMAND = 0x8003
    """bExecute with an eCommand value that is not in E_AxiscalCommand."""


ERROR_ID_CONSTANTS = {
    "nErrNotEnabled": PlcErrorId.NOT_ENABLED,
    "nErrInvalidVelocity": PlcErrorId.INVALID_VELOCITY,
    "nErrUnknownCommand": PlcErrorId.UNKNOWN_COMMAND,
}
"""The GVL_Axiscal constant that holds each PlcErrorId."""


@dataclass(frozen=True)
class Symbol:
    """One PLC variable.

    name: the full ADS symbol name, e.g. "GVL_Axiscal.astAxes[1].stControl.fPosition".
    iec_type: the IEC type the value travels as: BOOL, INT, UINT, UDINT or LREAL (for an array,
        the element type). eCommand is declared as E_AxiscalCommand, an INT enum.
    unit: the unit of the value ("" for flags, ids and counts).
    array_length: number of elements (index 0..array_length-1) for an array, None for a scalar.
    """

    name: str
    iec_type: str
    unit: str = ""
    array_length: int | None = None

    @property
    def member(self) -> str:
        """The last part of the name, e.g. "fPosition"."""
        return self.name.rsplit(".", 1)[1]


def _check_axis(n: int) -> None:
    if not 1 <= n <= MAX_AXES:
        raise ValueError(f"axis number must be 1..{MAX_AXES}, got {n}")


def _symbols(prefix: str, members: tuple[tuple, ...]) -> dict[str, Symbol]:
    return {m[0]: Symbol(f"{prefix}.{m[0]}", *m[1:]) for m in members}


_CONTROL = (
    ("eCommand", "INT"),  # E_AxiscalCommand, see Command
    ("fPosition", "LREAL", "axis unit"),  # target of MOVE_ABSOLUTE
    ("fVelocity", "LREAL", "axis unit/s"),  # velocity of MOVE_ABSOLUTE, > 0
    ("bExecute", "BOOL"),  # PC: FALSE then TRUE to send eCommand; PLC clears it when taken
    ("bHalt", "BOOL"),  # PC: TRUE for a controlled stop; PLC clears it when taken
    ("bReset", "BOOL"),  # PC: TRUE to clear an axis error; PLC clears it when taken
)

_STATUS = (
    ("bBusy", "BOOL"),  # a move or a halt is in progress
    ("bDone", "BOOL"),  # the last move reached its target (FALSE after a halt or an error)
    ("bError", "BOOL"),  # an error is latched until a reset
    ("nErrorId", "UDINT"),  # the first error's id (NC error id or PlcErrorId), 0 when none
    ("fActPosition", "LREAL", "axis unit"),  # the NC's actual position
    ("bEnabled", "BOOL"),  # the drive is powered (MC_Power.Status)
    ("bHomed", "BOOL"),  # the axis is referenced
)

_COMP = (
    # correction value at point i (position fStart + i * fSpacing), axis unit; valid for
    # i < nPoints. afForward applies when moving in the positive direction, afReverse negative.
    ("afForward", "LREAL", "axis unit", MAX_COMP_POINTS),
    ("afReverse", "LREAL", "axis unit", MAX_COMP_POINTS),
    ("fStart", "LREAL", "axis unit"),  # position of point 0
    ("fSpacing", "LREAL", "axis unit"),  # distance between neighbouring points, > 0
    ("nPoints", "UINT"),  # number of valid points, 2..MAX_COMP_POINTS
    ("fOverrun", "LREAL", "axis unit"),  # L1: beyond either end the correction fades to 0 over this length
    ("fMaxRate", "LREAL", "axis unit/s"),  # rate limit of the applied correction
    ("fMaxAccel", "LREAL", "axis unit/s²"),  # acceleration limit of the applied correction
    ("bEnable", "BOOL"),  # apply the tables
)


def control_symbols(n: int) -> dict[str, Symbol]:
    """The command symbols of axis n (PC writes), keyed by member name (e.g. "fPosition")."""
    _check_axis(n)
    return _symbols(f"{GVL}.astAxes[{n}].stControl", _CONTROL)


def status_symbols(n: int) -> dict[str, Symbol]:
    """The status symbols of axis n (PLC writes, PC reads), keyed by member name."""
    _check_axis(n)
    return _symbols(f"{GVL}.astAxes[{n}].stStatus", _STATUS)


def comp_symbols(n: int) -> dict[str, Symbol]:
    """The compensation-table symbols of axis n (PC writes), keyed by member name."""
    _check_axis(n)
    return _symbols(f"{GVL}.astComp[{n}]", _COMP)


def writable_symbols(n: int) -> frozenset[str]:
    """Names of every symbol the PC may ever write for axis n: control and compensation only."""
    return frozenset(s.name for s in (*control_symbols(n).values(), *comp_symbols(n).values()))


@dataclass(frozen=True)
class CompTable:
    """The content of `GVL_Axiscal.astComp[n]`.

    forward, reverse: correction values, axis unit, one per point, equal lengths 2..MAX_COMP_POINTS
        (point i is at start + i * spacing). Stored zero-padded to MAX_COMP_POINTS in the PLC.
    start: position of point 0, axis unit. spacing: distance between points, axis unit, > 0.
    overrun: end-zone length L1 over which the correction fades to 0, axis unit, >= 0.
    max_rate: rate limit of the applied correction, axis unit/s, > 0.
    max_accel: acceleration limit of the applied correction, axis unit/s², > 0.
    enabled: the PLC applies the tables.
    """

    forward: tuple[float, ...]
    reverse: tuple[float, ...]
    start: float
    spacing: float
    overrun: float
    max_rate: float
    max_accel: float
    enabled: bool = False

    def __post_init__(self) -> None:
        if len(self.forward) != len(self.reverse):
            raise ValueError("forward and reverse tables must have the same length")
        if not 2 <= len(self.forward) <= MAX_COMP_POINTS:
            raise ValueError(f"a table needs 2..{MAX_COMP_POINTS} points, got {len(self.forward)}")
        if self.spacing <= 0:
            raise ValueError("spacing must be > 0")
        if self.overrun < 0 or self.max_rate <= 0 or self.max_accel <= 0:
            raise ValueError("overrun must be >= 0, max_rate and max_accel > 0")
        object.__setattr__(self, "forward", tuple(float(v) for v in self.forward))
        object.__setattr__(self, "reverse", tuple(float(v) for v in self.reverse))

    @property
    def points(self) -> int:
        """Number of valid points (nPoints)."""
        return len(self.forward)

"""Where each variable of `GVL_Axiscal` lies in PLC memory, as TwinCAT 3 lays it out (pure data).

TwinCAT 3 on x86/x64 packs structures with pack mode 8: a member starts at a multiple of
min(its alignment, 8), where the alignment of an elementary type is its size and that of a
structure or array the largest alignment among its members; a structure's size is rounded up to
its alignment. The GVL's two arrays follow each other in the same way. The structures are those of
`protocols/st/` (ST_AxiscalAxis, ST_AxiscalControl, ST_AxiscalStatus, ST_AxiscalComp), their
members in `protocols.plc_contract`'s order. Offsets and sizes are in bytes.

`resolve(path)` finds any variable by its ADS name (case-insensitive, as TwinCAT's symbol names
are): the GVL's arrays, an element, a structure, a member, an array element of a member.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from protocols import plc_contract
from protocols.plc_contract import GVL, MAX_AXES, MAX_COMP_POINTS

PACK_MODE = 8
"""TwinCAT 3's default pack mode on x86/x64 (attribute 'pack_mode' := '8')."""

ELEMENTARY_SIZE = {"BOOL": 1, "INT": 2, "UINT": 2, "UDINT": 4, "LREAL": 8}
"""Size of each IEC elementary type the contract uses, bytes."""

ENUMS = {"E_AxiscalCommand": "INT"}
"""Enumerations and their base type (`protocols/st/E_AxiscalCommand.st`)."""


@dataclass(frozen=True)
class DataType:
    """A type as the PLC declares it: an elementary type (`base` is None, no members), an
    enumeration (`base` its elementary type), an array (`element` and `bounds`, inclusive) or a
    structure (`members`: (name, type, offset) in declaration order). size, align: bytes."""

    name: str
    size: int
    align: int
    base: str | None = None
    members: tuple[tuple[str, DataType, int], ...] = ()
    element: DataType | None = None
    bounds: tuple[int, int] | None = None

    @property
    def iec_base(self) -> str:
        """The elementary type a value of this type travels as (itself for an elementary type)."""
        return self.base or self.name


def elementary(name: str) -> DataType:
    size = ELEMENTARY_SIZE[name]
    return DataType(name, size, size)


def enumeration(name: str) -> DataType:
    base = elementary(ENUMS[name])
    return DataType(name, base.size, base.align, base=base.name)


def array(element: DataType, low: int, high: int) -> DataType:
    return DataType(f"ARRAY [{low}..{high}] OF {element.name}", element.size * (high - low + 1), element.align,
                    element=element, bounds=(low, high))


def structure(name: str, fields: list[tuple[str, DataType]]) -> DataType:
    """A STRUCT with TwinCAT's pack-8 layout of `fields` (name, type) in order."""
    offset, align, members = 0, 1, []
    for member, kind in fields:
        a = min(kind.align, PACK_MODE)
        offset = -(-offset // a) * a
        members.append((member, kind, offset))
        offset += kind.size
        align = max(align, a)
    return DataType(name, -(-offset // align) * align, align, members=tuple(members))


def _contract_type(symbol: plc_contract.Symbol) -> DataType:
    if symbol.member == "eCommand":
        return enumeration("E_AxiscalCommand")
    kind = elementary(symbol.iec_type)
    return kind if symbol.array_length is None else array(kind, 0, symbol.array_length - 1)


def _struct_of(name: str, symbols: dict[str, plc_contract.Symbol]) -> DataType:
    return structure(name, [(member, _contract_type(s)) for member, s in symbols.items()])


CONTROL = _struct_of("ST_AxiscalControl", plc_contract.control_symbols(1))
STATUS = _struct_of("ST_AxiscalStatus", plc_contract.status_symbols(1))
COMP = _struct_of("ST_AxiscalComp", plc_contract.comp_symbols(1))
AXIS = structure("ST_AxiscalAxis", [("stControl", CONTROL), ("stStatus", STATUS)])
GVL_TYPE = structure(GVL, [("astAxes", array(AXIS, 1, MAX_AXES)), ("astComp", array(COMP, 1, MAX_AXES))])
"""The GVL's variables, laid out like a structure of them (offset 0 is the GVL's first byte)."""

DATA_TYPES = {t.name.lower(): t for t in (CONTROL, STATUS, COMP, AXIS, enumeration("E_AxiscalCommand"),
                                          *(kind for _, kind, _ in GVL_TYPE.members),
                                          *(kind for s in (CONTROL, STATUS, COMP) for _, kind, _ in s.members))}
"""Every type the GVL uses, by lower-case name: the project's structures and enumeration, the
array types it instantiates and the elementary types of their members (TwinCAT 3 answers for all
of them when a client asks for a type by name)."""

MAX_COMP_BYTES = MAX_COMP_POINTS * ELEMENTARY_SIZE["LREAL"]


@dataclass(frozen=True)
class Variable:
    """A resolved variable: its ADS name as declared, type, offset in the GVL, bytes."""

    name: str
    kind: DataType
    offset: int

    @property
    def size(self) -> int:
        return self.kind.size


_PART = re.compile(r"([A-Za-z_]\w*)((?:\[\s*-?\d+\s*\])*)$")


def resolve(path: str) -> Variable | None:
    """The variable named `path` (e.g. "GVL_Axiscal.astAxes[1].stStatus.bDone"), None when the
    GVL has no such variable. Names are case-insensitive; the returned name is as declared."""
    parts = path.strip().strip("\x00").split(".")
    if not parts or parts[0].lower() != GVL.lower() or len(parts) < 2:
        return None
    kind, offset, name = GVL_TYPE, 0, GVL
    for part in parts[1:]:
        match = _PART.match(part.strip())
        if match is None:
            return None
        member = next((m for m in kind.members if m[0].lower() == match[1].lower()), None)
        if member is None:
            return None
        name, kind, offset = f"{name}.{member[0]}", member[1], offset + member[2]
        for index in re.findall(r"-?\d+", match[2]):
            if kind.element is None or kind.bounds is None or not kind.bounds[0] <= int(index) <= kind.bounds[1]:
                return None
            name += f"[{int(index)}]"
            offset += (int(index) - kind.bounds[0]) * kind.element.size
            kind = kind.element
    return Variable(name, kind, offset)


def require(path: str) -> Variable:
    """The variable named `path`; ValueError naming it when the GVL has no such variable."""
    variable = resolve(path)
    if variable is None:
        raise ValueError(f"{path}: not a variable of {GVL}")
    return variable

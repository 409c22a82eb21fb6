"""Siemens 840D encoder error compensation (EEC) file `%_N_AX_EEC_INI`, one table, values in mm
(degree), a positive value moves the axis in the negative direction: value = -correction.
Needs MD38000 >= the number of points and MD32700 ENC_COMP_ENABLE = 1; active once the axis is
referenced. Direction-dependent tables (CEC with $AN_CEC_DIRECTION) are not written: uni mode.
The number of points depends on the control (MAX_POINTS; 808D: 200); the manual recommends the
value 0 at the reference point (give `reference`, compensate --reference). `;` comment lines
carry the provenance.
"""

from __future__ import annotations

import re

from protocols.errors import FormatError
from protocols.tables import CorrectionTable, FormatOptions, Rendered, TableRead, number, provenance_lines

MAX_POINTS = {"840d": 5000, "828d": 5000, "808d": 200}
"""Points per EEC table by control: MD38000's upper limit (840D sl, 828D: 5000; 808D: 200)."""
DEFAULT_CONTROL = "840d"


def _mm(value: float) -> str:
    """`value` in mm (deg) with 6 decimals; a value that rounds to zero is written 0.000000, never
    -0.000000 (a correction of -0.4 nm, or -0.0)."""
    text = f"{value:.6f}"
    return "0.000000" if text == "-0.000000" else text


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    control = options.control or DEFAULT_CONTROL
    if control not in MAX_POINTS:
        raise FormatError(f"siemens --control must be one of {', '.join(MAX_POINTS)}, found '{control}'")
    if len(table.common) > MAX_POINTS[control]:
        raise FormatError(f"the SINUMERIK {control.upper()} takes at most {MAX_POINTS[control]} points per table, "
                          f"the table has {len(table.common)} (use --max-points)")
    if table.mode != "uni":
        raise FormatError("siemens EEC holds one table per axis; use --mode uni")
    axis = options.axis_name
    f = table.unit_factor
    lines = ["%_N_AX_EEC_INI", *provenance_lines(options, "; "), "CHANDATA(1)"]
    lines += [f"$AA_ENC_COMP[0,{i},{axis}]={_mm(-c * f)}" for i, c in enumerate(table.common)]
    lines += [f"$AA_ENC_COMP_STEP[0,{axis}]={_mm(table.spacing)}",
              f"$AA_ENC_COMP_MIN[0,{axis}]={_mm(table.positions[0])}",
              f"$AA_ENC_COMP_MAX[0,{axis}]={_mm(table.positions[-1])}",
              f"$AA_ENC_COMP_IS_MODULO[0,{axis}]=0", "M17"]
    notes = [f"MD38000 MM_ENC_COMP_MAX_POINTS >= {len(table.common)}", "MD32700 ENC_COMP_ENABLE = 1"]
    if table.reference is None:
        notes.append("the manual recommends 0 at the reference point: give --reference (the reference position)")
    if table.backlash is not None:
        notes.append(f"MD32450 BACKLASH = {_mm(-table.backlash * f)} (lost motion = -B̄)")
    return Rendered("\n".join(lines) + "\n", notes)


ENTRY = re.compile(r"^\$AA_ENC_COMP(_STEP|_MIN|_MAX)?\[0,(?:(\d+),)?\s*([A-Za-z0-9_]+)\]=(\S+)$")


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    values: dict[int, float] = {}
    limits: dict[str, float] = {}
    for i, line in enumerate(text.splitlines(), start=1):
        match = ENTRY.match(line.strip())
        if not match:
            continue
        value = number(match.group(4), path, i)
        if match.group(1):
            limits[match.group(1)] = value
        elif match.group(2) is not None:
            values[int(match.group(2))] = -value
    n = len(values)
    if n < 2 or sorted(values) != list(range(n)):
        raise FormatError(f"{path}: $AA_ENC_COMP[0,i,AXIS] must be given for i = 0..N-1, N ≥ 2")
    if "_STEP" not in limits or "_MIN" not in limits or limits["_STEP"] <= 0:
        raise FormatError(f"{path}: $AA_ENC_COMP_STEP (> 0) and $AA_ENC_COMP_MIN are needed")
    table = tuple(values[i] for i in range(n))
    return TableRead(limits["_MIN"], limits["_STEP"], table, table, "uni")

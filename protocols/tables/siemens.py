"""Siemens 840D encoder error compensation (EEC) file `%_N_AX_EEC_INI`, one table, values in mm
(degree), a positive value moves the axis in the negative direction: value = -correction.
Needs MD38000 >= the number of points and MD32700 ENC_COMP_ENABLE = 1; active once the axis is
referenced. Direction-dependent tables (CEC with $AN_CEC_DIRECTION) are not written: uni mode.
"""

from __future__ import annotations

from protocols.errors import FormatError
from protocols.tables import FormatOptions, Rendered


def render(table, options: FormatOptions) -> Rendered:
    if table.mode != "uni":
        raise FormatError("siemens EEC holds one table per axis; use --mode uni")
    axis = options.axis_name
    f = table.unit_factor
    lines = ["%_N_AX_EEC_INI", "CHANDATA(1)"]
    lines += [f"$AA_ENC_COMP[0,{i},{axis}]={-c * f:.6f}" for i, c in enumerate(table.common)]
    lines += [f"$AA_ENC_COMP_STEP[0,{axis}]={table.spacing:.6f}",
              f"$AA_ENC_COMP_MIN[0,{axis}]={table.positions[0]:.6f}",
              f"$AA_ENC_COMP_MAX[0,{axis}]={table.positions[-1]:.6f}",
              f"$AA_ENC_COMP_IS_MODULO[0,{axis}]=0", "M17"]
    notes = [f"MD38000 MM_ENC_COMP_MAX_POINTS >= {len(table.common)}", "MD32700 ENC_COMP_ENABLE = 1"]
    if table.backlash is not None:
        notes.append(f"MD32450 BACKLASH = {-table.backlash * f:.6f} (lost motion = -B̄)")
    return Rendered("\n".join(lines) + "\n", notes)

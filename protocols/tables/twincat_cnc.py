"""TwinCAT CNC (TF5200) leadscrew error compensation list `kw.ssfk.*`: equidistant, bilateral,
unit 1 = 0.1 µm (0.0001 degree on a rotary axis: not verified). Positions and values are in that
unit; a value is actual - programmed = -correction (Beckhoff's example: -102 = -10.2 µm).
Enabled by lr_param.ssfk = 1 in the axis parameters.
"""

from __future__ import annotations

from protocols.errors import FormatError
from protocols.tables import FormatOptions, Rendered

MAX_POINTS = 1500
PER_AXIS_UNIT = 10_000  # 0.1 µm per mm


def render(table, options: FormatOptions) -> Rendered:
    n = len(table.forward)
    if n > MAX_POINTS:
        raise FormatError(f"twincat_cnc takes at most {MAX_POINTS} points (kw.ssfk.max_points), got {n}")
    tenth = table.unit_factor * PER_AXIS_UNIT  # 0.1 µm per deviation unit
    rows = [("kw.ssfk.interval", round(table.spacing * PER_AXIS_UNIT)),
            ("kw.ssfk.kw_startpos", round(table.start * PER_AXIS_UNIT)),
            ("kw.ssfk.kw_nr_max", n), ("kw.ssfk.unit", 1), ("kw.ssfk.bilateral", 1)]
    for i, p in enumerate(table.positions):
        rows.append((f"kw.ssfk.table[{i}].setpoint", round(p * PER_AXIS_UNIT)))
    for i, c in enumerate(table.forward):
        rows.append((f"kw.ssfk.table[{i}].pos", round(-c * tenth)))
    for i, c in enumerate(table.reverse):
        rows.append((f"kw.ssfk.table[{i}].neg", round(-c * tenth)))
    text = f"kopf.log_achs_name {options.axis_name}\n" + "".join(f"{k:<36}{v}\n" for k, v in rows)
    return Rendered(text, ["set lr_param.ssfk = 1 in the axis parameters"])

"""axiscal's own CSV: one row per point, position in the axis unit, corrections (what the
control adds to the command, ≈ -error) in the deviation unit, for both directions."""

from __future__ import annotations

from protocols.tables import FormatOptions, Rendered
from protocols.units import UNITS


def render(table, options: FormatOptions) -> Rendered:
    pos_unit, dev_unit = UNITS[table.kind]
    lines = [f"position_{pos_unit},correction_forward_{dev_unit},correction_reverse_{dev_unit}"]
    lines += [f"{p:.6f},{fw:.4f},{rv:.4f}" for p, fw, rv in zip(table.positions, table.forward, table.reverse)]
    return Rendered("\n".join(lines) + "\n")

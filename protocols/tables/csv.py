"""axiscal's own CSV: one row per point, position in the axis unit, corrections (what the
control adds to the command, ≈ -error) in the deviation unit, for both directions."""

from __future__ import annotations

from protocols.errors import FormatError
from protocols.tables import (
    CorrectionTable,
    FormatOptions,
    Rendered,
    TableRead,
    equidistant,
    number,
    provenance_lines,
)
from protocols.units import UNITS


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    pos_unit, dev_unit = UNITS[table.kind]
    lines = provenance_lines(options, "# ")
    lines.append(f"position_{pos_unit},correction_forward_{dev_unit},correction_reverse_{dev_unit}")
    lines += [f"{p:.6f},{fw:.4f},{rv:.4f}" for p, fw, rv in zip(table.positions, table.forward, table.reverse)]
    return Rendered("\n".join(lines) + "\n")


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    lines = [(i, line.strip()) for i, line in enumerate(text.lstrip("\ufeff").splitlines(), start=1)
             if line.strip() and not line.startswith("#")]
    if not lines:
        raise FormatError(f"{path}: empty table")
    header = lines[0][1].split(",")
    kinds = {tuple(f"{c}_{u}" for c, u in zip(("position", "correction_forward", "correction_reverse"), (p, d, d))): k
             for k, (p, d) in UNITS.items()}
    kind = kinds.get(tuple(header))
    if kind is None:
        raise FormatError(f"{path}: line {lines[0][0]}: expected the header position_mm,correction_forward_um,"
                          f"correction_reverse_um (or _deg/_arcsec), found '{lines[0][1][:60]}'")
    factor = 1.0 / (1000.0 if kind == "linear" else 3600.0)
    rows = []
    for i, line in lines[1:]:
        cells = line.split(",")
        if len(cells) != 3:
            raise FormatError(f"{path}: line {i}: expected 3 fields, found {len(cells)}")
        rows.append([number(c, path, i) for c in cells])
    start, spacing = equidistant([r[0] for r in rows], path)
    forward = tuple(r[1] * factor for r in rows)
    reverse = tuple(r[2] * factor for r in rows)
    return TableRead(start, spacing, forward, reverse, "uni" if forward == reverse else "bi", kind)

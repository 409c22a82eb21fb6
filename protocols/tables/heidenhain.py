"""Heidenhain TNC nonlinear axis error compensation table (.COM), assigned to the axis in a
.CMA file. Columns: NR, AXISPOS (mm or degree), the correction of the common table (mm or
degree) and BACKLASH = reverse - forward correction per point. At most 256 entries.

Checked against reference.md and two Heidenhain technical manuals: the TNC 407 manual lists
"more than 256 entries" as an error of a .COM table; the MANUALplus 620 manual puts the
compensation points in AXISPOS (relative to the machine datum) and "the compensation values
measured in the negative direction of traverse" in BACKLASH. Whether BACKLASH takes the
difference to the positive direction (written here) or the negative direction's own value, the
exact header and end lines and the sign of the correction column (written here as the
correction to add, i.e. -error) are NOT verified. Check with a test move before use. The value
column is named after the axis (`X`, `Z`, …). Older TNCs (TNC 426/430, `control="tnc426"`)
take only a power-of-two spacing between entries (…, 0.5, 1, 2, 4, … mm); the TNC 640 any.
"""

from __future__ import annotations

import math

from protocols.errors import FormatError
from protocols.tables import CorrectionTable, FormatOptions, Rendered, TableRead, equidistant, number

MAX_POINTS = 256
CONTROLS = ("tnc640", "tnc426")


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    n = len(table.forward)
    if n > MAX_POINTS:
        raise FormatError(f"heidenhain takes at most {MAX_POINTS} entries, the table has {n}")
    control = options.control or "tnc640"
    if control not in CONTROLS:
        raise FormatError(f"heidenhain --control must be one of {', '.join(CONTROLS)}, found '{control}'")
    if control == "tnc426":
        exponent = math.log2(table.spacing)
        if abs(exponent - round(exponent)) > 1e-9:
            raise FormatError(f"the {control.upper()} takes a power-of-two spacing (…, 0.5, 1, 2, 4, 8, 16, 32, … mm), "
                              f"the table's is {table.spacing:g}: give --spacing {2.0 ** math.floor(exponent):g}")
    f = table.unit_factor
    axis = options.axis_name
    lines = [f"BEGIN {axis}.COM", f"NR AXISPOS {axis} BACKLASH"]
    for i, (p, c, fw, rv) in enumerate(zip(table.positions, table.common, table.forward, table.reverse)):
        lines.append(f"{i} {p:.4f} {c * f:+.5f} {(rv - fw) * f:+.5f}")
    lines.append("[END]")
    return Rendered("\n".join(lines) + "\n", [f"assign {axis}.COM to axis {axis} in the .CMA file",
                                               "UNVERIFIED sign of the correction column: test first"])


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    """NR AXISPOS <correction> BACKLASH rows: forward = correction - BACKLASH/2, reverse =
    correction + BACKLASH/2 (as written by `render`)."""
    rows = []
    for i, line in enumerate(text.splitlines(), start=1):
        cells = line.split()
        if not cells or cells[0] in ("BEGIN", "NR") or cells[0].startswith("[END"):
            continue
        if len(cells) != 4:
            raise FormatError(f"{path}: line {i}: expected 'NR AXISPOS correction BACKLASH', found '{line.strip()[:60]}'")
        rows.append([number(c, path, i) for c in cells[1:]])
    start, spacing = equidistant([r[0] for r in rows], path)
    forward = tuple(c - b / 2 for _, c, b in rows)
    reverse = tuple(c + b / 2 for _, c, b in rows)
    return TableRead(start, spacing, forward, reverse, "uni" if forward == reverse else "bi")

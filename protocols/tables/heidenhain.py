"""Heidenhain TNC nonlinear axis error compensation table (.COM), assigned to the axis in a
.CMA file. Columns: NR, AXISPOS (mm or degree), the correction of the common table (mm or
degree) and BACKLASH = reverse - forward correction per point. At most 256 entries.

Checked against reference.md and two Heidenhain technical manuals: the TNC 407 manual lists
"more than 256 entries" as an error of a .COM table; the MANUALplus 620 manual puts the
compensation points in AXISPOS (relative to the machine datum) and "the compensation values
measured in the negative direction of traverse" in BACKLASH. Whether BACKLASH takes the
difference to the positive direction (written here) or the negative direction's own value, the
exact header and end lines and the sign of the correction column (written here as the
correction to add, i.e. -error) are NOT verified. Check with a test move before use.
"""

from __future__ import annotations

from protocols.errors import FormatError
from protocols.tables import FormatOptions, Rendered, TableRead, equidistant, number

MAX_POINTS = 256


def render(table, options: FormatOptions) -> Rendered:
    n = len(table.forward)
    if n > MAX_POINTS:
        raise FormatError(f"heidenhain takes at most {MAX_POINTS} entries, the table has {n}")
    f = table.unit_factor
    axis = options.axis_name
    lines = [f"BEGIN {axis}.COM", f"NR AXISPOS D{axis} BACKLASH"]
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

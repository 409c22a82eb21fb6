"""LinuxCNC COMP_FILE, COMP_FILE_TYPE 0: one line `nominal actual_forward actual_reverse` per
point, machine units (mm or degree), nominal strictly increasing, at most 256 lines, no header
or comment (older loaders stop at the first line that is not three numbers).

The loader stores trim = nominal - actual and adds it to the command, so the "actual" written
is nominal - correction: with the simple method that is the measured actual position
(nominal + error); with inverse interpolation it is the actual position that gives the exact
correction. BACKLASH is ignored when a COMP_FILE is set, so both directions are always written.
"""

from __future__ import annotations

from protocols.errors import FormatError
from protocols.tables import FormatOptions, Rendered, TableRead, equidistant, number

MAX_POINTS = 256


def render(table, options: FormatOptions) -> Rendered:
    positions = table.positions
    if len(positions) > MAX_POINTS:
        raise FormatError(f"linuxcnc takes at most {MAX_POINTS} points, the table has {len(positions)}")
    f = table.unit_factor
    lines = [f"{p:.6f} {p - fw * f:.6f} {p - rv * f:.6f}"
             for p, fw, rv in zip(positions, table.forward, table.reverse)]
    notes = [f"[JOINT_{options.joint}]", "COMP_FILE = <this file>", "COMP_FILE_TYPE = 0"]
    return Rendered("\n".join(lines) + "\n", notes)


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    """Every line three numbers (LinuxCNC's own loader stops silently at the first other line;
    this reader names it instead)."""
    rows = []
    for i, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        cells = line.split()
        if len(cells) != 3:
            raise FormatError(f"{path}: line {i}: expected 'nominal actual_forward actual_reverse', "
                              f"found '{line.strip()[:60]}'")
        rows.append([number(c, path, i) for c in cells])
    start, spacing = equidistant([r[0] for r in rows], path)
    forward = tuple(p - a for p, a, _ in rows)
    reverse = tuple(p - a for p, _, a in rows)
    return TableRead(start, spacing, forward, reverse, "uni" if forward == reverse else "bi")

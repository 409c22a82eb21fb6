"""LinuxCNC COMP_FILE, COMP_FILE_TYPE 0: one line `nominal actual_forward actual_reverse` per
point, machine units (mm or degree), nominal strictly increasing, at most 256 lines, no header
or comment (older loaders stop at the first line that is not three numbers).

The loader stores trim = nominal - actual and adds it to the command, so the "actual" written
is nominal - correction: with the simple method that is the measured actual position
(nominal + error); with inverse interpolation it is the actual position that gives the exact
correction. BACKLASH is ignored when a COMP_FILE is set, so both directions are always written.

Machine units: an inch machine (LINEAR_UNITS = inch) needs the table in inches (`units="inch"`);
a rotary joint is in degrees either way. LinuxCNC's loader stops silently at the first line that
is not three numbers, so the file carries no comment and no provenance.
"""

from __future__ import annotations

from protocols.errors import FormatError
from protocols.tables import CorrectionTable, FormatOptions, Rendered, TableRead, equidistant, number

MAX_POINTS = 256
MM_PER_INCH = 25.4


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    positions = table.positions
    if len(positions) > MAX_POINTS:
        raise FormatError(f"linuxcnc takes at most {MAX_POINTS} points, the table has {len(positions)}")
    if options.units not in ("mm", "inch"):
        raise FormatError(f"linuxcnc units must be mm or inch, found '{options.units}'")
    f = table.unit_factor
    scale = 1.0 / MM_PER_INCH if options.units == "inch" and table.kind == "linear" else 1.0
    d = 7 if scale != 1.0 else 6  # 1 nm in mm, 2.5 nm in inch
    lines = [f"{p * scale:.{d}f} {(p - fw * f) * scale:.{d}f} {(p - rv * f) * scale:.{d}f}"
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
    scale = MM_PER_INCH if options.units == "inch" else 1.0
    rows = [[v * scale for v in r] for r in rows]
    start, spacing = equidistant([r[0] for r in rows], path)  # mm (degree), whatever the file's unit
    forward = tuple(p - a for p, a, _ in rows)
    reverse = tuple(p - a for p, _, a in rows)
    return TableRead(start, spacing, forward, reverse, "uni" if forward == reverse else "bi")

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
from protocols.tables import FormatOptions, Rendered

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

"""LinuxCNC (rs274ngc) G-code: G21/G20 is not needed for a rotary axis; G90 absolute, G94 feed per
minute, G1 moves with F, G4 P<seconds> dwells (LinuxCNC's P is seconds), ( ) comments, M2 ends.
Checked by LinuxCNC's own interpreter in tests/test_program.py (rs274 -g)."""

from __future__ import annotations

from protocols.nc import NcProgram, clean_comment


def render(program: NcProgram) -> str:
    axis = program.axis.upper()
    lines = [f"({clean_comment(h)})" for h in program.header]
    lines.append("G90 G94" + (" G21" if program.unit == "mm" else ""))
    for move in program.moves:
        if move.comment:
            lines.append(f"({clean_comment(move.comment)})")
        lines.append(f"G1 {axis}{move.position:.4f} F{move.feed:.1f}")
        if move.dwell_s > 0:
            lines.append(f"G4 P{move.dwell_s:.3f}")
    lines.append("M2")
    return "\n".join(lines) + "\n"

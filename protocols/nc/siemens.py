"""SINUMERIK 840D sl / 828D (ISO dialect off): G71 metric, G90 absolute, G94 feed per minute,
G1 moves with F, G4 F<seconds> dwells (G4 in its own block; F is the time in s there), ; comments,
M30 ends. Follows the SINUMERIK 840D sl programming manual "Fundamentals" (G4 dwell time). Not
run on a SINUMERIK control."""

from __future__ import annotations

from protocols.nc import NcProgram, clean_comment


def render(program: NcProgram) -> str:
    axis = program.axis.upper()
    lines = [f"; {clean_comment(h)}" for h in program.header]
    lines.append("G90 G94" + (" G71" if program.unit == "mm" else ""))
    for move in program.moves:
        if move.comment:
            lines.append(f"; {clean_comment(move.comment)}")
        lines.append(f"G1 {axis}{move.position:.4f} F{move.feed:.1f}")
        if move.dwell_s > 0:
            lines.append(f"G4 F{move.dwell_s:.3f}")
    lines.append("M30")
    return "\n".join(lines) + "\n"

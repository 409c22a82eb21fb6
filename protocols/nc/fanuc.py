"""FANUC (Series 0i/30i) G-code: % start and end, O program number, G21 metric, G90 absolute,
G94 feed per minute, G01 moves with F, G04 X<seconds> dwells (X takes a decimal point; P would be
milliseconds without one), ( ) comments, M30 ends. Follows the FANUC Series 0i-MF operator's
manual (B-64604EN), G04 dwell. Not run on a FANUC control."""

from __future__ import annotations

from protocols.nc import NcProgram, clean_comment

PROGRAM_NUMBER = 2302
"""O-number of the program (O2302: ISO 230-2)."""


def render(program: NcProgram) -> str:
    axis = program.axis.upper()
    lines = ["%", f"O{PROGRAM_NUMBER:04d} ({clean_comment(program.name)[:30]})"]
    lines += [f"({clean_comment(h)})" for h in program.header]
    lines.append("G90 G94" + (" G21" if program.unit == "mm" else ""))
    for move in program.moves:
        if move.comment:
            lines.append(f"({clean_comment(move.comment)})")
        lines.append(f"G01 {axis}{move.position:.4f} F{move.feed:.1f}")
        if move.dwell_s > 0:
            lines.append(f"G04 X{move.dwell_s:.3f}")
    lines += ["M30", "%"]
    return "\n".join(lines) + "\n"

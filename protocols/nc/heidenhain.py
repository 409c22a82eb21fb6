"""HEIDENHAIN Klartext (TNC 640/620): numbered blocks, BEGIN PGM / END PGM with the unit, L moves
with F (mm/min), CYCL DEF 9 DWELL TIME (9.0 then 9.1 DWELL <s>) for the dwell, ; comments.
Follows the TNC 640 Klartext user's manual (cycle 9 DWELL TIME, path function L). Not run on a
HEIDENHAIN control."""

from __future__ import annotations

from protocols.nc import NcProgram, clean_comment


def render(program: NcProgram) -> str:
    axis = program.axis.upper()
    unit = "MM"  # the program's linear unit; a rotary axis is in degrees either way
    name = "".join(c for c in program.name.upper() if c.isalnum() or c == "_")[:16] or "AXISCAL"
    body = [f"BEGIN PGM {name} {unit}"]
    body += [f"; {clean_comment(h)}" for h in program.header]
    for move in program.moves:
        if move.comment:
            body.append(f"; {clean_comment(move.comment)}")
        body.append(f"L {axis}{move.position:+.4f} F{move.feed:.0f}")
        if move.dwell_s > 0:
            body += ["CYCL DEF 9.0 DWELL TIME", f"CYCL DEF 9.1 DWELL {move.dwell_s:.3f}"]
    body.append(f"END PGM {name} {unit}")
    return "\n".join(f"{i} {line}" for i, line in enumerate(body)) + "\n"

"""ecmc encoder correction table: the file an ecmccfg axis YAML names under `encoder: lookuptable:
filename:` (ecmccfg manual, motion configuration, "yaml configuration", the encoder section's
`lookuptable`; the file's format is described in ecmc's ecmcLookupTable.h).

One row per point, `position value`: the encoder position and the correction value there, both in
the axis's engineering unit (mm or degree), positions increasing, at least 3 rows. ecmc
interpolates linearly between rows and holds the first or last value outside them, and applies the
table only to a homed encoder. A line starting with `#` is a comment, an empty line is skipped, a
line `PREC=n` sets the digits the loader reads; every other line must start with two numbers
(comma or space between them), anything after them is ignored (`read_rows`).

Sign (ecmc 10.0.0 and later; its release notes: "Change encoder lookup table correction sign. The
loaded table will be subtracted instead of added"; ecmcEncoder.cpp; the ecmccfg manual's axis YAML:
"Value will be subtracted from encoder value"): ecmc takes the actual position as
raw − scale·value(raw), with `encoder: lookuptable: scale:` (ecmc 10.0.9 and later) defaulting to
1, and closes the loop on it. The axis's true position is raw + error(raw), so the actual position
is the true one when value = −error: the value is axiscal's correction (what the control adds to
the command, minus the error), for scale 1. ecmc 9.6.7 to 9.6.x added the value instead, with no
scale: these files are not for those versions. The
position column is the encoder's reading, which differs from the nominal position by the error
(µm): the correction's change over that distance is negligible, so the nominal positions are
written. One table for both directions: uni mode only.
"""

from __future__ import annotations

import itertools
import re

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

MIN_ROWS = 3
PREC_LINE = re.compile(r"PREC=\s*[+-]?\d")
"""A precision line as ecmc's loader takes it (sscanf "PREC=%d")."""
PREC = 10
"""The digits written in `PREC=` (ecmc's loader reads that many; its own default is 10 too)."""


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    if table.mode != "uni":
        raise FormatError("ecmc's lookup table holds one correction for both directions; use --mode uni")
    positions = table.positions
    if len(positions) < MIN_ROWS:
        raise FormatError(f"ecmc's lookup table needs at least {MIN_ROWS} rows, the table has {len(positions)}")
    f = table.unit_factor
    lines = ["# ecmc encoder correction table (encoder: lookuptable: filename:), written by axiscal",
             *provenance_lines(options, "# "),
             "# encoder position, value ecmc subtracts from it (lookuptable: scale: 1) (axis unit)",
             f"PREC={PREC}"]
    lines += [f"{p:.6f} {ecmc_value(c * f):.9f}" for p, c in zip(positions, table.common)]
    notes = [("ecmccfg axis YAML: encoder: lookuptable: filename: <this file>, scale: 1 (the default; ecmc subtracts "
              "the value from the encoder position once the encoder is homed)")]
    if table.backlash is not None:
        notes.append(f"reversal B̄ = {table.backlash:g} (deviation unit) is not in the table: ecmc's lookup table "
                     "has one correction for both directions")
    return Rendered("\n".join(lines) + "\n", notes)


def ecmc_value(correction: float) -> float:
    """The value ecmc's table holds (it subtracts scale·value from the encoder position, scale 1) for
    axiscal's `correction` (what the control adds to the command, minus the error); same unit."""
    return correction


def correction_of(value: float) -> float:
    """axiscal's correction for the value ecmc's table holds (the inverse of `ecmc_value`)."""
    return value


def apply_encoder_table(raw: float, positions: list[float], values: list[float], scale: float = 1.0) -> float:
    """ecmc's rule: the actual position for the encoder's `raw` position, raw − scale·value(raw),
    the value interpolated linearly between rows and held outside them (axis unit)."""
    if raw <= positions[0]:
        value = values[0]
    elif raw >= positions[-1]:
        value = values[-1]
    else:
        i = next(k for k in range(1, len(positions)) if raw <= positions[k])
        a, b = positions[i - 1], positions[i]
        value = values[i - 1] + (values[i] - values[i - 1]) * (raw - a) / (b - a)
    return raw - scale * value


def read_rows(text: str, path: str) -> list[tuple[float, float]]:
    """The (position, value) rows as ecmc's loader (ecmcLookupTable.h, ecmc 10/11) reads them:
    commas count as spaces; an empty line is skipped; a line starting with `#` is a comment; a line
    starting with `PREC=n` (no space before `=`) sets the digits read; any other line must start
    with two numbers, and what follows them is ignored. At least MIN_ROWS rows, positions
    increasing."""
    rows: list[tuple[float, float]] = []
    for i, line in enumerate(text.splitlines(), start=1):
        line = line.replace(",", " ")
        if not line or line.startswith("#") or (line.startswith("P") and PREC_LINE.match(line)):
            continue
        cells = line.split()
        if len(cells) < 2:
            raise FormatError(f"{path}: line {i}: expected 'position value' (ecmc's loader refuses this "
                              f"line), found '{line.strip()[:60]}'")
        rows.append((number(cells[0], path, i, "position"), number(cells[1], path, i)))
    if len(rows) < MIN_ROWS:
        raise FormatError(f"{path}: ecmc needs at least {MIN_ROWS} rows, the file has {len(rows)}")
    positions = [p for p, _ in rows]
    if any(b < a for a, b in itertools.pairwise(positions)):
        raise FormatError(f"{path}: the positions are not in increasing order (ecmc refuses the table)")
    return rows


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    """Rows as ecmc's loader reads them (`read_rows`); the positions must be equidistant for
    axiscal's tables (ecmc itself takes any increasing positions)."""
    rows = read_rows(text, path)
    start, spacing = equidistant([p for p, _ in rows], path)
    correction = tuple(correction_of(v) for _, v in rows)
    return TableRead(start, spacing, correction, correction, "uni")

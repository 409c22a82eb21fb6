"""ecmc encoder correction table: the file an ecmccfg axis YAML names under `encoder: lookuptable:
filename:` (ecmccfg manual, motion configuration, "yaml configuration", the encoder section's
`lookuptable`; the file's format is described in ecmc's ecmcLookupTable.h).

One row per point, `position value`: the encoder position and the error ecmc adds to the encoder's
position there, both in the axis's engineering unit (mm or degree), positions increasing, at least
3 rows. ecmc interpolates linearly between rows and holds the first or last value outside them,
and applies the table only to a homed encoder. A line starting with `#` is a comment; a line
`PREC=n` sets the digits the loader reads. ecmc's loader refuses any other line, a blank one too.

Sign: ecmc adds the value to the encoder position and closes the loop on the sum, so the value is
the axis's error (actual minus nominal), which is minus the correction axiscal's tables hold (what
the control adds to the command). The position column is the encoder's reading, which differs from
the nominal position by the error (µm): the correction's change over that distance is negligible,
so the nominal positions are written. One table for both directions: uni mode only.
"""

from __future__ import annotations

import itertools

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
             "# encoder position, error added to it (axis unit)",
             f"PREC={PREC}"]
    lines += [f"{p:.6f} {-c * f:.9f}" for p, c in zip(positions, table.common)]
    notes = [("ecmccfg axis YAML: encoder: lookuptable: filename: <this file> (ecmc applies it once the encoder "
              "is homed)")]
    if table.backlash is not None:
        notes.append(f"reversal B̄ = {table.backlash:g} (deviation unit) is not in the table: ecmc's lookup table "
                     "has one correction for both directions")
    return Rendered("\n".join(lines) + "\n", notes)


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    """Rows as ecmc's loader reads them (comments, PREC=n, two numbers a line); the positions must
    be equidistant for axiscal's tables (ecmc itself takes any increasing positions)."""
    rows: list[tuple[float, float]] = []
    for i, line in enumerate(text.splitlines(), start=1):
        if line.startswith("#"):
            continue
        if line.startswith("P"):
            head, _, digits = line.partition("=")
            if head.strip() == "PREC" and digits.strip().isdigit():
                continue
        cells = line.split()
        if len(cells) != 2:
            raise FormatError(f"{path}: line {i}: expected 'position value' (ecmc's loader refuses any other "
                              f"line), found '{line.strip()[:60]}'")
        rows.append((number(cells[0], path, i, "position"), number(cells[1], path, i)))
    if len(rows) < MIN_ROWS:
        raise FormatError(f"{path}: ecmc needs at least {MIN_ROWS} rows, the file has {len(rows)}")
    positions = [p for p, _ in rows]
    if any(b < a for a, b in itertools.pairwise(positions)):
        raise FormatError(f"{path}: the positions are not in increasing order (ecmc refuses the table)")
    start, spacing = equidistant(positions, path)
    correction = tuple(-v for _, v in rows)
    return TableRead(start, spacing, correction, correction, "uni")

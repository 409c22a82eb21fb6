"""Turbo PMAC leadscrew compensation: `DEFINE COMP {entries},{count length}` then the entries,
integers in 1/16 count with the sign of the correction (opposite to the error), then I51=1.

The first entry is the correction one spacing above motor zero; the table rolls over, so the
last entry is the value at count length, which is also the value at 0. The table must start at
motor zero. One table only: uni mode (a backlash B̄ is reported for Ixx86).
"""

from __future__ import annotations

import math
import re

from protocols.errors import FormatError
from protocols.tables import CorrectionTable, FormatOptions, Rendered, TableRead, provenance_lines


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    cpu = options.counts_per_unit
    if cpu is None or cpu <= 0:
        raise FormatError("pmac needs --counts-per-unit (encoder counts per mm or degree)")
    if table.mode != "uni":
        raise FormatError("pmac writes one leadscrew table; use --mode uni")
    if abs(table.start) > 1e-9 * max(1.0, table.spacing):
        raise FormatError(f"pmac tables start at motor zero; the grid starts at {table.start:g} "
                         "(use --reference 0)")
    spacing_counts = table.spacing * cpu
    if abs(spacing_counts - round(spacing_counts)) > 1e-6:
        whole = math.ceil(spacing_counts) / cpu
        raise FormatError(f"the spacing {table.spacing:g} is {spacing_counts:g} counts, not a whole number: "
                          f"give --spacing with a whole number of counts, e.g. --spacing {whole:.12g} "
                          f"({math.ceil(spacing_counts)} counts)")
    sixteenths = [round(c * table.unit_factor * cpu * 16) for c in table.common]
    entries = sixteenths[1:] + sixteenths[:1]
    count_length = round(spacing_counts) * len(entries)
    notes = [f"motor #{options.motor}: define tables from the highest-numbered motor down"]
    if table.backlash is not None:
        notes.append(f"backlash: I{options.motor}86 = {round(-table.backlash * table.unit_factor * cpu * 16)} "
                     "(1/16 count, lost motion = -B̄)")
    comments = "".join(f"{line}\n" for line in provenance_lines(options, "; "))
    text = (comments + f"#{options.motor}\nDEFINE COMP {len(entries)},{count_length}\n"
            + " ".join(str(e) for e in entries) + "\nI51=1\n")
    return Rendered(text, notes)


DEFINE = re.compile(r"DEFINE\s+COMP\s+(\d+)\s*,\s*(\d+)", re.IGNORECASE)


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    """Needs counts_per_unit. The entries' last is the value at motor zero (rollover)."""
    cpu = options.counts_per_unit
    if cpu is None or cpu <= 0:
        raise FormatError("reading a pmac table needs --counts-per-unit (encoder counts per mm or degree)")
    match = DEFINE.search(text)
    if not match:
        raise FormatError(f"{path}: no 'DEFINE COMP entries,count_length' line")
    entries, length = int(match.group(1)), int(match.group(2))
    words = text[match.end():].split()
    values = []
    for word in words:
        if word.upper().startswith("I"):
            break
        try:
            values.append(int(word))
        except ValueError:
            raise FormatError(f"{path}: entry '{word[:20]}' is not a whole number (1/16 count)") from None
    if len(values) != entries or entries < 1:
        raise FormatError(f"{path}: DEFINE COMP says {entries} entries, {len(values)} follow")
    table = [values[-1], *values[:-1]]  # the value at motor zero first
    scale = 1.0 / (16 * cpu)  # axis unit per 1/16 count
    corrections = tuple(v * scale for v in table)
    return TableRead(0.0, length / entries / cpu, corrections, corrections, "uni")

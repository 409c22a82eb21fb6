"""TwinCAT CNC (TF5200) leadscrew error compensation list `kw.ssfk.*`: equidistant, bilateral,
unit 1 = 0.1 µm (0.0001 degree on a rotary axis: not verified). Positions and values are in that
unit; a value is actual - programmed = -correction (Beckhoff's example: -102 = -10.2 µm).
Enabled by lr_param.ssfk = 1 in the axis parameters. The header names the axis by its logical
number, kopf.achs_nr (P-COMP-00001, UNS16, 0 < achs_nr < 65535 in both TX1270 and TF5200; a
number that is not the axis' aborts the list): it must be given. The provenance goes on
whole-line comments, `# ` at the start of a line, as in Beckhoff's own compensation list examples
("Comments in the ASCII file", TX1270 axis compensation and TF5200).
"""

from __future__ import annotations

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

MAX_POINTS = 1500
PER_AXIS_UNIT = 10_000  # 0.1 µm per mm


AXIS_NUMBERS = range(1, 65535)
"""kopf.achs_nr: UNS16, 0 not allowed (Beckhoff TF5200 axis compensation, P-COMP-00001)."""


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    if options.axis_number is None:
        raise FormatError("twincat_cnc needs --axis-number: the axis' logical number (kopf.achs_nr, "
                          "P-AXIS-00016 in its axis parameters)")
    if options.axis_number not in AXIS_NUMBERS:
        raise FormatError(f"--axis-number {options.axis_number}: kopf.achs_nr must be 1..65534 (0 is not allowed)")
    n = len(table.forward)
    if n > MAX_POINTS:
        raise FormatError(f"twincat_cnc takes at most {MAX_POINTS} points (kw.ssfk.max_points), got {n}")
    tenth = table.unit_factor * PER_AXIS_UNIT  # 0.1 µm per deviation unit
    rows = [("kw.ssfk.interval", round(table.spacing * PER_AXIS_UNIT)),
            ("kw.ssfk.kw_startpos", round(table.start * PER_AXIS_UNIT)),
            ("kw.ssfk.kw_nr_max", n), ("kw.ssfk.unit", 1), ("kw.ssfk.bilateral", 1)]
    for i, p in enumerate(table.positions):
        rows.append((f"kw.ssfk.table[{i}].setpoint", round(p * PER_AXIS_UNIT)))
    for i, c in enumerate(table.forward):
        rows.append((f"kw.ssfk.table[{i}].pos", round(-c * tenth)))
    for i, c in enumerate(table.reverse):
        rows.append((f"kw.ssfk.table[{i}].neg", round(-c * tenth)))
    comments = "".join(f"{line}\n" for line in provenance_lines(options, "# "))
    text = (comments + f"kopf.achs_nr {options.axis_number}\nkopf.log_achs_name {options.axis_name}\n"
            + "".join(f"{k:<36}{v}\n" for k, v in rows))
    return Rendered(text, ["set lr_param.ssfk = 1 in the axis parameters"])


ENTRY = re.compile(r"^kw\.ssfk\.table\[(\d+)\]\.(setpoint|pos|neg)\s+(\S+)$")


def parse(text: str, path: str, options: FormatOptions) -> TableRead:
    columns: dict[str, dict[int, float]] = {"setpoint": {}, "pos": {}, "neg": {}}
    for i, line in enumerate(text.splitlines(), start=1):
        match = ENTRY.match(line.strip())
        if match:
            columns[match.group(2)][int(match.group(1))] = number(match.group(3), path, i)
    n = len(columns["setpoint"])
    for name, values in columns.items():
        if sorted(values) != list(range(n)):
            raise FormatError(f"{path}: kw.ssfk.table[i].{name} must be given for i = 0..{n - 1}")
    positions = [columns["setpoint"][i] / PER_AXIS_UNIT for i in range(n)]
    start, spacing = equidistant(positions, path)
    forward = tuple(-columns["pos"][i] / PER_AXIS_UNIT for i in range(n))
    reverse = tuple(-columns["neg"][i] / PER_AXIS_UNIT for i in range(n))
    return TableRead(start, spacing, forward, reverse, "uni" if forward == reverse else "bi")

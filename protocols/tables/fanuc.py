"""Fanuc pitch-error compensation parameters, values in detection units, incremental.

Point n is at reference + (n - 3620)·interval. The value of point n is the change of the
correction from point n-1 to point n (the correction over the interval ending at n), in
detection units divided by the magnification 3623; the most negative point gets 0. Increments
are taken between rounded cumulative values (in magnified units), so no rounding drift builds up. 3624 = interval in
detection units. Bidirectional (3605#0 = 1): the negative direction's points follow the positive
ones, 3626 = its most negative point, 3627 = its correction at the reference position (absolute).
FANUC's technical report A-77810E (bidirectional pitch error compensation, 16i/18i) defines 3627
as the compensation amount (absolute value) at the reference position when the axis arrives
there opposite to the reference return direction; axiscal assumes the reference return runs in
the + direction, so that amount is the negative direction's correction less the positive one's
there (the reference return makes the + correction at the reference the datum). Unidirectional: backlash
1851 = lost motion = -B̄. Values may have to stay within ±127 per point on older controls; the
magnification is chosen for that. The point numbering and 1851 follow reference.md only.
"""

from __future__ import annotations

import itertools
import math
import re

import numpy as np

from protocols.errors import FormatError
from protocols.tables import CorrectionTable, FormatOptions, Rendered, TableRead, number

MAX_POINTS = 128
MAX_INCREMENT = 127


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    cpu = options.counts_per_unit
    if cpu is None or cpu <= 0:
        raise FormatError("fanuc needs --counts-per-unit (detection units per mm or degree)")
    if table.reference is None:
        raise FormatError("fanuc counts its points from the reference position: give --reference")
    unit = table.unit_factor * cpu  # detection units per deviation unit
    n = len(table.forward)
    if n > MAX_POINTS:
        raise FormatError(f"fanuc takes about {MAX_POINTS} points, the table has {n}")
    ref_index = round((table.reference - table.start) / table.spacing)
    tables = [table.common if table.mode == "uni" else table.forward]
    if table.mode == "bi":
        tables.append(table.reverse)
    raw = [np.asarray(t) * unit for t in tables]  # detection units
    largest = max(float(np.max(np.abs(np.diff(r)))) for r in raw)
    magnification = max(1, math.ceil((largest + 1) / MAX_INCREMENT))
    cumulative = [[round(v / magnification) for v in r] for r in raw]  # magnified detection units
    increments = [[0] + [b - a for a, b in itertools.pairwise(c)] for c in cumulative]
    params = [("3620", ref_index), ("3621", 0), ("3622", n - 1), ("3623", magnification),
              ("3624", round(table.spacing * cpu))]
    if table.mode == "bi":
        # at the reference the + direction's correction is the datum (the reference return sets the
        # coordinate there), so the - direction's amount is taken relative to it
        params += [("3605#0", 1), ("3626", n), ("3627", round(raw[1][ref_index] - raw[0][ref_index]))]
    elif table.backlash is not None:
        params.append(("1851", round(-table.backlash * unit)))
    lines = [f"{name} = {value}" for name, value in params]
    for block, inc in enumerate(increments):
        for i, v in enumerate(inc):
            lines.append(f"pitch[{block * n + i}] = {v}")
    return Rendered("\n".join(lines) + "\n", ["enter the values as parameters; power off and on"])


PARAM = re.compile(r"^(\d{4}(?:#\d)?|pitch\[(\d+)\])\s*=\s*(\S+)$")


def parse(text: str, path: str, options: FormatOptions, reference: float = 0.0) -> TableRead:
    """Needs counts_per_unit. Fanuc tables are incremental and zero at the reference point, so
    the level read back is relative to it: the table's correction at the reference position is
    0 (a constant offset that ISO 230-2's A, E and R do not see); the negative direction's table
    has 3627 there (relative to the + table). `reference`: that position,
    axis unit."""
    cpu = options.counts_per_unit
    if cpu is None or cpu <= 0:
        raise FormatError("reading a fanuc table needs --counts-per-unit (detection units per mm or degree)")
    params: dict[str, float] = {}
    pitch: dict[int, float] = {}
    for i, line in enumerate(text.splitlines(), start=1):
        match = PARAM.match(line.strip())
        if match and match.group(2) is not None:
            pitch[int(match.group(2))] = number(match.group(3), path, i)
        elif match:
            params[match.group(1)] = number(match.group(3), path, i)
    for needed in ("3620", "3622", "3623", "3624"):
        if needed not in params:
            raise FormatError(f"{path}: parameter {needed} is missing")
    n = int(params["3622"]) + 1
    blocks = 2 if params.get("3605#0") == 1 else 1
    if sorted(pitch) != list(range(n * blocks)):
        raise FormatError(f"{path}: pitch[0..{n * blocks - 1}] must all be given")
    ref = int(params["3620"])
    scale = params["3623"] / cpu  # axis unit per magnified increment
    tables = []
    for block in range(blocks):
        cumulative, total = [], 0.0
        for i in range(n):
            total += pitch[block * n + i]
            cumulative.append(total * scale)
        tables.append(tuple(c - cumulative[ref] for c in cumulative))
    spacing = params["3624"] / cpu
    start = reference - ref * spacing
    if blocks == 2:  # 3627: the negative direction's correction at the reference position, absolute
        level = params.get("3627", 0.0) / cpu
        return TableRead(start, spacing, tables[0], tuple(c + level for c in tables[1]), "bi")
    return TableRead(start, spacing, tables[0], tables[0], "uni")

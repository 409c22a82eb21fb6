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
the + direction, so that amount is the negative direction's correction. Unidirectional: backlash
1851 = lost motion = -B̄. Values may have to stay within ±127 per point on older controls; the
magnification is chosen for that. The point numbering and 1851 follow reference.md only.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from protocols.errors import FormatError
from protocols.tables import FormatOptions, Rendered

MAX_POINTS = 128
MAX_INCREMENT = 127


def render(table, options: FormatOptions) -> Rendered:
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
        params += [("3605#0", 1), ("3626", n), ("3627", round(raw[1][ref_index]))]
    elif table.backlash is not None:
        params.append(("1851", round(-table.backlash * unit)))
    lines = [f"{name} = {value}" for name, value in params]
    for block, inc in enumerate(increments):
        for i, v in enumerate(inc):
            lines.append(f"pitch[{block * n + i}] = {v}")
    return Rendered("\n".join(lines) + "\n", ["enter the values as parameters; power off and on"])

"""ecmc ISO 230-2 data files (EPICS EtherCAT motion control, used at ESS and PSI; `*_ISO230.dat`).

Lines `TGT_DATA[i]=<target>`, `REF_DATA_FWD[i,j]=<reading>` and `REF_DATA_BWD[i,j]=<reading>`:
i the target (from 1), j the cycle (from 1), the reference sensor's reading in the file's unit.
FWD is the approach in increasing position. Optional `UNIT=mm` (or deg), `CYCLES=`, `POSITIONS=`,
`DEC=`; `# ...` comments and other `KEY=VALUE` lines (PV names) are kept as metadata. A comment
`# key: value` is read as that metadata key, as in a point table.

deviation = reading - target: µm for mm, arcsec for degrees.
"""

from __future__ import annotations

import itertools
import math
import re

from protocols.errors import FormatError
from protocols.measurements import Measurement, Row
from protocols.units import DEVIATION_SCALE

TARGET = re.compile(r"^TGT_DATA\[\s*(\d+)\s*\]\s*=\s*(\S+)\s*$")
REFERENCE = re.compile(r"^REF_DATA_(FWD|BWD)\[\s*(\d+)\s*,\s*(\d+)\s*\]\s*=\s*(\S+)\s*$")
SETTING = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")
COMMENT_META = re.compile(r"^#\s*([a-z_]+):\s*(.*?)\s*$")
KINDS = {"mm": "linear", "deg": "rotary"}
DECIMALS = 9
"""Digits after the point of a written reading: 1 pm in mm, far below any deviation's last digit."""


def _value(text: str, name: str, line: int) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FormatError(f"{name}: line {line}: '{text}' is not a number") from None
    if not math.isfinite(value):
        raise FormatError(f"{name}: line {line}: '{text}' is not a finite number")
    return value


def parse(text: str, name: str = "<ecmc>", kind: str | None = None) -> Measurement:
    """The measurement in an ecmc ISO 230-2 file. `kind` (linear or rotary) when the file has no
    UNIT line; UNIT wins. FormatError names the line for bad input."""
    targets: dict[int, float] = {}
    readings: dict[tuple[str, int, int], tuple[float, int]] = {}
    meta: dict[str, str] = {}
    unit = None
    comments = []
    for number, raw in enumerate(text.lstrip("\ufeff").splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            match = COMMENT_META.match(line)
            if match:
                meta[match.group(1)] = match.group(2)
            elif line.strip("# "):
                comments.append(line.lstrip("# "))
            continue
        if match := TARGET.match(line):
            i, value = int(match.group(1)), _value(match.group(2), name, number)
            if i in targets and targets[i] != value:  # repeated per cycle by some writers: must agree
                raise FormatError(f"{name}: line {number}: TGT_DATA[{i}]={value:g}, earlier {targets[i]:g}")
            targets[i] = value
        elif match := REFERENCE.match(line):
            key = (match.group(1), int(match.group(2)), int(match.group(3)))
            if key in readings:
                raise FormatError(f"{name}: line {number}: REF_DATA_{key[0]}[{key[1]},{key[2]}] appears twice")
            readings[key] = (_value(match.group(4), name, number), number)
        elif line.startswith(("TGT_DATA", "REF_DATA")):
            raise FormatError(f"{name}: line {number}: expected TGT_DATA[i]=value or REF_DATA_FWD|BWD[i,j]=value, "
                              f"found '{line[:60]}'")
        elif match := SETTING.match(line):
            setting, text_value = match.group(1), match.group(2)
            if setting == "UNIT":
                if text_value not in KINDS:
                    raise FormatError(f"{name}: line {number}: UNIT must be mm or deg, found '{text_value}'")
                unit = text_value
            elif setting not in ("CYCLES", "POSITIONS"):  # written anew from the data
                meta[f"ecmc.{setting}"] = text_value
        else:
            comments.append(line)
    if comments:
        meta["ecmc.comments"] = " | ".join(comments)
    unit = unit or ("deg" if kind == "rotary" else "mm")
    if len(targets) < 2:
        raise FormatError(f"{name}: fewer than 2 TGT_DATA lines (not an ecmc ISO 230-2 file?)")
    order = sorted(targets)
    if order != list(range(1, len(order) + 1)):
        raise FormatError(f"{name}: the TGT_DATA indices must run 1..{len(order)}, found {order}")
    values = [targets[i] for i in order]
    if any(b <= a for a, b in itertools.pairwise(values)):
        raise FormatError(f"{name}: the targets TGT_DATA[1..{len(values)}] must increase")
    if not readings:
        raise FormatError(f"{name}: no REF_DATA_FWD or REF_DATA_BWD lines")
    scale = DEVIATION_SCALE[unit]
    rows = []
    for (direction, i, j), (reading, number) in sorted(readings.items(), key=lambda kv: kv[1][1]):
        if i not in targets:
            raise FormatError(f"{name}: line {number}: REF_DATA_{direction}[{i},{j}] has no TGT_DATA[{i}]")
        if j < 1:
            raise FormatError(f"{name}: line {number}: cycle {j}: cycles count from 1")
        rows.append(Row(j, 1 if direction == "FWD" else -1, i - 1, (reading - targets[i]) * scale))
    meta.setdefault("unit", unit)
    return Measurement(KINDS[unit], tuple(values), tuple(rows), meta)


def render(m: Measurement) -> str:
    """The ecmc text of `m`: metadata as `# key: value` comments, UNIT, CYCLES, POSITIONS, then per
    cycle the targets and readings (reading = target + deviation)."""
    unit = "mm" if m.kind == "linear" else "deg"
    scale = DEVIATION_SCALE[unit]
    lines = ["# ISO 230-2 data, ecmc layout, written by axiscal"]
    lines += [f"# {key}: {value}" for key, value in m.meta.items()
              if not key.startswith("ecmc.") and key != "unit"]
    lines += [f"{key[5:]}={value}" for key, value in m.meta.items()
              if key.startswith("ecmc.") and key != "ecmc.comments"]
    lines += [f"UNIT={unit}", f"CYCLES={m.runs}", f"POSITIONS={len(m.targets)}"]
    lines += [f"TGT_DATA[{i + 1}]={t:.{DECIMALS}f}" for i, t in enumerate(m.targets)]
    for row in sorted(m.rows, key=lambda r: (r.run, -r.direction, r.target * r.direction)):
        tag = "FWD" if row.direction > 0 else "BWD"
        reading = m.targets[row.target] + row.deviation / scale
        lines.append(f"REF_DATA_{tag}[{row.target + 1},{row.run}]={reading:.{DECIMALS}f}")
    return "\n".join(lines) + "\n"

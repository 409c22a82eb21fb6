"""Read back a table `axiscal compensate` wrote, in any of its formats, for `verify`."""

from __future__ import annotations

import hashlib
import json
import math
import re
from pathlib import Path

import numpy as np

from campaign.compensation.grid import AXIS_UNIT_PER_DEVIATION_UNIT, ControllerTable
from campaign.errors import InputError, read_input_bytes
from protocols.tables import FORMATS, FormatOptions, sniff
from protocols.tables import parse as parse_table
from protocols.tables.fanuc import parse as fanuc_parse

KINDS = {"mm": "linear", "deg": "rotary"}


PROVENANCE_COMMENT = re.compile(r"^\s*[#;]\s*(campaign|measured|written|points|machine|axis|software):\s*(.*?)\s*$")
"""A provenance line as compensate writes it where the format has comments (`# key: value` or
`; key: value`, protocols/tables provenance_lines)."""


def read_comp_provenance(path: str | Path) -> dict[str, str]:
    """The provenance of a table compensate wrote (campaign, measured, written, points file,
    machine, axis, software): the JSON file's `provenance`, or the comment lines of the formats that
    have comments (csv, twincat_cnc, siemens, pmac); empty for formats without comments and older
    files."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return {}
    try:
        doc = json.loads(text)
    except json.JSONDecodeError:
        return {m.group(1): m.group(2) for line in text.splitlines() if (m := PROVENANCE_COMMENT.match(line))}
    value = doc.get("provenance") if isinstance(doc, dict) else None
    return {str(k): str(v) for k, v in value.items()} if isinstance(value, dict) else {}


KEPT_TABLE = "compensation-table"
"""The name (plus the table's own suffix) under which verify keeps the table file it was given in
the campaign directory, byte for byte."""


def table_identity(path: str | Path, fmt: str | None) -> dict[str, str]:
    """What names a table file for the record and the report: its file name and absolute path, its
    format (given, else recognised from its text), its SHA-256 and the provenance it carries
    (`read_comp_provenance`: the campaign it was computed from, when that was measured, when the
    table was written, machine and axis)."""
    raw = read_input_bytes(path, "a compensation table")
    text = raw.decode("utf-8-sig", errors="replace")
    found = fmt or sniff(text) or "unknown"
    identity = {"name": Path(path).name, "path": str(Path(path).resolve()), "format": found,
                "sha256": hashlib.sha256(raw).hexdigest()}
    identity.update({f"source_{k}": v for k, v in read_comp_provenance(path).items() if v})
    return identity


def read_comp_json(path: str | Path) -> ControllerTable:
    """The ControllerTable in a compensate JSON file; InputError naming the file and key."""
    name = str(path)
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{name}: not a compensation JSON file ({exc})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{name}: not a compensation JSON file (write it with --format json)")

    def number(key: str, positive: bool = False) -> float:
        value = doc.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or (positive and value <= 0):
            raise InputError(f"{name}: key '{key}' must be a {'positive ' if positive else ''}number")
        return float(value)

    def values(key: str) -> np.ndarray:
        v = doc.get(key)
        if not isinstance(v, list) or len(v) < 2 or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v):
            raise InputError(f"{name}: key '{key}' must be a list of at least 2 numbers")
        return np.array(v, dtype=float)

    if doc.get("position_unit") not in KINDS:
        raise InputError(f"{name}: key 'position_unit' must be mm or deg")
    forward, reverse, common = values("forward"), values("reverse"), values("common")
    if not len(forward) == len(reverse) == len(common):
        raise InputError(f"{name}: 'forward', 'reverse' and 'common' differ in length")
    backlash = doc.get("backlash")
    reference = doc.get("reference")
    return ControllerTable(KINDS[doc["position_unit"]], number("start"), number("spacing", True), forward, reverse,
                           common, str(doc.get("mode", "bi")),
                           None if backlash is None else number("backlash"),
                           number("overrun") if doc.get("overrun") is not None else 0.0,
                           None if reference is None else number("reference"))


def table_units_note(path: str | Path, fmt: str | None, units: str | None) -> str | None:
    """What the user is told about the unit a table is read in: LinuxCNC tables carry no unit (the
    machine's INI says LINEAR_UNITS), so without `units` (mm or inch) the assumption is said; the
    other formats name their unit (mm, µm, counts) and take no `units` (InputError)."""
    if fmt is None:
        raw = read_input_bytes(path, "a compensation table")
        fmt = sniff(raw.decode("utf-8-sig", errors="replace"))
    if fmt != "linuxcnc":
        if units is not None:
            raise InputError(f"--units applies to LinuxCNC tables, whose files carry no unit; {path} is {fmt}")
        return None
    if units is None:
        return (f"{path}: a LinuxCNC table carries no unit; read in mm (an inch machine, LINEAR_UNITS = inch: "
                "give --units inch)")
    return None


SPIKE_FACTOR = 10.0
"""A step between neighbouring table points more than this many times the table's median step is
a spike (a typing error, a table in the wrong unit, a point measured wrong)."""
SPIKE_FLOOR = 10.0
"""...and more than this, deviation unit (µm, arcsec): smaller steps are within what a screw shows."""


def table_spikes(table: ControllerTable, name: str) -> list[str]:
    """One warning per direction whose table has a step between neighbours far beyond the others
    (SPIKE_FACTOR times the median step and above SPIKE_FLOOR): worth a look before it is loaded."""
    warnings = []
    unit = "µm" if table.kind == "linear" else "arcsec"
    for label, values in (("forward", table.forward), ("reverse", table.reverse)):
        steps = np.abs(np.diff(values))
        if len(steps) < 2:
            continue
        i = int(np.argmax(steps))
        limit = max(SPIKE_FACTOR * float(np.median(steps)), SPIKE_FLOOR)
        if steps[i] > limit:
            positions = table.positions
            warnings.append(f"{name}: the {label} table steps by {steps[i]:.1f} {unit} between "
                            f"{positions[i]:g} and {positions[i + 1]:g} (the median step is "
                            f"{float(np.median(steps)):.2f} {unit}): a spike, or a table in another unit?")
            if table.mode == "uni":
                break  # one table for both directions: said once
    return warnings


def read_comp_table(path: str | Path, kind: str, fmt: str | None = None,
                    options: FormatOptions | None = None, reference: float = 0.0) -> ControllerTable:
    """Any table `axiscal compensate` writes, as a ControllerTable for an axis of `kind`. `fmt`:
    one of protocols.tables.FORMATS, else recognised from the text. pmac and fanuc need
    `options.counts_per_unit`; fanuc's positions count from `reference` (axis unit).
    InputError or FormatError naming the file and line."""
    name = str(path)
    options = options or FormatOptions()
    raw = read_input_bytes(path, "a compensation table")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{name}: not a text file (a compensation table is text)") from None
    fmt = fmt or sniff(text)
    if fmt is None:
        raise InputError(f"{name}: not a table axiscal writes (give --comp-format: {', '.join(FORMATS)})")
    if fmt == "json":
        return read_comp_json(path)
    if fmt == "linuxcnc" and kind == "rotary" and options.units == "inch":
        raise InputError(f"{name}: a rotary joint's table is in degrees; --units inch is for a linear axis")
    read = (fanuc_parse(text, name, options, reference) if fmt == "fanuc" else parse_table(fmt, text, name, options))
    if read.kind is not None and read.kind != kind:
        raise InputError(f"{name}: a {read.kind} table does not fit the {kind} axis")
    per = AXIS_UNIT_PER_DEVIATION_UNIT[kind]
    forward, reverse = np.array(read.forward) / per, np.array(read.reverse) / per
    return ControllerTable(kind, read.start, read.spacing, forward, reverse, (forward + reverse) / 2, read.mode, None)

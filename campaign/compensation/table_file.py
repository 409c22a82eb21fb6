"""Read back the table `axiscal compensate --format json` wrote, for `verify`."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from campaign.compensation.grid import ControllerTable
from campaign.errors import InputError

KINDS = {"mm": "linear", "deg": "rotary"}


def read_comp_provenance(path: str | Path) -> dict[str, str]:
    """The `provenance` of a compensate JSON file (machine, axis, points file, software); empty
    for a file written before axiscal recorded it."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    value = doc.get("provenance") if isinstance(doc, dict) else None
    return {str(k): str(v) for k, v in value.items()} if isinstance(value, dict) else {}


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

    def number(key, positive=False):
        value = doc.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or (positive and value <= 0):
            raise InputError(f"{name}: key '{key}' must be a {'positive ' if positive else ''}number")
        return float(value)

    def values(key):
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

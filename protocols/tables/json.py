"""axiscal's own JSON: the whole table with its units and sign convention spelled out."""

from __future__ import annotations

import json

from protocols.tables import CorrectionTable, FormatOptions, Rendered
from protocols.units import UNITS


def render(table: CorrectionTable, options: FormatOptions) -> Rendered:
    pos_unit, dev_unit = UNITS[table.kind]
    doc = {
        "sign": "correction = value added to the commanded position; about -(measured - target)",
        "position_unit": pos_unit, "correction_unit": dev_unit, "mode": table.mode,
        "start": table.start, "spacing": table.spacing, "overrun": table.overrun,
        "reference": table.reference, "backlash": table.backlash,
        "positions": [float(p) for p in table.positions],
        "forward": [float(v) for v in table.forward], "reverse": [float(v) for v in table.reverse],
        "common": [float(v) for v in table.common],
        "provenance": dict(options.provenance),
    }
    return Rendered(json.dumps(doc, indent=1, allow_nan=False) + "\n")

"""Other programs' measurement files (pure text in, text out; no I/O).

Each module has `parse(text, name, kind) -> Measurement` and `render(measurement) -> str`:
`rtl` (Renishaw .rtl, ISO linear layout), `ecmc` (EPICS ecmc `*_ISO230.dat`). `campaign.convert`
maps a Measurement to and from the point table. docs/convert.md describes both layouts.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Row:
    """One measured point. run: ISO 230-2 run (cycle), from 1. direction: +1 (approach in
    increasing position) or -1. target: index into Measurement.targets, from 0. deviation:
    measured - target, µm (linear) or arcsec (rotary)."""

    run: int
    direction: int
    target: int
    deviation: float


@dataclass(frozen=True)
class Measurement:
    """kind: linear or rotary. targets: the target positions, mm or degrees, increasing.
    rows: every point, in the file's order. meta: what the file says about the measurement, by
    the point table's metadata keys where one exists (machine, serial, axis, date, operator,
    location, title, air_temp_c, air_pressure_hpa, humidity_pct, material_temp_c) and by the
    format's own name otherwise."""

    kind: str
    targets: tuple[float, ...]
    rows: tuple[Row, ...]
    meta: dict[str, str] = field(default_factory=dict)

    @property
    def runs(self) -> int:
        return max((r.run for r in self.rows), default=0)

    @property
    def bidirectional(self) -> bool:
        return any(r.direction < 0 for r in self.rows) and any(r.direction > 0 for r in self.rows)

"""The live reading as a person reads it: the deviation near the target, the distance while moving."""

from __future__ import annotations

from protocols.hardware import Reading
from protocols.units import DEVIATION_SCALE, deviation_label

LIVE_DEVIATION_BAND = 100.0
"""The live deviation is shown within this distance of the target, µm (arcsec); else the distance."""


def live_text(reading: Reading, target: float | None, unit: str) -> str:
    """'reading 300.0012 mm, deviation +1.20 µm' near `target` (mm or deg); while the axis is
    further than LIVE_DEVIATION_BAND away, '… , +12.500 mm to the target' instead: a deviation of
    tens of thousands of µm says nothing. No signal: says so, with no number."""
    if not reading.signal_ok:
        signal = "" if reading.signal_pct is None else f" (signal {reading.signal_pct:.0f} %)"
        return f"[bold red]BEAM LOST[/]{signal}: no valid reading"
    text = f"reading {reading.position:.4f} {unit}"
    if target is not None:
        deviation = (reading.position - target) * DEVIATION_SCALE[unit]
        text += (f", deviation {deviation:+.2f} {deviation_label(unit)}" if abs(deviation) <= LIVE_DEVIATION_BAND
                 else f", {target - reading.position:+.3f} {unit} to the target")
    if reading.signal_pct is not None:
        text += f", signal {reading.signal_pct:.0f} %"
    return text

"""Units of positions and deviations, shared by every format."""

UNITS = {"linear": ("mm", "um"), "rotary": ("deg", "arcsec")}
"""Axis kind -> (position unit, deviation unit)."""

DEVIATION_SCALE = {"mm": 1000.0, "deg": 3600.0}
"""Position unit -> deviation units per position unit (mm -> µm, deg -> arcsec)."""


def unit_label(unit: str) -> str:
    """A unit as people read it: "um" (the files' and JSON's ASCII spelling) is µm."""
    return {"um": "µm"}.get(unit, unit)


def deviation_label(position_unit: str) -> str:
    """The deviation unit people read for an axis in `position_unit`: mm -> µm, deg -> arcsec."""
    return "µm" if position_unit == "mm" else "arcsec"


def counted(n: int, noun: str) -> str:
    """A count as people say it: "1 run", "5 runs" (`noun` singular; the plural adds s)."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"

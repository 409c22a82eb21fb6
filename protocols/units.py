"""Units of positions and deviations, shared by every format."""

UNITS = {"linear": ("mm", "um"), "rotary": ("deg", "arcsec")}
"""Axis kind -> (position unit, deviation unit)."""

DEVIATION_SCALE = {"mm": 1000.0, "deg": 3600.0}
"""Position unit -> deviation units per position unit (mm -> µm, deg -> arcsec)."""

"""axiscal: measurement campaigns for pitch-error (lead-screw) compensation of a machine axis."""

__version__ = "0.1.0"

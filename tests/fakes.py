"""The fast tier's machine is the product's fake machine (drivers/fake.py), re-exported here with
the small campaign the executor tests run on it."""

from drivers.fake import AxisFault, FakeAxis, FakeClock, FakeLaser, FakeMachine, FakeParts, linear_error_um

__all__ = ["SMALL", "AxisFault", "FakeAxis", "FakeClock", "FakeLaser", "FakeMachine", "FakeParts", "linear_error_um"]

SMALL = """
[campaign]
machine = "fake"
tolerance = 10.0
[axis]
soft_limit_min = -5.0
soft_limit_max = 105.0
max_velocity = 50.0
[plan]
targets = [0.0, 50.0, 100.0]
overrun = 2.0
cycles = 2
dwell_s = 1.0
velocity = 25.0
[capture]
average_s = 0.5
"""
"""A 12-point campaign (3 targets × 2 directions × 2 runs) that takes about 40 s of fake time."""

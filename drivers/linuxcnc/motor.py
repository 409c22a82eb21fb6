"""What the simulated laser needs of the machine, read from LinuxCNC's HAL: the joint's motor
position command (the joint command plus LinuxCNC's own compensation), when the axis arrived and
from which side. Duck-types the simulated PLC for drivers.sim.machine.SimAxisPhysics."""

from __future__ import annotations

import math

from drivers.linuxcnc.process import LinuxCnc

STILL_MM = 1e-7
"""A motor position that changes less than this between two reads is at rest, mm."""


class LinuxCncMotor:
    """setpoint_position(t): joint.0.motor-pos-cmd (mm), read from HAL. arrival_time: when it came
    to rest (s on the campaign clock), None while moving. last_direction: +1/-1, the last motion's."""

    def __init__(self, linuxcnc: LinuxCnc):
        self.linuxcnc = linuxcnc
        self.arrival_time: float | None = None
        self.last_direction = 1
        self._last: float | None = None

    def setpoint_position(self, t: float) -> float:
        x = float(self.linuxcnc.getp("joint.0.motor-pos-cmd"))
        if self._last is not None and abs(x - self._last) > STILL_MM:
            self.last_direction = 1 if x > self._last else -1
            self.arrival_time = None
        elif self._last is not None and self.arrival_time is None:
            self.arrival_time = t
        self._last = x
        return x if math.isfinite(x) else 0.0

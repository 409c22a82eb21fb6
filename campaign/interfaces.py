"""The small interfaces through which the campaign talks to hardware.

`campaign/` never imports pyads or serial: the drivers in `drivers/` implement these protocols, and
the simulated machine in `drivers/sim/` implements them too.

Units: positions are in the axis unit, mm for a linear axis and degrees for a rotary axis;
velocities in axis unit per second; times in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


class AxisError(Exception):
    """The controller reported an axis error, or the connection to it failed.

    `error_id` is the controller's error number (0 when there is none, e.g. a lost connection).
    """

    def __init__(self, message: str, error_id: int = 0):
        super().__init__(message)
        self.error_id = error_id


class InstrumentError(Exception):
    """The interferometer stopped answering, or its port went away."""


@dataclass(frozen=True)
class AxisStatus:
    """One snapshot of the axis status symbols.

    actual_position: the controller's actual position, axis unit (mm or deg).
    error_id: the controller's error number, 0 when there is no error.
    """

    busy: bool
    done: bool
    error: bool
    error_id: int
    actual_position: float
    enabled: bool
    homed: bool = True


@dataclass(frozen=True)
class Reading:
    """One interferometer sample.

    time_s: the instrument's own timestamp, s.
    position: the measured position, axis unit (mm or deg), as the instrument reports it.
    signal_ok: True when the beam is OK (signal strength above the instrument's threshold).
    signal_pct: signal strength in % of full scale, or None when the instrument gives only a flag.
    air_temp_c (°C), air_pressure_hpa (hPa), humidity_pct (% RH), material_temp_c (°C): None when
    the line carries no such field.
    """

    time_s: float
    position: float
    signal_ok: bool
    signal_pct: float | None = None
    air_temp_c: float | None = None
    air_pressure_hpa: float | None = None
    humidity_pct: float | None = None
    material_temp_c: float | None = None


class Clock(Protocol):
    """Wall time on real hardware, simulated time on the simulated machine."""

    def now(self) -> float:
        """Seconds since an arbitrary epoch (monotonic)."""
        ...

    def sleep(self, seconds: float) -> None:
        """Let `seconds` pass. On the simulated machine this advances the simulation."""
        ...


class Axis(Protocol):
    """One axis owned by a controller. The controller runs the motion; the PC only asks."""

    def status(self) -> AxisStatus:
        """Read busy, done, error, error id, actual position, enabled and homed at once."""
        ...

    def start_move(self, position: float, velocity: float) -> None:
        """Command an absolute move to `position` (axis unit) at `velocity` (axis unit/s).

        Returns at once; poll `status()` until done or error. Raises AxisError when the command
        cannot be sent.
        """
        ...

    def halt(self) -> None:
        """Stop the axis with a controlled deceleration. Safe to call at any time, also twice."""
        ...

    def reset(self) -> None:
        """Clear an axis error so that the next move can be commanded."""
        ...

    def close(self) -> None:
        """Release the connection. The axis is halted first if it is moving."""
        ...


class Interferometer(Protocol):
    """A laser interferometer on a serial line (or its simulation)."""

    skipped_lines: int
    """Lines skipped as partial or garbage since the driver was opened."""

    def poll(self) -> list[Reading]:
        """The readings that arrived since the last call (streaming mode), or one fresh reading
        (query mode). Never blocks longer than the driver's timeout. Raises InstrumentError when
        the port is gone or a query goes unanswered."""
        ...

    def close(self) -> None:
        """Release the port."""
        ...

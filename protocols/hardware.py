"""The small interfaces through which the campaign talks to hardware, and the data they pass.

Both sides import this module: `campaign/` uses the protocols, `drivers/` implements them (the real
ADS axis and serial interferometer, and the simulated machine). It imports nothing of either.

Units: positions are in the axis unit, mm for a linear axis and degrees for a rotary axis;
velocities in axis unit per second; times in seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from protocols.plc_contract import CompTable


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


ENV_FIELDS = ("air_temp_c", "air_pressure_hpa", "humidity_pct", "material_temp_c")
"""The environment fields of a Reading, in their order on the serial line and in the files."""


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

    def write_comp_table(self, table: CompTable) -> None:
        """Write the controller's compensation table (axis units, protocols/plc_contract.py), read
        it back and compare, then enable it when `table.enabled`. AxisError when it differs."""
        ...

    def read_comp_table(self) -> CompTable | None:
        """The compensation table the controller holds, or None when it holds none."""
        ...


class PositionStream(Protocol):
    """The controller's actual position sampled by the controller itself, with its own time stamps
    (ADS device notifications of the actual position; the samples a scan aligns against)."""

    def take(self) -> list[tuple[float, float]]:
        """The samples since the last call, oldest first: (the controller's time of the sample, s on
        its own clock; actual position, axis unit). AxisError when the stream ended (connection lost)."""
        ...

    def close(self) -> None:
        """End the stream. Safe to call twice."""
        ...


@runtime_checkable
class StreamingAxis(Axis, Protocol):
    """An axis whose controller can stream its actual position (a scan needs one)."""

    def stream_positions(self, cycle_s: float = 0.0, max_delay_s: float = 0.05) -> PositionStream:
        """Start streaming: a sample every `cycle_s` of the controller (0: every controller cycle),
        each sent at most `max_delay_s` after it was taken. AxisError when the controller refuses."""
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


@dataclass
class Hardware:
    """What a campaign runs on. `closers` are called in reverse order by `close()`, which releases
    everything (the axis is halted first by its own close)."""

    axis: Axis
    interferometer: Interferometer
    clock: Clock
    closers: list[Callable[[], None]] = field(default_factory=list)

    def close(self) -> list[str]:
        """Close everything, in reverse order of opening, even when one part fails (e.g. the
        PLC is unreachable and the axis cannot be asked whether it moves). Returns the failures."""
        failures = []
        for close in reversed(self.closers):
            try:
                close()
            except Exception as exc:  # noqa: BLE001 - every part must get its chance to close
                failures.append(f"{type(exc).__name__}: {exc}")
        self.closers.clear()
        return failures

"""A fake machine in-process: an axis, a laser and a clock that implement protocols/hardware.py
without a PLC, an ADS server, a pty or a socket.

`FakeMachine` is a campaign.measure.Opener. The executor's fast tests run on it (retry, skip,
abort, pause, beam loss, a full disk, resume), `bench/` measures the executor's own cost on it,
and `axiscal demo --fake` runs the demo campaign on it in about a second. Nothing imports this
module at run time unless asked: `drivers.factory.fake_opener()` imports it when a command
wants the fake (an import-linter contract in pyproject.toml keeps it so).

Time is simulated: `FakeClock.sleep` advances it and moves the axis. The axis moves at the
commanded velocity (no ramps); the laser reads one sample per 1/rate_hz s: the axis position plus
`error_um(x, direction, t, wait)` (µm; t the clock's time, wait the time since the axis arrived,
s). Positions in axis unit (mm or deg), times in s. Unlike the simulated machine it draws no noise:
the same campaign gives the same table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from campaign.model import ErrorModel, sim_model
from campaign.specs import DriverSpec
from drivers.sim.machine import SimAxisPhysics
from protocols.hardware import AxisError, AxisStatus, Hardware, InstrumentError, Reading
from protocols.plc_contract import CompTable
from protocols.units import DEVIATION_SCALE


class ErrorFunction(Protocol):
    """The fake axis's error at position x (axis unit), approached in `direction` (+1/-1), at
    time t (s), `wait` s after it arrived: µm (arcsec on a rotary axis)."""

    def __call__(self, x: float, direction: int, t: float, wait: float) -> float: ...


class FakeClock:
    """Simulated time: `sleep(dt)` advances it and calls the listeners with the new time (s)."""

    def __init__(self, start_s: float = 0.0) -> None:
        self.t = start_s
        self.listeners: list[Callable[[float], None]] = []

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += max(seconds, 0.0)
        for listener in self.listeners:
            listener(self.t)


@dataclass
class AxisFault:
    """An axis error `error_id` that latches during the `move`-th commanded move (1-based)."""

    move: int
    error_id: int = 0x4550


class FakeAxis:
    """Moves at the commanded velocity; records every command (`moves`, `halts`, `resets`).
    `faults`: AxisFaults to latch; `offline`: (start, end) s windows in which the connection is
    lost (AxisError with error id 0)."""

    def __init__(self, clock: FakeClock, position: float = 0.0) -> None:
        self.clock = clock
        self.position = position
        self.target = position
        self.velocity = 0.0
        self.direction = 1
        self.error_id = 0
        self.arrival_time: float | None = clock.now()
        """When the axis came to rest, s (None while it moves): drivers.sim.machine.Motor."""
        self.moves: list[tuple[float, float]] = []
        self.halts = 0
        self.resets = 0
        self.faults: list[AxisFault] = []
        self.offline: list[tuple[float, float]] = []
        self.comp: CompTable | None = None
        self.closed = False
        self._last = clock.now()
        clock.listeners.append(self._advance)

    def _online(self) -> None:
        if any(a <= self.clock.now() < b for a, b in self.offline):
            raise AxisError("connection lost (fake)", 0)

    def _advance(self, t: float) -> None:
        dt, self._last = t - self._last, t
        if self.error_id or self.position == self.target:
            return
        step = self.velocity * dt
        if abs(self.target - self.position) <= step:
            self.position = self.target
            self.arrival_time = t
        else:
            self.position += step * (1 if self.target > self.position else -1)

    @property
    def last_direction(self) -> int:
        """The last motion's direction, +1 or -1 (drivers.sim.machine.Motor)."""
        return self.direction

    def setpoint_position(self, t: float) -> float:
        """Where the axis is commanded to be now (axis unit; the fake follows it exactly)."""
        return self.position

    def status(self) -> AxisStatus:
        self._online()
        moving = self.position != self.target and not self.error_id
        return AxisStatus(busy=moving, done=not moving and not self.error_id, error=bool(self.error_id),
                          error_id=self.error_id, actual_position=self.position, enabled=True)

    def start_move(self, position: float, velocity: float) -> None:
        self._online()
        self.moves.append((position, velocity))
        if position != self.position:
            self.direction = 1 if position > self.position else -1
            self.arrival_time = None
        self.target, self.velocity = position, velocity
        for fault in self.faults:
            if fault.move == len(self.moves):
                self.error_id = fault.error_id

    def halt(self) -> None:
        self._online()
        self.halts += 1
        self.target = self.position

    def reset(self) -> None:
        self._online()
        self.resets += 1
        self.error_id = 0

    def close(self) -> None:
        self.closed = True

    def write_comp_table(self, table: CompTable) -> None:
        self.comp = table

    def read_comp_table(self) -> CompTable | None:
        return self.comp


class FakeLaser:
    """One reading per 1/rate_hz s: the axis position plus error_um(...) / DEVIATION_SCALE, or,
    with `physics`, what the simulated machine's physics reads there (its error model with its
    scatter and reading noise, seeded, and its room's slowly swinging environment).
    `beam_off`: (start, end) s windows without the beam, whose readings are 1 axis unit off
    (averaging one would show); `gone_at`: the port vanishes then (InstrumentError);
    `garbage_at`: {time s: lines} of garbage serial lines counted as skipped; `offset`: a datum
    shift, axis unit (a laser re-zeroed elsewhere); `env`: the environment fields every reading
    carries."""

    def __init__(self, clock: FakeClock, axis: FakeAxis, rate_hz: float, error_um: ErrorFunction,
                 scale: float = DEVIATION_SCALE["mm"], env: dict[str, float] | None = None,
                 physics: SimAxisPhysics | None = None) -> None:
        self.clock, self.axis, self.period = clock, axis, 1.0 / rate_hz
        self.error_um, self.scale, self.physics = error_um, scale, physics
        self.env = dict(env or {})
        self.beam_off: list[tuple[float, float]] = []
        self.gone_at: float | None = None
        self.skipped_lines = 0
        self.offset = 0.0
        self.garbage_at: dict[float, int] = {}
        self.closed = False
        self._pending: list[Reading] = []
        self._next = clock.now() + self.period
        clock.listeners.append(self._advance)

    def _advance(self, t: float) -> None:
        while self._next <= t + 1e-9:
            ok = not any(a <= self._next < b for a, b in self.beam_off)
            self._pending.append(self._reading(self._next, ok))
            for at, lines in list(self.garbage_at.items()):
                if at <= self._next:
                    self.skipped_lines += lines
                    del self.garbage_at[at]
            self._next += self.period

    def _reading(self, t: float, ok: bool) -> Reading:
        bad = 0.0 if ok else 1.0
        signal = 90.0 if ok else 0.0
        if self.physics is not None:
            m = self.physics.measure(t)
            return Reading(t, m["position"] + self.offset + bad, ok, signal, m["air_temp_c"], m["air_pressure_hpa"],
                           m["humidity_pct"], m["material_temp_c"])
        x, arrived = self.axis.position, self.axis.arrival_time
        wait = 0.0 if arrived is None else max(0.0, t - arrived)
        position = x + self.offset + self.error_um(x, self.axis.direction, t, wait) / self.scale + bad
        return Reading(t, position, ok, signal, **self.env)

    def poll(self) -> list[Reading]:
        if self.gone_at is not None and self.clock.now() >= self.gone_at:
            raise InstrumentError("the port went away (fake)")
        out, self._pending = self._pending, []
        return out

    def close(self) -> None:
        self.closed = True


def linear_error_um(x: float, direction: int, t: float = 0.0, wait: float = 0.0) -> float:
    """10 µm/m of scale error and 2 µm of backlash (e = -d·b/2), µm at x mm."""
    return 0.010 * x - direction * 1.0


@dataclass
class FakeParts:
    """The fake machine's parts (what a test may poke at), and its state for the session
    (campaign.measure.MachineParts): it keeps no files; the recorder's disk-full hook fires at
    the machine's `disk_full_at_s` when one is set."""

    clock: FakeClock
    axis: FakeAxis
    laser: FakeLaser
    disk_full_at_s: float | None = None
    inject_disk_full: Callable[[], None] | None = field(default=None, repr=False)

    def kept_files(self) -> dict[str, str]:
        return {}

    def bind_recorder(self, inject_disk_full: Callable[[], None]) -> None:
        self.inject_disk_full = inject_disk_full
        if self.disk_full_at_s is not None:
            self.clock.listeners.append(self._disk_full_at)

    def _disk_full_at(self, t: float) -> None:
        if self.disk_full_at_s is not None and t >= self.disk_full_at_s and self.inject_disk_full is not None:
            self.disk_full_at_s = None  # once
            self.inject_disk_full()


class FakeMachine:
    """An Opener (campaign.measure.Opener) of fake machines. `error_um`: the laser's error (by
    default 10 µm/m and 2 µm of backlash, `linear_error_um`, no noise); None: the simulated
    machine's physics instead (drivers.sim.machine.SimAxisPhysics: the campaign's error model, or
    `model`, with its seeded scatter, reading noise and environment); `setup(parts)`: configures each machine before it is
    returned (faults, beam cuts, ...); `disk_full_at_s`: the recorder's next point write fails
    then (s of machine time). `openings`: every machine opened, in order."""

    def __init__(self, error_um: ErrorFunction | None = linear_error_um,
                 setup: Callable[[FakeParts], None] | None = None, disk_full_at_s: float | None = None) -> None:
        self.error_um = error_um
        self.setup = setup
        self.disk_full_at_s = disk_full_at_s
        self.openings: list[FakeParts] = []

    def __call__(self, spec: DriverSpec, speed: float | None = None, model: ErrorModel | None = None,
                 start_position: float | None = None, start_time: float = 0.0, comp: CompTable | None = None,
                 kept_dir: Path | None = None) -> tuple[Hardware, FakeParts]:
        """Open a fake machine at `start_position` (axis unit; default the spec's) and `start_time`
        (s), with `comp` written into its axis. `speed` and `kept_dir` change nothing: fake time
        costs no wall time and the fake keeps no files."""
        clock = FakeClock(start_time)
        start = start_position if start_position is not None else spec.start_position
        axis = FakeAxis(clock, start)
        physics = None
        if self.error_um is None:
            physics = SimAxisPhysics(axis, model or sim_model(spec.sim), spec.axis.unit, spec.sim.seed,
                                     vacuum_readings=spec.vacuum_readings)
        laser = FakeLaser(clock, axis, spec.instrument.rate_hz, self.error_um or linear_error_um,
                          DEVIATION_SCALE[spec.axis.unit], physics=physics)
        parts = FakeParts(clock, axis, laser, self.disk_full_at_s)
        if self.setup is not None:
            self.setup(parts)
        self.openings.append(parts)
        if comp is not None:
            axis.write_comp_table(comp)
        return Hardware(axis, laser, clock, [axis.close, laser.close]), parts

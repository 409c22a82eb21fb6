"""An in-process fake axis, fake laser and fake clock for the fast tier: the executor's logic
(retry, skip, abort, pause, beam loss, disk full, resume) without an ADS server or a pty.

They implement protocols/hardware.py exactly as the drivers do, and `fake_opener` is a
campaign.measure.session.Opener. Time is simulated: `FakeClock.sleep` advances it and moves the
axis. The axis moves at the commanded velocity (no ramps); the laser reads the axis position
plus `error_um(x, direction)` (µm), one reading per 1/rate_hz s. Positions in mm, times in s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from campaign.specs import DriverSpec
from protocols.hardware import AxisError, AxisStatus, Hardware, InstrumentError, Reading


class FakeClock:
    def __init__(self, start_s: float = 0.0):
        self.t = start_s
        self.listeners = []

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
    """Moves at the commanded velocity; records every command. `faults`: AxisFaults to raise;
    `offline`: (start, end) s windows in which the connection is lost."""

    def __init__(self, clock: FakeClock, position: float = 0.0):
        self.clock = clock
        self.position = position
        self.target = position
        self.velocity = 0.0
        self.direction = 1
        self.error_id = 0
        self.moves: list[tuple[float, float]] = []
        self.halts = 0
        self.resets = 0
        self.faults: list[AxisFault] = []
        self.offline: list[tuple[float, float]] = []
        self.comp = None
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
        else:
            self.position += step * (1 if self.target > self.position else -1)

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

    def write_comp_table(self, table) -> None:
        self.comp = table

    def read_comp_table(self):
        return self.comp


class FakeLaser:
    """One reading per 1/rate_hz s: the axis position plus error_um(x, direction) / 1000 mm.
    `beam_off`: (start, end) s windows without the beam, whose readings are 1 mm off (averaging
    one would show); `gone_at`: the port vanishes then."""

    def __init__(self, clock: FakeClock, axis: FakeAxis, rate_hz: float, error_um, env: dict | None = None):
        self.clock, self.axis, self.period = clock, axis, 1.0 / rate_hz
        self.error_um = error_um
        self.env = env or {}
        self.beam_off: list[tuple[float, float]] = []
        self.gone_at: float | None = None
        self.skipped_lines = 0
        self.offset = 0.0
        """A datum shift, mm (a laser re-zeroed elsewhere)."""
        self.garbage_at: dict[float, int] = {}
        self.closed = False
        self._pending: list[Reading] = []
        self._next = clock.now() + self.period
        clock.listeners.append(self._advance)

    def _advance(self, t: float) -> None:
        while self._next <= t + 1e-9:
            x = self.axis.position
            ok = not any(a <= self._next < b for a, b in self.beam_off)
            reading = x + self.offset + self.error_um(x, self.axis.direction) / 1000.0 + (0.0 if ok else 1.0)
            self._pending.append(Reading(self._next, reading, ok, 90.0 if ok else 0.0, **self.env))
            for at, lines in list(self.garbage_at.items()):
                if at <= self._next:
                    self.skipped_lines += lines
                    del self.garbage_at[at]
            self._next += self.period

    def poll(self) -> list[Reading]:
        if self.gone_at is not None and self.clock.now() >= self.gone_at:
            raise InstrumentError("the port went away (fake)")
        out, self._pending = self._pending, []
        return out

    def close(self) -> None:
        self.closed = True


def linear_error_um(x: float, direction: int) -> float:
    """10 µm/m of scale error and 2 µm of backlash (e = -d·b/2)."""
    return 0.010 * x - direction * 1.0


@dataclass
class FakeParts:
    """What a test may poke at (the simulated machine's SimParts play the same role)."""

    clock: FakeClock
    axis: FakeAxis
    laser: FakeLaser
    faults: object = None
    opened: list = field(default_factory=list)


class FakeMachine:
    """An Opener whose hardware the test configures before (`setup(parts)`) each opening."""

    def __init__(self, error_um=linear_error_um, setup=None):
        self.error_um = error_um
        self.setup = setup
        self.openings: list[FakeParts] = []

    def __call__(self, spec: DriverSpec, speed=None, model=None, start_position=None, start_time=0.0, comp=None,
                 kept_dir=None):
        clock = FakeClock(start_time)
        start = start_position if start_position is not None else spec.start_position
        axis = FakeAxis(clock, start)
        laser = FakeLaser(clock, axis, spec.instrument.rate_hz, self.error_um)
        parts = FakeParts(clock, axis, laser)
        if self.setup is not None:
            self.setup(parts)
        self.openings.append(parts)
        if comp is not None:
            axis.write_comp_table(comp)
        return Hardware(axis, laser, clock, [axis.close, laser.close]), parts


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

"""A scan on the simulated machine: the axis moves at constant velocity between the ends of the
travel while two streams are taken, each on its own clock.

- The instrument's stream: the simulated interferometer samples at `rate_hz` of its own clock
  (`InstrumentClock`), which is off the controller's by an unknown offset, runs fast or slow by a
  rate error, wanders slowly, and takes each sample a little off its stamp (sample jitter). Each
  sample reaches the PC a transport latency later (with jitter): `received_s`, on the controller's
  clock, as a PC that stamps what arrives would record it.
- The controller's stream: the actual position (`fActPosition`: the motor position without
  compensation) at every PLC cycle, stamped with the controller's time, as ADS device
  notifications of the actual position would carry it (the notification wiring is not here).

The controller's clock is the simulated clock. Both streams are sampled analytically from the
PLC's motion and `SimAxisPhysics.true_position`, so the PLC cycle need not be the clock's step.
The sampler is attached to the clock before the PLC's scan, so it sees the motion the PLC ran up to
the instant sampled. Times in s, positions in the axis unit (mm or deg).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from campaign.model import ErrorModel
from drivers.sim.clock import SimClock
from drivers.sim.machine import SimAxisPhysics
from drivers.sim.plc import SimPLC
from protocols import plc_contract, plc_layout
from protocols.plc_contract import Command


@dataclass(frozen=True)
class InstrumentClock:
    """The instrument's own sample clock against the controller's.

    offset_s: the instrument clock's reading when the controller's reads 0, s.
    rate_error_ppm: the instrument clock runs (1 + rate_error_ppm·1e-6) times as fast, ppm.
    wander_ppm, wander_period_s: a slow sinusoidal wander of that rate (temperature), ppm and s.
    sample_jitter_s: RMS of the instant a sample is really taken about its stamp, s.
    latency_s, latency_jitter_s: the transport to the PC takes latency_s plus up to
    latency_jitter_s more (uniform), s.
    """

    offset_s: float = 0.0
    rate_error_ppm: float = 0.0
    wander_ppm: float = 0.0
    wander_period_s: float = 600.0
    sample_jitter_s: float = 0.0
    latency_s: float = 0.0
    latency_jitter_s: float = 0.0

    def reading(self, t: np.ndarray | float) -> np.ndarray:
        """The instrument clock's reading at controller time t (s)."""
        t = np.asarray(t, dtype=float)
        w = 2 * math.pi / self.wander_period_s
        wander = self.wander_ppm * 1e-6 * (1 - np.cos(w * t)) / w
        return self.offset_s + (1 + self.rate_error_ppm * 1e-6) * t + wander

    def controller_time(self, stamp: np.ndarray | float) -> np.ndarray:
        """The controller time (s) at which the instrument clock reads `stamp` (s)."""
        stamp = np.asarray(stamp, dtype=float)
        t = (stamp - self.offset_s) / (1 + self.rate_error_ppm * 1e-6)
        for _ in range(3):  # Newton on a rate within ppm of 1
            t = t - (self.reading(t) - stamp) / (1 + self.rate_error_ppm * 1e-6)
        return t


@dataclass
class ScanRecord:
    """What a scan recorded. controller_*: the controller's stream (time s, actual position);
    instrument_*: the instrument's (its own stamp s, reading, arrival at the PC on the
    controller's clock s); true_time_s: when each instrument sample was really taken (the truth,
    for tests)."""

    controller_time_s: np.ndarray
    controller_position: np.ndarray
    instrument_time_s: np.ndarray
    instrument_reading: np.ndarray
    received_s: np.ndarray
    true_time_s: np.ndarray


class ScanSampler:
    """Takes both streams as simulated time advances. Attach before the PLC's scan."""

    def __init__(self, plc: SimPLC, physics: SimAxisPhysics, instrument: InstrumentClock, rate_hz: float,
                 cycle_s: float, start_s: float, seed: int = 0):
        if rate_hz <= 0 or cycle_s <= 0:
            raise ValueError("rate_hz and cycle_s must be > 0")
        self.plc, self.physics, self.instrument = plc, physics, instrument
        self.rate_hz, self.cycle_s = rate_hz, cycle_s
        self.rng = np.random.default_rng([seed, 7])
        self._next_cycle = math.floor(start_s / cycle_s + 1e-9) + 1
        self._next_stamp = math.floor(float(instrument.reading(start_s)) * rate_hz) + 1
        self._ctrl: list[tuple[float, float]] = []
        self._inst: list[tuple[float, float, float, float]] = []

    def on_advance(self, t: float) -> None:
        while self._next_cycle * self.cycle_s <= t + 1e-12:
            tc = self._next_cycle * self.cycle_s
            self._next_cycle += 1
            self._ctrl.append((tc, self.plc.setpoint_position(tc) - self.plc.correction))
        while True:
            stamp = self._next_stamp / self.rate_hz
            taken = float(self.instrument.controller_time(stamp))
            if taken > t:
                break
            self._next_stamp += 1
            if self.instrument.sample_jitter_s:
                taken += float(self.rng.normal(0.0, self.instrument.sample_jitter_s))
            arrival = taken + self.instrument.latency_s + float(self.rng.uniform(0, self.instrument.latency_jitter_s))
            self._inst.append((stamp, self.physics.true_position(taken), arrival, taken))

    def record(self) -> ScanRecord:
        c = np.array(self._ctrl, dtype=float).reshape(-1, 2)
        i = np.array(self._inst, dtype=float).reshape(-1, 4)
        order = np.argsort(i[:, 2], kind="stable")  # as they reach the PC
        i = i[order]
        return ScanRecord(c[:, 0], c[:, 1], i[:, 0], i[:, 1], i[:, 2], i[:, 3])


def _write(plc: SimPLC, member: str, value: float | bool) -> None:
    """What the ADS server does for a client's write of a control member of the PLC's axis."""
    symbol = plc_contract.control_symbols(plc.axis)[member]
    place = plc_layout.require(symbol.name)
    plc.memory[place.offset:place.offset + place.size] = SimPLC._encode(symbol, value)


def _move_and_wait(clock: SimClock, plc: SimPLC, target: float, velocity: float, tick_s: float,
                   timeout_s: float) -> None:
    _write(plc, "fPosition", target)
    _write(plc, "fVelocity", velocity)
    _write(plc, "eCommand", int(Command.MOVE_ABSOLUTE))
    _write(plc, "bExecute", True)
    plc.scan(clock.now())  # the request arrives at a cycle: the motion starts now, as both streams see it
    done = plc_contract.status_symbols(plc.axis)["bDone"].name
    clock.sleep(tick_s)
    end = clock.now() + timeout_s
    while not plc.value(done):
        if clock.now() > end:
            raise TimeoutError(f"the simulated axis did not reach {target} in {timeout_s} s")
        clock.sleep(tick_s)


def run_scan(plc: SimPLC, clock: SimClock, sampler: ScanSampler, low: float, high: float, velocity: float, passes: int, end_dwell_s: float, tick_s: float = 0.01) -> ScanRecord:
    """Scan `passes` times up from `low` to `high` and back at `velocity` (axis unit/s), at rest
    `end_dwell_s` at each end (and before the first pass), commanding the PLC as the executor
    would (a move, then polling bDone every `tick_s`). The axis starts at `low`."""
    timeout = (high - low) / velocity + 10 * velocity / plc.acceleration + 10.0
    clock.sleep(end_dwell_s)
    for _ in range(passes):
        for target in (high, low):
            _move_and_wait(clock, plc, target, velocity, tick_s, timeout)
            clock.sleep(end_dwell_s)
    return sampler.record()


@dataclass
class SimScanMachine:
    """The simulated axis with both scan streams attached, in the order the streams need."""

    clock: SimClock
    plc: SimPLC
    physics: SimAxisPhysics
    sampler: ScanSampler

    def scan(self, low: float, high: float, velocity: float, passes: int, end_dwell_s: float = 1.0,
             tick_s: float = 0.01) -> ScanRecord:
        return run_scan(self.plc, self.clock, self.sampler, low, high, velocity, passes,
                        end_dwell_s, tick_s)


def scan_machine(model: ErrorModel, unit: str, max_velocity: float, acceleration: float, start: float,
                 instrument: InstrumentClock, rate_hz: float, cycle_s: float = 1e-3, seed: int = 1) -> SimScanMachine:
    """A simulated axis at `start` (axis unit) with the error `model`, seeded like the simulated
    machine (`seed`), both streams sampled from time 0 (`cycle_s`: the PLC cycle, s)."""
    clock = SimClock(0.0)
    plc = SimPLC(1, max_velocity, acceleration, position=start)
    physics = SimAxisPhysics(plc, model, unit, seed)
    sampler = ScanSampler(plc, physics, instrument, rate_hz, cycle_s, 0.0, seed)
    clock.attach(sampler.on_advance)
    clock.attach(plc.scan)
    return SimScanMachine(clock, plc, physics, sampler)

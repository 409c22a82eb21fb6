"""Builds the hardware a campaign's DriverSpec asks for: a real PLC and instrument, or the simulated machine.

This is the one place where the campaign's protocols meet pyads and pyserial.
"""

from __future__ import annotations

import contextlib
import os
import random
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from campaign.errors import InputError
from campaign.model import ErrorModel, read_model, sim_model
from campaign.specs import DriverSpec, plain
from drivers.ads_axis import AdsAxis
from drivers.clock import ListenedClock, RealClock
from drivers.serial_interferometer import SerialInterferometer
from protocols.hardware import Axis, Hardware, InstrumentError
from protocols.plc_contract import CompTable

if TYPE_CHECKING:
    from drivers.fake import FakeMachine
    from drivers.sim.ads_server import SimAdsServer
    from drivers.sim.clock import SimClock
    from drivers.sim.epics_ioc import SimMotorIoc
    from drivers.sim.faults import FaultScheduler
    from drivers.sim.interferometer import SimInterferometer
    from drivers.sim.machine import SimAxisPhysics
    from drivers.sim.plc import SimPLC
    from drivers.sim.scan_streams import InstrumentClock


SIM_MODEL_FILE = "sim-model.toml"
"""The simulated machine's effective error model, kept in the campaign directory: a resume reopens
the machine with it (`kept_dir`), whatever the config's model file says by then."""


@dataclass
class SimParts:
    """The simulated machine's parts, for tests and fault injection. As the machine's state for the
    session (campaign.measure.session.MachineParts): the files to keep in the campaign directory,
    and the recorder's disk-full hook for the disk_full fault."""

    clock: SimClock
    plc: SimPLC
    server: SimAdsServer | SimMotorIoc
    """What serves the PLC: the ADS server, or the motor record IOC of the EPICS machine."""
    instrument: SimInterferometer
    physics: SimAxisPhysics
    faults: FaultScheduler | None = None

    def kept_files(self) -> dict[str, str]:
        return {SIM_MODEL_FILE: self.physics.model.to_toml()}

    def bind_recorder(self, inject_disk_full: Callable[[], None]) -> None:
        if self.faults is not None:
            self.faults.on_disk_full = inject_disk_full


def fake_opener() -> FakeMachine:
    """The fake machine (drivers/fake.py: in-process, no socket, no pty) with the campaign's own
    error model, imported only when asked (`axiscal demo --fake`)."""
    from drivers.fake import FakeMachine

    return FakeMachine(error_um=None)


COMP_SEED_OFFSET = 1000
"""A simulated machine opened with a compensation table draws its noise from sim.seed + this: a
new measurement sees new scatter, not the baseline's again."""


def open_hardware(spec: DriverSpec, speed: float | None = None, model: ErrorModel | None = None,
                  start_position: float | None = None, start_time: float = 0.0, comp: CompTable | None = None,
                  kept_dir: Path | None = None) -> tuple[Hardware, SimParts | None]:
    """Open the axis, instrument and clock `spec` names. For the simulated machine also return
    its parts. `speed` overrides `sim.speed`; `model` overrides the config's error model;
    `start_position` (axis unit) and `start_time` (s) are where and when the simulated machine
    starts (a resumed campaign continues where it stopped); `comp`: a compensation table written
    into the controller (read back, compared, enabled) before this returns; `kept_dir`: a campaign
    directory whose kept files (SimParts.kept_files: the simulated machine's model) reopen the
    same machine."""
    if model is None and kept_dir is not None and (kept_dir / SIM_MODEL_FILE).is_file():
        model = read_model(kept_dir / SIM_MODEL_FILE)
    opened = _open(spec, speed, model, start_position, start_time, comp is not None)
    if comp is not None:
        try:
            opened[0].axis.write_comp_table(comp)
        except BaseException:
            opened[0].close()
            raise
    return opened


def _open(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
          start_time: float, compensated: bool) -> tuple[Hardware, SimParts | None]:
    drv = spec.controller
    if drv.type == "ads":
        return with_serial_laser(spec, AdsAxis(drv.ams_net_id, drv.ip, drv.axis_index, drv.ams_port,
                                               read_only=drv.read_only, timeout_s=drv.timeout_s)), None
    if drv.type == "linuxcnc":
        return _open_linuxcnc(spec, model)
    if drv.type == "epics":
        try:
            from drivers.epics.machine import open_epics
        except ImportError as exc:
            raise InputError(f"{spec.source}: axis_driver.type = epics needs caproto: pip install "
                             f"'axiscal[epics]' ({exc})") from None
        return open_epics(spec, speed, model, start_position, start_time, compensated)
    return _open_sim(spec, speed, model, start_position, start_time, compensated)


def with_serial_laser(spec: DriverSpec, axis: Axis) -> Hardware:
    """A real controller's `axis` with the laser on the config's serial port, on the wall clock;
    `axis` is closed again when the port cannot be opened (InputError)."""
    inst = spec.instrument
    try:
        interferometer = SerialInterferometer(inst.port, inst.baudrate, inst.line, inst.mode, inst.timeout_s)
    except InstrumentError as exc:
        axis.close()
        raise InputError(f"{spec.source}: instrument.port: cannot open {inst.port}: {exc}") from None
    return Hardware(axis, interferometer, RealClock(), [axis.close, interferometer.close])


def sim_machine(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
                start_time: float, compensated: bool, axis_index: int) -> tuple[SimClock, SimPLC, SimAxisPhysics]:
    """The simulated machine behind whatever serves it: its clock (`speed` or sim.speed times real
    time, from `start_time` s), its PLC axis `axis_index` at `start_position` (or the config's)
    with its compensation function block (idle until a table is enabled), and its physics (the
    error model `model` or the config's; noise from sim.seed, + COMP_SEED_OFFSET when
    `compensated`)."""
    from drivers.sim.compensation import SimCompensation
    from drivers.sim.machine import SimAxisPhysics, make_clock
    from drivers.sim.plc import SimPLC

    axis_spec = spec.axis
    clock = make_clock(speed if speed is not None else spec.sim.speed, start_time)
    start = spec.start_position if start_position is None else start_position
    plc = SimPLC(axis_index, axis_spec.max_velocity, axis_spec.max_acceleration, position=start,
                 start_time=start_time)
    clock.attach(plc.scan)
    clock.attach(SimCompensation(plc, clock.now()).tick)  # FB_AxiscalCompensation: idle until a table is enabled
    seed = spec.sim.seed + (COMP_SEED_OFFSET if compensated else 0)
    physics = SimAxisPhysics(plc, model or sim_model(spec.sim), axis_spec.unit, seed,
                             vacuum_readings=spec.vacuum_readings)
    return clock, plc, physics


def sim_hardware(spec: DriverSpec, clock: SimClock | ListenedClock, physics: SimAxisPhysics, open_axis: Callable[[], Axis],
                 closers: list[Callable[[], None]], compensated: bool = False) -> tuple[Hardware, SimInterferometer]:
    """The hardware of a simulated laser on `clock` (simulated, or the wall clock beside a real-time
    controller) once the controller runs: the simulated laser on its pty, the axis `open_axis()`
    opens, and the serial interferometer reading that pty. `closers` (what already runs, e.g. the
    server) are closed in reverse order when a part fails to open. The laser samples on its own clock
    when [sim] gives it one, its jitter drawn from the noise seed (another after a compensation)."""
    from drivers.sim.interferometer import SimInterferometer

    inst = spec.instrument
    try:
        seed = spec.sim.seed + (COMP_SEED_OFFSET if compensated else 0)
        instrument = SimInterferometer(clock, physics.measure, inst.line, inst.rate_hz, inst.mode,
                                       own_clock=instrument_clock(spec), seed=seed)
        closers.append(instrument.close)
        axis = open_axis()
        closers.append(axis.close)
        interferometer = SerialInterferometer(instrument.port_name, inst.baudrate, inst.line, inst.mode,
                                              inst.timeout_s)
        closers.append(interferometer.close)
    except BaseException:
        _close(closers)
        raise
    return Hardware(axis, interferometer, clock, closers), instrument


def _open_linuxcnc(spec: DriverSpec, model: ErrorModel | None) -> tuple[Hardware, None]:
    """A headless LinuxCNC (with `axis_driver.comp_file` loaded by its own COMP_FILE loader), its
    axis over linuxcncrsh, and the simulated laser reading the joint's motor position from HAL
    through the error model, on the wall clock (LinuxCNC runs in real time)."""

    from drivers.linuxcnc.axis import LinuxCncAxis, LinuxCncShell
    from drivers.linuxcnc.motor import LinuxCncMotor
    from drivers.linuxcnc.process import LinuxCnc
    from drivers.sim.machine import SimAxisPhysics

    axis_spec, drv = spec.axis, spec.controller
    if axis_spec.unit != "mm":
        raise InputError(f"{spec.source}: axis_driver.type = linuxcnc drives one linear joint (mm)")
    comp = Path(drv.comp_file) if drv.comp_file else None
    if comp is not None and not comp.is_file():
        raise InputError(f"{spec.source}: axis_driver.comp_file: {comp}: no such file")
    linuxcnc = LinuxCnc(axis_spec, comp)
    try:
        physics = SimAxisPhysics(LinuxCncMotor(linuxcnc), model or sim_model(spec.sim), "mm", spec.sim.seed)
    except BaseException:
        linuxcnc.stop()
        raise
    hw, _ = sim_hardware(spec, ListenedClock(), physics, lambda: LinuxCncAxis(LinuxCncShell()), [linuxcnc.stop])
    return hw, None


def _close(closers: list[Callable[[], None]]) -> None:
    """Close what was opened before a failure, in reverse order (their own failures are secondary)."""
    for close in reversed(closers):
        with contextlib.suppress(Exception):  # every part gets its chance to close
            close()


def instrument_clock(spec: DriverSpec) -> InstrumentClock | None:
    """The simulated instrument's own clock ([sim] instrument_*), None when it has none."""
    from drivers.sim.scan_streams import InstrumentClock

    s = spec.sim
    if not (s.instrument_offset_s or s.instrument_rate_ppm or s.instrument_jitter_s or s.instrument_latency_s):
        return None
    return InstrumentClock(offset_s=s.instrument_offset_s, rate_error_ppm=s.instrument_rate_ppm,
                           sample_jitter_s=s.instrument_jitter_s, latency_s=s.instrument_latency_s)


def serve_on_free_loopback(plc: SimPLC) -> SimAdsServer:
    """Serve `plc` over ADS on a free loopback address 127.0.x.y (every ADS client connects to TCP
    port 48898, so simulated machines running side by side, e.g. CI and a demo, each get their own
    address)."""
    from drivers.sim.ads_server import SimAdsServer

    rng = random.Random(os.getpid() * 1_000_003 + time.time_ns())
    for _ in range(64):
        ip = f"127.0.{rng.randint(0, 255)}.{rng.randint(2, 254)}"
        server = SimAdsServer(plc, ip)
        try:
            server.start()
        except OSError:
            continue
        return server
    raise OSError("no free loopback address for the simulated PLC's ADS server")


def _open_sim(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
              start_time: float, compensated: bool) -> tuple[Hardware, SimParts]:
    from campaign.faults import parse_faults
    from drivers.sim.faults import FaultScheduler

    drv = spec.controller
    faults = parse_faults(plain(spec.sim.faults), spec.source)
    if epics_only := sorted({f.name for f in faults} & {"ca_lost", "limit_switch", "stall"}):
        raise InputError(f"{spec.source}: sim.faults: {', '.join(epics_only)} rehearse the EPICS axis "
                         "(axis_driver.type = \"epics\"); the simulated PLC over ADS has no such fault")
    clock, plc, physics = sim_machine(spec, speed, model, start_position, start_time, compensated, drv.axis_index)
    server = serve_on_free_loopback(plc)
    hw, instrument = sim_hardware(spec, clock, physics, lambda: AdsAxis(
        server.net_id, server.ip, drv.axis_index, drv.ams_port, timeout_s=drv.timeout_s, read_only=drv.read_only),
        [server.stop], compensated)
    scheduler = FaultScheduler(faults, plc, server, instrument, physics)
    clock.attach(scheduler.tick)
    return hw, SimParts(clock, plc, server, instrument, physics, scheduler)


def leftover_controller(spec: DriverSpec) -> tuple[str, Callable[[], None]] | None:
    """A controller an earlier axiscal started for a driver of this kind and left running (a
    LinuxCNC whose axiscal was killed): what it is and how to stop it; None when there is none
    (always for the other drivers: axiscal starts no other controller)."""
    if spec.controller.type != "linuxcnc":
        return None
    from drivers.linuxcnc.process import find_leftover

    leftover = find_leftover()
    return None if leftover is None else (leftover.describe(), leftover.stop)

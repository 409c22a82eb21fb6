"""Opens a campaign's hardware for `[axis_driver] type = "epics"`.

- `[instrument] type = "sim"`: the simulated machine behind the simulated IOC: the simulated PLC and
  its compensation, served as the motor record `pv` by `drivers.sim.epics_ioc` on a free loopback
  port, the interferometer on its pty, in simulated time. This process's EPICS_CA_* variables point
  at that port on loopback while the machine is open (caproto's client reads them at every search),
  and are put back when it closes.
- `[instrument] type = "serial"`: the motor record `pv` of a running IOC, found as this process's
  EPICS_CA_* variables say, and the laser on its serial port, on the wall clock.
"""

from __future__ import annotations

import os
from collections.abc import Callable

from campaign.errors import InputError
from campaign.model import ErrorModel, sim_model
from campaign.specs import DriverSpec, plain
from drivers.clock import RealClock
from drivers.epics.axis import EpicsAxis
from drivers.factory import COMP_SEED_OFFSET, SimParts, _close
from drivers.serial_interferometer import SerialInterferometer
from protocols.hardware import Hardware, InstrumentError

SIM_PV = "SIM:M1"
"""The simulated IOC's motor record when the config names none."""


def open_epics(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
               start_time: float, compensated: bool) -> tuple[Hardware, SimParts | None]:
    axis_spec, drv, inst = spec.axis, spec.controller, spec.instrument
    limits = (axis_spec.soft_limit_min, axis_spec.soft_limit_max)
    if inst.type != "sim":
        axis = EpicsAxis(drv.pv, limits=limits, read_only=drv.read_only, timeout_s=drv.timeout_s,
                         where=spec.source, unit=axis_spec.unit)
        try:
            interferometer = SerialInterferometer(inst.port, inst.baudrate, inst.line, inst.mode, inst.timeout_s)
        except InstrumentError as exc:
            axis.close()
            raise InputError(f"{spec.source}: instrument.port: cannot open {inst.port}: {exc}") from None
        return Hardware(axis, interferometer, RealClock(), [axis.close, interferometer.close]), None
    return _open_sim_ioc(spec, speed, model, start_position, start_time, compensated)


def _open_sim_ioc(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
                  start_time: float, compensated: bool) -> tuple[Hardware, SimParts]:
    from campaign.faults import parse_faults
    from drivers.sim.compensation import SimCompensation
    from drivers.sim.epics_ioc import IocFaultScheduler, SimMotorIoc
    from drivers.sim.interferometer import SimInterferometer
    from drivers.sim.machine import SimAxisPhysics, make_clock
    from drivers.sim.plc import SimPLC

    axis_spec, drv, inst = spec.axis, spec.controller, spec.instrument
    clock = make_clock(speed if speed is not None else spec.sim.speed, start_time)
    start = spec.start_position if start_position is None else start_position
    plc = SimPLC(1, axis_spec.max_velocity, axis_spec.max_acceleration, position=start, start_time=start_time)
    clock.attach(plc.scan)
    clock.attach(SimCompensation(plc, clock.now()).tick)
    seed = spec.sim.seed + (COMP_SEED_OFFSET if compensated else 0)
    physics = SimAxisPhysics(plc, model or sim_model(spec.sim), axis_spec.unit, seed,
                             vacuum_readings=spec.vacuum_readings)
    pv = drv.pv or SIM_PV
    ioc = SimMotorIoc(plc, pv, low=axis_spec.soft_limit_min, high=axis_spec.soft_limit_max,
                      velocity=min(axis_spec.max_velocity, 1.0), unit=axis_spec.unit)
    clock.attach(ioc.scan)
    saved = {key: os.environ.get(key) for key in ioc.environment}
    os.environ.update(ioc.environment)

    def restore_environment() -> None:
        for key, old in saved.items():
            if old is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = old

    closers: list[Callable[[], None]] = [restore_environment, ioc.close]
    try:
        instrument = SimInterferometer(clock, physics.measure, inst.line, inst.rate_hz, inst.mode)
        closers.append(instrument.close)
        axis = EpicsAxis(pv, limits=(axis_spec.soft_limit_min, axis_spec.soft_limit_max),
                         read_only=drv.read_only, timeout_s=drv.timeout_s, where=spec.source, unit=axis_spec.unit)
        closers.append(axis.close)
        interferometer = SerialInterferometer(instrument.port_name, inst.baudrate, inst.line, inst.mode,
                                              inst.timeout_s)
        closers.append(interferometer.close)
    except BaseException:
        _close(closers)
        raise
    hw = Hardware(axis, interferometer, clock, closers)
    scheduler = IocFaultScheduler(parse_faults(plain(spec.sim.faults), spec.source), plc, ioc, instrument, physics)
    clock.attach(scheduler.tick)
    return hw, SimParts(clock, plc, ioc, instrument, physics, scheduler)

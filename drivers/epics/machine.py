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

from campaign.model import ErrorModel
from campaign.specs import DriverSpec, plain
from drivers.epics.axis import EpicsAxis
from drivers.factory import SimParts, sim_hardware, sim_machine, with_serial_laser
from protocols.hardware import Hardware

SIM_PV = "SIM:M1"
"""The simulated IOC's motor record when the config names none."""


def open_epics(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
               start_time: float, compensated: bool) -> tuple[Hardware, SimParts | None]:
    axis_spec, drv, inst = spec.axis, spec.controller, spec.instrument
    limits = (axis_spec.soft_limit_min, axis_spec.soft_limit_max)
    if inst.type != "sim":
        return with_serial_laser(spec, EpicsAxis(drv.pv, limits=limits, read_only=drv.read_only,
                                                 timeout_s=drv.timeout_s, where=spec.source, unit=axis_spec.unit)), None
    return _open_sim_ioc(spec, speed, model, start_position, start_time, compensated)


def _open_sim_ioc(spec: DriverSpec, speed: float | None, model: ErrorModel | None, start_position: float | None,
                  start_time: float, compensated: bool) -> tuple[Hardware, SimParts]:
    from campaign.faults import parse_faults
    from drivers.sim.epics_ioc import IocFaultScheduler, SimMotorIoc

    axis_spec, drv = spec.axis, spec.controller
    clock, plc, physics = sim_machine(spec, speed, model, start_position, start_time, compensated, 1)
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

    hw, instrument = sim_hardware(spec, clock, physics, lambda: EpicsAxis(
        pv, limits=(axis_spec.soft_limit_min, axis_spec.soft_limit_max), read_only=drv.read_only,
        timeout_s=drv.timeout_s, where=spec.source, unit=axis_spec.unit), [restore_environment, ioc.close],
        compensated)
    scheduler = IocFaultScheduler(parse_faults(plain(spec.sim.faults), spec.source), plc, ioc, instrument, physics)
    clock.attach(scheduler.tick)
    return hw, SimParts(clock, plc, ioc, instrument, physics, scheduler)

"""Builds the hardware a config asks for: a real PLC and instrument, or the simulated machine.

This is the one place where the campaign's protocols meet pyads and pyserial.
"""

from __future__ import annotations

import contextlib
import os
import random
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from campaign.config import Config
from campaign.errors import InputError
from campaign.model import ErrorModel, sim_model
from drivers.ads_axis import AdsAxis
from drivers.clock import RealClock
from drivers.serial_interferometer import SerialInterferometer
from protocols.hardware import Hardware, InstrumentError
from protocols.serial_line import LineFormat

if TYPE_CHECKING:
    from drivers.sim.ads_server import SimAdsServer
    from drivers.sim.plc import SimPLC


@dataclass
class SimParts:
    """The simulated machine's parts, for tests and fault injection."""

    clock: object
    plc: object
    server: object
    instrument: object
    physics: object
    faults: object = None


def line_format(config: Config) -> LineFormat:
    return LineFormat.from_dict(config["instrument"].get("line", {}), f"{config.source}: [instrument.line]")


def open_hardware(config: Config, speed: float | None = None, model: ErrorModel | None = None,
                  start_position: float | None = None, start_time: float = 0.0,
                  ) -> tuple[Hardware, SimParts | None]:
    """Open the axis, instrument and clock of `config`. For the simulated machine also return
    its parts. `speed` overrides `sim.speed`; `model` overrides the config's error model;
    `start_position` (axis unit) and `start_time` (s) are where and when the simulated machine
    starts (a resumed campaign continues where it stopped)."""
    fmt = line_format(config)
    inst, drv = config["instrument"], config["axis_driver"]
    if drv["type"] == "ads":
        axis = AdsAxis(drv["ams_net_id"], drv["ip"], drv["axis_index"], drv["ams_port"],
                       read_only=drv["read_only"], timeout_s=drv["timeout_s"])
        try:
            interferometer = SerialInterferometer(inst["port"], inst["baudrate"], fmt, inst["mode"],
                                                  inst["timeout_s"])
        except InstrumentError as exc:
            axis.close()
            raise InputError(f"{config.source}: instrument.port: cannot open {inst['port']}: {exc}") from None
        return Hardware(axis, interferometer, RealClock(), [axis.close, interferometer.close]), None
    if drv["type"] == "linuxcnc":
        return _open_linuxcnc(config, fmt, model)
    return _open_sim(config, fmt, speed, model, start_position, start_time)


def _open_linuxcnc(config: Config, fmt: LineFormat, model: ErrorModel | None) -> tuple[Hardware, None]:
    """A headless LinuxCNC (with `axis_driver.comp_file` loaded by its own COMP_FILE loader), its
    axis over linuxcncrsh, and the simulated laser reading the joint's motor position from HAL
    through the error model, on the wall clock (LinuxCNC runs in real time)."""
    from pathlib import Path

    from drivers.clock import ListenedClock
    from drivers.linuxcnc.axis import LinuxCncAxis, LinuxCncShell
    from drivers.linuxcnc.motor import LinuxCncMotor
    from drivers.linuxcnc.process import LinuxCnc
    from drivers.sim.interferometer import SimInterferometer
    from drivers.sim.machine import SimAxisPhysics

    axis_cfg, drv, inst = config["axis"], config["axis_driver"], config["instrument"]
    if axis_cfg["unit"] != "mm":
        raise InputError(f"{config.source}: axis_driver.type = linuxcnc drives one linear joint (mm)")
    comp = Path(drv["comp_file"]) if drv["comp_file"] else None
    if comp is not None and not comp.is_file():
        raise InputError(f"{config.source}: axis_driver.comp_file: {comp}: no such file")
    linuxcnc = LinuxCnc(axis_cfg["soft_limit_min"], axis_cfg["soft_limit_max"], axis_cfg["max_velocity"],
                        axis_cfg["max_acceleration"], comp)
    clock = ListenedClock()
    closers: list[Callable[[], None]] = [linuxcnc.stop]
    try:
        axis = LinuxCncAxis(LinuxCncShell())
        closers.append(axis.close)
        physics = SimAxisPhysics(LinuxCncMotor(linuxcnc), model or sim_model(config), "mm", config["sim"]["seed"])
        instrument = SimInterferometer(clock, physics.measure, fmt, inst["rate_hz"], inst["mode"])
        closers.append(instrument.close)
        interferometer = SerialInterferometer(instrument.port_name, inst["baudrate"], fmt, inst["mode"],
                                              inst["timeout_s"])
        closers.append(interferometer.close)
    except BaseException:
        _close(closers)
        raise
    return Hardware(axis, interferometer, clock, closers), None


def _close(closers: list[Callable[[], None]]) -> None:
    """Close what was opened before a failure, in reverse order (their own failures are secondary)."""
    for close in reversed(closers):
        with contextlib.suppress(Exception):  # every part gets its chance to close
            close()


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


def _open_sim(config: Config, fmt: LineFormat, speed: float | None, model: ErrorModel | None,
              start_position: float | None, start_time: float) -> tuple[Hardware, SimParts]:
    from campaign.faults import parse_faults
    from drivers.sim.compensation import SimCompensation
    from drivers.sim.faults import FaultScheduler
    from drivers.sim.interferometer import SimInterferometer
    from drivers.sim.machine import SimAxisPhysics, make_clock
    from drivers.sim.plc import SimPLC

    axis_cfg, drv, inst = config["axis"], config["axis_driver"], config["instrument"]
    clock = make_clock(speed if speed is not None else config["sim"]["speed"], start_time)
    start = config["plan"]["start"] if start_position is None else start_position
    plc = SimPLC(drv["axis_index"], axis_cfg["max_velocity"], axis_cfg["max_acceleration"], position=start,
                 start_time=start_time)
    clock.attach(plc.scan)
    clock.attach(SimCompensation(plc, clock.now()).tick)  # FB_AxiscalCompensation: idle until a table is enabled
    physics = SimAxisPhysics(plc, model or sim_model(config), axis_cfg["unit"], config["sim"]["seed"],
                             vacuum_readings=config["environment"]["air_correction"] == "edlen")
    server = serve_on_free_loopback(plc)
    closers: list[Callable[[], None]] = [server.stop]
    try:
        instrument = SimInterferometer(clock, physics.measure, fmt, inst["rate_hz"], inst["mode"])
        closers.append(instrument.close)
        axis = AdsAxis(server.net_id, server.ip, drv["axis_index"], drv["ams_port"], timeout_s=drv["timeout_s"],
                       read_only=drv["read_only"])
        closers.append(axis.close)
        interferometer = SerialInterferometer(instrument.port_name, inst["baudrate"], fmt, inst["mode"],
                                              inst["timeout_s"])
        closers.append(interferometer.close)
    except BaseException:
        _close(closers)
        raise
    hw = Hardware(axis, interferometer, clock, closers)
    scheduler = FaultScheduler(parse_faults(config["sim"].get("faults", {}), config.source), plc, server,
                               instrument, physics)
    clock.attach(scheduler.tick)
    return hw, SimParts(clock, plc, server, instrument, physics, scheduler)

"""Fires the faults of campaign/faults.py on the simulated machine at their simulated times."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from campaign.faults import Fault

if TYPE_CHECKING:
    from drivers.sim.ads_server import SimAdsServer
    from drivers.sim.interferometer import SimInterferometer
    from drivers.sim.machine import SimAxisPhysics
    from drivers.sim.plc import SimPLC


class FaultScheduler:
    """Fires the faults at their simulated times. Attach `tick` to the SimClock after the PLC scan.

    `on_disk_full` is called for the disk_full fault (the campaign wires it to its recorder).
    """

    def __init__(self, faults: list[Fault], plc: SimPLC, server: SimAdsServer, instrument: SimInterferometer,
                 physics: SimAxisPhysics) -> None:
        self.faults = faults
        self.plc, self.server, self.instrument, self.physics = plc, server, instrument, physics
        self.on_disk_full: Callable[[], None] | None = None
        self.log: list[tuple[float, str, str]] = []

    def tick(self, t: float) -> None:
        for fault in self.faults:
            if not fault.fired and t >= fault.at_s:
                if fault.name == "axis_error" and self.plc.arrival_time is not None:
                    continue  # wait for a move
                fault.fired = True
                self._fire(fault, t)
            elif fault.fired and not fault.ended and "duration_s" in fault.params \
                    and t >= fault.at_s + fault.params["duration_s"]:
                fault.ended = True
                self._end(fault, t)

    def _fire(self, fault: Fault, t: float) -> None:
        p = fault.params
        self.log.append((t, fault.name, "injected"))
        if fault.name == "ads_lost":
            self.server.stop()
        elif fault.name == "axis_error":
            self.plc.inject_error(int(p["error_id"]))
        elif fault.name == "beam_break":
            self.instrument.beam_break(t, t + p["duration_s"])
        elif fault.name == "serial_garbage":
            for i in range(int(p["lines"])):
                self.instrument.inject_garbage(f"#%$@ noise {i} \x07\x7f garbage\r\n")
        elif fault.name == "serial_gone":
            self.instrument.disappear()
        elif fault.name == "env_stuck":
            self.physics.freeze_environment(t)
        elif fault.name == "env_out_of_range":
            self.physics.air_temp_override = 85.0
        elif fault.name == "disk_full" and self.on_disk_full is not None:
            self.on_disk_full()

    def _end(self, fault: Fault, t: float) -> None:
        self.log.append((t, fault.name, "ended"))
        if fault.name == "ads_lost":
            self.server.start()
        elif fault.name == "env_out_of_range":
            self.physics.air_temp_override = None

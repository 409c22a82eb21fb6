"""The simulated machine: a PLC served over loopback ADS, an axis with a physics model of named
effects, and a laser interferometer behind a pty, all running in simulated time.

Where the axis really is: the PLC's motor setpoint x (including any compensation correction) plus
the error model's deviation at x, the approach direction, the time and the wait since arrival,
plus a per-approach scatter drawn at each arrival and a per-sample reading noise. Everything is
seeded and deterministic. Positions in axis unit (mm or deg); deviations in µm (arcsec for a
rotary axis).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from campaign.edlen import refractive_index
from campaign.model import ErrorModel
from drivers.sim.clock import SimClock
from protocols.units import DEVIATION_SCALE


class Motor(Protocol):
    """What the physics reads of the controller: the motor setpoint at time t (s; axis unit), when
    the axis came to rest (s, None while moving) and the last motion's direction (+1/-1). The
    simulated PLC and LinuxCNC's joint both provide it."""

    @property
    def arrival_time(self) -> float | None: ...
    @property
    def last_direction(self) -> int: ...
    def setpoint_position(self, t: float) -> float: ...


class SimAxisPhysics:
    """Turns the PLC's motor setpoint into the true position the interferometer sees.

    air: (air temperature °C, pressure hPa, humidity %) of the simulated room; material_temp_c: the
    machine's temperature, °C. vacuum_readings: the instrument reports vacuum lengths (true × n),
    for a campaign that corrects for air itself.
    """

    def __init__(self, plc: Motor, model: ErrorModel, unit: str = "mm", seed: int = 1,
                 air: tuple[float, float, float] = (20.0, 1013.25, 50.0), material_temp_c: float = 20.0,
                 vacuum_readings: bool = False):
        self.plc, self.model, self.unit = plc, model, unit
        # Two streams: the k-th approach gets the same scatter however many readings were taken
        # before it (a stable capture reads fewer than a fixed dwell), so capture methods compare.
        self.rng = np.random.default_rng([seed, 2])
        self.scatter_rng = np.random.default_rng([seed, 1])
        self.air = air
        self.material_temp_c = material_temp_c
        self.vacuum_readings = vacuum_readings
        self._arrival: float | None = None
        self._scatter_um = 0.0
        self.air_temp_override: float | None = None
        """A faulty air temperature sensor's reading, °C (None: the sensor is fine)."""
        self._frozen_at: float | None = None

    def true_position(self, t: float, with_reading_noise: bool = True) -> float:
        """Where the carriage really is at simulated time t (s), axis unit."""
        x = self.plc.setpoint_position(t)
        arrival = self.plc.arrival_time
        if arrival is not None and arrival != self._arrival:
            self._arrival = arrival
            self._scatter_um = float(self.scatter_rng.normal(0.0, self.model.sigma_um)) if self.model.sigma_um else 0.0
        wait = 0.0 if arrival is None else max(0.0, t - arrival)
        e_um = self.model.deviation_at(float(x), float(self.plc.last_direction), float(t), float(wait))
        if arrival is not None:
            e_um += self._scatter_um
        if with_reading_noise and self.model.reading_sigma_um:
            e_um += float(self.rng.normal(0.0, self.model.reading_sigma_um))
        return x + e_um / DEVIATION_SCALE[self.unit]

    def environment(self, t: float) -> tuple[float, float, float, float]:
        """The room at t (s): air °C, hPa, % RH and material °C. A slow, small daily-like swing
        (0.1 K, 0.3 hPa, 1 % over 30 min) around the set values, so a stuck sensor shows."""
        phase = 2 * np.pi * t / 1800.0
        temp, pressure, humidity = self.air
        return (temp + 0.1 * np.sin(phase), pressure + 0.3 * np.cos(phase), humidity + 1.0 * np.sin(phase),
                self.material_temp_c + 0.05 * np.sin(phase))

    def freeze_environment(self, t: float) -> None:
        """The environment sensors stick at their values of time t (s)."""
        self._frozen_at = t

    def measure(self, t: float) -> dict:
        """What the simulated interferometer reads at t: position (axis unit), signal and environment."""
        position = self.true_position(t)
        temp, pressure, humidity, material = self.environment(t)
        if self.vacuum_readings:
            position *= refractive_index(temp, pressure * 100.0, humidity)
        if self._frozen_at is not None:
            temp, pressure, humidity, material = self.environment(self._frozen_at)
        if self.air_temp_override is not None:
            temp = self.air_temp_override
        return {"position": position, "signal_pct": 90.0, "air_temp_c": round(float(temp), 3),
                "air_pressure_hpa": round(float(pressure), 2), "humidity_pct": round(float(humidity), 2),
                "material_temp_c": round(float(material), 3)}


def make_clock(speed: float | None, start_s: float = 0.0) -> SimClock:
    return SimClock(start_s, speed)

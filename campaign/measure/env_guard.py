"""Plausibility of the environment sensors: out-of-range values never reach the point table (the
raw stream keeps what the sensor said), and a sensor that stops changing is reported.

Ranges: air 10–35 °C, 800–1100 hPa, 5–95 % RH; material 10–35 °C. An out-of-range value is
replaced by the last plausible one (the event says so); a value unchanged for `stuck_after_s`
seconds of campaign time is reported once as stuck.
"""

from __future__ import annotations

from typing import Literal

PLAUSIBLE = {"air_temp_c": (10.0, 35.0), "air_pressure_hpa": (800.0, 1100.0), "humidity_pct": (5.0, 95.0),
             "material_temp_c": (10.0, 35.0)}


EnvProblem = Literal["out_of_range", "stuck"]


class EnvironmentGuard:
    """Checks each captured point's environment. Times in s of campaign time."""

    def __init__(self, stuck_after_s: float = 600.0):
        self.stuck_after_s = stuck_after_s
        self.last_good: dict[str, float] = {}
        self.changed_at: dict[str, float] = {}
        self.reported_stuck: set[str] = set()

    def check(self, env: dict[str, float | None], t_s: float,
              ) -> tuple[dict[str, float | None], list[tuple[str, EnvProblem, str]]]:
        """(the environment to record, (field, problem, message) for each event to log; problem
        is out_of_range or stuck)."""
        clean = dict(env)
        messages: list[tuple[str, EnvProblem, str]] = []
        for name, value in env.items():
            if value is None or name not in PLAUSIBLE:
                continue
            low, high = PLAUSIBLE[name]
            if not low <= value <= high:
                clean[name] = self.last_good.get(name)
                used = "last plausible value used" if clean[name] is not None else "no value recorded"
                messages.append((name, "out_of_range", f"{name} = {value:g} is outside [{low:g}, {high:g}]: {used}"))
                continue
            if self.last_good.get(name) != value:
                self.changed_at[name] = t_s
                self.reported_stuck.discard(name)
            elif t_s - self.changed_at.get(name, t_s) >= self.stuck_after_s and name not in self.reported_stuck:
                self.reported_stuck.add(name)
                messages.append((name, "stuck", f"{name} has not changed for {t_s - self.changed_at[name]:.0f} s: sensor stuck?"))
            self.last_good[name] = value
        return clean, messages

"""Faults to inject into the simulated machine: their names, parameters and schedule (data).

The simulated machine fires them (drivers/sim/faults.py).

Set in a config as `[sim.faults]` (one inline table per fault) or rehearsed with
`axiscal demo --inject NAME[@SECONDS],...`:

    [sim.faults]
    beam_break = { at_s = 300.0, duration_s = 3.0 }

| fault | parameters (defaults) | what happens |
|---|---|---|
| ads_lost | at_s, duration_s (5) | the PLC's ADS server stops, and starts again after duration_s |
| ca_lost | at_s, duration_s (5) | EPICS: the simulated IOC's Channel Access server stops, and starts again after duration_s |
| limit_switch | at_s | EPICS: the limit switch ahead trips during the first move at or after at_s (clears when the axis moves away) |
| stall | at_s | EPICS: the motor stalls during the first move at or after at_s (DMOV stays 0; the controller reports it after 1 s) |
| axis_error | at_s, error_id (0x4550) | the drive faults during the first move at or after at_s |
| beam_break | at_s, duration_s (3) | the interferometer's signal drops to 0 % |
| serial_garbage | at_s, lines (5) | garbage lines appear on the serial line |
| serial_gone | at_s | the serial port disappears (the pty closes) |
| env_stuck | at_s | the environment sensors stop changing |
| env_out_of_range | at_s, duration_s (60) | the air temperature reads 85 °C |
| disk_full | at_s | the next write to the campaign directory fails with ENOSPC |

Times are simulated seconds since the simulated machine started.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from campaign.errors import InputError

DEFAULTS: dict[str, dict[str, float]] = {
    "ads_lost": {"duration_s": 5.0},
    "axis_error": {"error_id": 0x4550},
    "beam_break": {"duration_s": 3.0},
    "serial_garbage": {"lines": 5},
    "serial_gone": {},
    "env_stuck": {},
    "env_out_of_range": {"duration_s": 60.0},
    "disk_full": {},
    "ca_lost": {"duration_s": 5.0},
    "limit_switch": {},
    "stall": {},
}
DEFAULT_AT_S = 120.0


@dataclass
class Fault:
    """One scheduled fault: its name, when (simulated s) and its parameters."""

    name: str
    at_s: float
    params: dict[str, float] = field(default_factory=dict)
    fired: bool = False
    ended: bool = False


def parse_faults(table: dict, where: str) -> list[Fault]:
    """Faults from a `[sim.faults]` table; InputError naming the key on any problem."""
    faults = []
    for name, params in table.items():
        if name not in DEFAULTS:
            raise InputError(f"{where}: unknown fault 'sim.faults.{name}' (known: {', '.join(DEFAULTS)})")
        if not isinstance(params, dict):
            raise InputError(f"{where}: 'sim.faults.{name}' must be a table like {{ at_s = 120.0 }}")
        merged = {"at_s": DEFAULT_AT_S, **DEFAULTS[name]}
        for key, value in params.items():
            if key not in merged:
                raise InputError(f"{where}: unknown key 'sim.faults.{name}.{key}'")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < 1e9:
                raise InputError(f"{where}: 'sim.faults.{name}.{key}' must be a number >= 0")
            merged[key] = float(value)
        at = merged.pop("at_s")
        faults.append(Fault(name, at, merged))
    return faults


def parse_inject(text: str) -> dict[str, dict[str, float]]:
    """`NAME[@SECONDS],...` (the --inject option) as a [sim.faults] table."""
    table: dict[str, dict[str, float]] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, _, at = item.partition("@")
        if name not in DEFAULTS:
            raise InputError(f"--inject: unknown fault '{name}' (known: {', '.join(DEFAULTS)})")
        try:
            at_s = float(at) if at else DEFAULT_AT_S
        except ValueError:
            raise InputError(f"--inject: '{item}': the time after @ must be seconds") from None
        if not 0 <= at_s < 1e9:
            raise InputError(f"--inject: '{item}': the time must be >= 0 s")
        table[name] = {"at_s": at_s}
    if not table:
        raise InputError("--inject: give at least one fault, e.g. beam_break@300")
    return table

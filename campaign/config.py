"""The campaign configuration: one TOML file per campaign.

The schema below is the documentation: `docs/config.md` is generated from it
(`python -m campaign.config > docs/config.md`, checked by a test). An unknown key or an
out-of-range value raises InputError naming the key.
"""

from __future__ import annotations

import itertools
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from campaign.errors import InputError, read_input_text
from campaign.faults import parse_faults
from campaign.model import model_from_dict
from protocols import plc_contract
from protocols.serial_line import LineFormat

REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One config key: its type, default (REQUIRED if none), meaning with unit, bounds, and whether
    it may change before a resume."""

    type: type
    default: Any
    doc: str
    min: float | None = None
    max: float | None = None
    choices: tuple = ()
    resume: bool = False
    """True when the key may change between a campaign's start and its resume (a connection, a
    limit, a name); any other change would mix two measurements in one table."""


SCHEMA: dict[str, dict[str, Key]] = {
    "campaign": {
        "machine": Key(str, "machine", "machine id, recorded in the metadata", resume=True),
        "operator": Key(str, "", "operator name, recorded in the metadata", resume=True),
        "description": Key(str, "", "free text, recorded in the metadata", resume=True),
        "tolerance": Key(float, 0.0, "pass/fail tolerance on the accuracy A, deviation unit (µm or arcsec); "
                         "0 = none", min=0, resume=True),
        "tolerance_e": Key(float, 0.0, "tolerance on the systematic deviation E, deviation unit; 0 = none", min=0,
                           resume=True),
        "tolerance_b": Key(float, 0.0, "tolerance on the reversal value B, deviation unit; 0 = none", min=0,
                           resume=True),
        "tolerance_r": Key(float, 0.0, "tolerance on the repeatability R, deviation unit; 0 = none", min=0,
                           resume=True),
        "on_fault": Key(str, "retry", "without an operator: retry a point after a fault (up to fault_retries "
                        "times), skip it (resume measures it later), or abort at once",
                        choices=("retry", "skip", "abort"), resume=True),
        "fault_retries": Key(int, 3, "faults retried at one point before the campaign stops", min=0, max=20, resume=True),
    },
    "axis": {
        "name": Key(str, "X", "axis name"),
        "kind": Key(str, "linear", "linear or rotary", choices=("linear", "rotary")),
        "unit": Key(str, "mm", "position unit: mm (linear) or deg (rotary)", choices=("mm", "deg")),
        "soft_limit_min": Key(float, REQUIRED, "lowest position any motion may command, axis unit", resume=True),
        "soft_limit_max": Key(float, REQUIRED, "highest position any motion may command, axis unit", resume=True),
        "max_velocity": Key(float, REQUIRED, "highest velocity any motion may command, axis unit/s",
                            min=1e-6, resume=True),
        "max_acceleration": Key(float, 500.0, "axis acceleration (simulated machine), axis unit/s²",
                                min=1e-6),
        "in_position_window": Key(float, 0.01, "|actual - target| allowed when a move is done, axis unit",
                                  min=0, resume=True),
    },
    "plan": {
        "targets": Key(list, None, "explicit target list, axis unit (instead of start/length/count)"),
        "start": Key(float, 0.0, "first target, axis unit"),
        "length": Key(float, None, "distance from the first to the last target, axis unit", min=1e-9),
        "count": Key(int, None, "number of targets (>= 2)", min=2, max=10000),
        "overrun": Key(float, 2.0, "overrun L1 beyond both ends, axis unit", min=0),
        "cycles": Key(int, 5, "number of runs (cycles); ISO 230-2 asks for 5", min=1, max=1000),
        "dwell_s": Key(float, 4.0, "dwell at each target, s", min=0.1, max=600),
        "dwell_jitter": Key(float, 0.0, "vary each point's dwell by up to this fraction (seeded): settling is "
                            "only told from backlash when the dwell varies", min=0, max=0.9),
        "velocity": Key(float, REQUIRED, "positioning velocity, axis unit/s", min=1e-9),
        "cycle": Key(str, "linear", "linear (ISO 230-2) or pilgrim (step cycle, annex)",
                     choices=("linear", "pilgrim")),
        "offsets": Key(str, "none", "per-target offsets to sample periodic errors: none, random, golden",
                       choices=("none", "random", "golden")),
        "offset_fraction": Key(float, 0.1, "largest offset as a fraction of the target spacing",
                               min=0, max=0.45),
        "seed": Key(int, 1, "seed of the random offsets (recorded)", min=0),
    },
    "axis_driver": {
        "type": Key(str, "sim", "sim (simulated machine over loopback ADS), ads (a real PLC) or linuxcnc (a "
                    "headless LinuxCNC with a simulated laser, docs/linuxcnc.md)",
                    choices=("sim", "ads", "linuxcnc"), resume=True),
        "comp_file": Key(str, "", "linuxcnc: the COMP_FILE (type 0) LinuxCNC loads at start; empty: none",
                         resume=True),
        "ams_net_id": Key(str, "127.0.0.1.1.1", "the PLC's AMS net id", resume=True),
        "ams_port": Key(int, 851, "the PLC runtime's ADS port", min=1, max=65535, resume=True),
        "ip": Key(str, "127.0.0.1", "the PLC's IP address", resume=True),
        "axis_index": Key(int, 1, "index n of GVL_Axiscal.astAxes[n]", min=1, max=plc_contract.MAX_AXES, resume=True),
        "timeout_s": Key(float, 2.0, "ADS call timeout, s", min=0.01, max=60, resume=True),
        "move_timeout_s": Key(float, 300.0, "longest a single move may take, s", min=0.1, resume=True),
        "reconnect_s": Key(float, 30.0, "how long to wait for a lost ADS connection to come back, s", min=0, resume=True),
        "read_only": Key(bool, False, "dry run: talk to the PLC read-only, command nothing", resume=True),
    },
    "instrument": {
        "type": Key(str, "sim", "sim (simulated interferometer over a pty) or serial",
                    choices=("sim", "serial")),
        "port": Key(str, "", "serial port, e.g. /dev/ttyUSB0", resume=True),
        "baudrate": Key(int, 115200, "serial baud rate", min=50, max=4000000, resume=True),
        "mode": Key(str, "stream", "stream (instrument sends continuously) or query",
                    choices=("stream", "query")),
        "rate_hz": Key(float, 10.0, "how often axiscal takes the readings (its tick), Hz; set the instrument "
                       "to stream at least this fast; the simulated instrument streams at this rate",
                       min=0.1, max=1000),
        "timeout_s": Key(float, 1.0, "serial read timeout, s", min=0.01, max=60, resume=True),
        "model": Key(str, "", "the laser's model, for the report's traceability (e.g. Renishaw XL-80)", resume=True),
        "serial": Key(str, "", "the laser's serial number", resume=True),
        "certificate": Key(str, "", "the laser's calibration certificate: number, laboratory, date", resume=True),
        "wavelength_uncertainty_ppm": Key(float, None, "expanded uncertainty (k = 2) of the laser's length "
                                          "measurement from its calibration certificate, µm/m; absent: 0.5 µm/m, "
                                          "a typical specification, named as such in the budget", min=0, max=100,
                                          resume=True),
        "angle_uncertainty_arcsec": Key(float, None, "rotary axis: expanded uncertainty (k = 2) of the angular "
                                        "measurement from the certificate, arcsec; absent: 1 arcsec (typical "
                                        "specification)", min=0, max=100, resume=True),
        "resolution": Key(float, 0.001, "the reading's resolution, deviation unit (µm or arcsec)", min=0,
                          resume=True),
        "misalignment_mm": Key(float, 0.5, "largest lateral walk of the beam over the travel seen when aligning, "
                               "mm (the cosine error)", min=0, resume=True),
        "dead_path_mm": Key(float, 0.0, "distance from the interferometer optic to the laser's datum, mm (dead "
                            "path)", min=0, resume=True),
    },
    "environment": {
        "air_correction": Key(str, "none", "none (instrument corrects for air) or edlen (axiscal "
                              "corrects vacuum readings with the updated Edlén equation)",
                              choices=("none", "edlen")),
        "wavelength_nm": Key(float, 633.0, "laser vacuum wavelength, nm", min=100, max=2000),
        "co2_ppm": Key(float, 450.0, "CO2 content of the air, ppm", min=0, max=10000),
        "air_temp_c": Key(float, None, "air temperature when the instrument gives none, °C", min=-20, max=60),
        "air_pressure_hpa": Key(float, None, "air pressure when the instrument gives none, hPa",
                                min=500, max=1200),
        "humidity_pct": Key(float, None, "relative humidity when the instrument gives none, %", min=0, max=100),
        "normalise_to_20c": Key(bool, False, "normalise readings to 20 °C with the material temperature"),
        "expansion_ppm_per_k": Key(float, 11.5, "material expansion coefficient, µm/m per K", min=0, max=100),
        "air_temp_uncertainty_c": Key(float, 0.2, "expanded uncertainty (k = 2) of the air temperature sensor, °C",
                                      min=0, resume=True),
        "air_pressure_uncertainty_hpa": Key(float, 1.0, "expanded uncertainty (k = 2) of the air pressure "
                                            "sensor, hPa", min=0, resume=True),
        "humidity_uncertainty_pct": Key(float, 6.0, "expanded uncertainty (k = 2) of the humidity sensor, % RH",
                                        min=0, resume=True),
        "material_temp_uncertainty_c": Key(float, 0.1, "expanded uncertainty (k = 2) of the material "
                                           "temperature sensor, °C", min=0, resume=True),
        "expansion_uncertainty_ppm_per_k": Key(float, 1.0, "half-width of the range the expansion coefficient "
                                               "may lie in, µm/m per K", min=0, resume=True),
    },
    "capture": {
        "method": Key(str, "dwell", "dwell (average the end of a fixed dwell) or stable (capture when "
                      "the reading is stable)", choices=("dwell", "stable")),
        "average_s": Key(float, 1.0, "dwell method: averaging window at the end of the dwell, s", min=0.01),
        "stable_tolerance": Key(float, 0.5, "stable method: band the reading must stay in, deviation unit",
                                min=0),
        "stable_drift": Key(float, 0.08, "stable method: largest difference between the means of the window's "
                            "two halves, deviation unit (raised to the noise's own uncertainty when that is larger)",
                            min=0),
        "stable_window_s": Key(float, 0.7, "stable method: how long the reading must stay in the band, s",
                               min=0.01),
        "stable_timeout_s": Key(float, 10.0, "stable method: longest wait after arrival, s", min=0.1),
        "retries": Key(int, 2, "captures retried at a point after beam loss before the campaign stops",
                       min=0, max=20),
    },
    "sim": {
        "speed": Key(float, None, "run N times faster than real time; absent = as fast as possible",
                     min=1e-3, resume=True),
        "seed": Key(int, 1, "seed of the simulated noise", min=0),
        "model": Key(str, "", "error-model TOML file (relative to this config); or [sim.effects.NAME]"),
    },
}

TABLES = {("instrument", "line"), ("sim", "effects"), ("sim", "faults")}
"""Sub-tables validated elsewhere: the serial line format, the error model, the faults."""


@dataclass
class Config:
    """A validated config: `sections[name][key]` with every default filled in."""

    sections: dict[str, dict[str, Any]]
    source: str
    text: str

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self.sections[section]

    @property
    def base_dir(self) -> Path:
        return Path(self.source).resolve().parent


def _check_value(name: str, key: Key, value: Any, where: str) -> Any:
    if key.type is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if key.type is list:
        if not isinstance(value, list) or not value or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
            raise InputError(f"{where}: key '{name}': must be a non-empty list of numbers")
        return [float(v) for v in value]
    expected: Any = key.type  # a TOML value of a key's type: compared below with its bounds
    if not isinstance(value, expected) or (key.type is int and isinstance(value, bool)):
        raise InputError(f"{where}: key '{name}': must be {key.type.__name__}, found {value!r}"[:200])
    if key.type is float and not math.isfinite(value):
        raise InputError(f"{where}: key '{name}': must be a finite number")
    if key.min is not None and value < key.min or key.max is not None and value > key.max:
        raise InputError(f"{where}: key '{name}': {value!r} is out of range "
                         f"[{key.min if key.min is not None else '-inf'}, {key.max if key.max is not None else 'inf'}]")
    if key.choices and value not in key.choices:
        raise InputError(f"{where}: key '{name}': '{value}' is not one of {', '.join(key.choices)}")
    return value


def config_from_dict(data: dict, source: str = "<config>", text: str = "") -> Config:
    sections: dict[str, dict[str, Any]] = {}
    for section, table in data.items():
        if section not in SCHEMA:
            raise InputError(f"{source}: unknown section '[{section}]' (known: {', '.join(SCHEMA)})")
        if not isinstance(table, dict):
            raise InputError(f"{source}: '{section}' must be a table")
    for section, keys in SCHEMA.items():
        given = data.get(section, {})
        values: dict[str, Any] = {}
        for name, value in given.items():
            if (section, name) in TABLES:
                if not isinstance(value, dict):
                    raise InputError(f"{source}: key '{section}.{name}': must be a table")
                values[name] = value
                continue
            if name not in keys:
                raise InputError(f"{source}: unknown key '{section}.{name}'")
            values[name] = _check_value(f"{section}.{name}", keys[name], value, source)
        for name, key in keys.items():
            if name not in values:
                if key.default is REQUIRED:
                    raise InputError(f"{source}: missing key '{section}.{name}' ({key.doc})")
                values[name] = key.default
        sections[section] = values
    config = Config(sections, source, text)
    _check_consistency(config)
    return config


def _check_consistency(config: Config) -> None:
    src = config.source
    axis, plan = config["axis"], config["plan"]
    if (axis["kind"] == "linear") != (axis["unit"] == "mm"):
        raise InputError(f"{src}: key 'axis.unit': '{axis['unit']}' does not fit kind '{axis['kind']}' "
                         "(linear uses mm, rotary uses deg)")
    if axis["soft_limit_min"] >= axis["soft_limit_max"]:
        raise InputError(f"{src}: key 'axis.soft_limit_max': must be above axis.soft_limit_min")
    if plan["targets"] is None and (plan["length"] is None or plan["count"] is None):
        raise InputError(f"{src}: key 'plan.targets': give plan.targets, or plan.length and plan.count")
    if plan["targets"] is not None and (plan["length"] is not None or plan["count"] is not None):
        raise InputError(f"{src}: key 'plan.targets': give either targets or length/count, not both")
    if plan["targets"] is not None:
        t = plan["targets"]
        if len(t) < 2 or any(b <= a for a, b in itertools.pairwise(t)):
            raise InputError(f"{src}: key 'plan.targets': needs at least 2 strictly increasing targets")
    env = config["environment"]
    if axis["kind"] == "rotary" and (env["air_correction"] != "none" or env["normalise_to_20c"]):
        raise InputError(f"{src}: key 'environment.air_correction': air and temperature corrections are "
                         "for linear axes; a rotary axis (angles) takes none")
    if config["axis_driver"]["type"] == "ads" and config["instrument"]["type"] == "sim":
        raise InputError(f"{src}: key 'instrument.type': a real axis needs a real instrument (serial)")
    if config["instrument"]["type"] == "serial" and not config["instrument"]["port"]:
        raise InputError(f"{src}: key 'instrument.port': required for a serial instrument")
    LineFormat.from_dict(config["instrument"].get("line", {}), f"{src}: [instrument.line]")
    parse_faults(config["sim"].get("faults", {}), src)
    if "effects" in config["sim"]:
        model_from_dict({"effects": config["sim"]["effects"]}, f"{src}: [sim.effects]")


def parse_config(text: str, source: str = "<config>") -> Config:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: not valid TOML ({exc})") from None
    return config_from_dict(data, source, text)


def load_config(path: str | Path) -> Config:
    """Read and validate a config file. InputError (exit 2) names the file and the key."""
    text = read_input_text(path, "a config file")
    return parse_config(text, str(path))


def _json_value(value: Any) -> Any:
    """`value` as it reads back from JSON (tuples become lists), for comparing with a record."""
    return json.loads(json.dumps(value, default=str))


def recorded_sections(config: Config) -> dict[str, Any]:
    """The config's sections as JSON values, kept in a campaign's meta.json."""
    return _json_value(config.sections)


def resume_conflicts(recorded: dict[str, Any], config: Config) -> list[str]:
    """The keys of `config` that differ from the `recorded` sections (see `recorded_sections`) and
    may not change before a resume (`Key.resume`), as "section.key is X now, Y when recorded".
    Sub-tables ([instrument.line], [sim.effects]) must not change; rehearsed [sim.faults] may."""
    found = []
    for section, keys in SCHEMA.items():
        now, then = config.sections.get(section, {}), recorded.get(section, {})
        names = [n for n, k in keys.items() if not k.resume]
        names += [n for s, n in TABLES if s == section and n != "faults"]
        for name in names:
            a, b = _json_value(now.get(name)), then.get(name)
            if a != b:
                found.append(f"{section}.{name} is {_show(a)} now, {_show(b)} when recorded")
    return found


def _show(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def schema_markdown() -> str:
    """docs/config.md: every section and key with type, default and meaning."""
    out = ["# Campaign configuration (TOML)", "",
           "Generated from `campaign/config.py` by `python -m campaign.config`. Examples are in",
           "`data/configs/`. An unknown key or an out-of-range value stops the command with exit status 2",
           "and one line naming the key.", ""]
    for section, keys in SCHEMA.items():
        out += [f"## [{section}]", "", "| key | type | default | meaning |", "|---|---|---|---|"]
        for name, key in keys.items():
            default = "required" if key.default is REQUIRED else ("—" if key.default is None else repr(key.default))
            extra = f" One of: {', '.join(key.choices)}." if key.choices else ""
            rng = ""
            if key.min is not None or key.max is not None:
                rng = f" Range [{key.min if key.min is not None else '−∞'}, {key.max if key.max is not None else '∞'}]."
            again = " May change before `axiscal resume`." if key.resume else ""
            out.append(f"| `{name}` | {key.type.__name__} | {default} | {key.doc}.{extra}{rng}{again} |")
        out.append("")
    out += ["## Sub-tables", "",
            "- `[instrument.line]`: the serial line format (see `docs/serial-line.md`).",
            ("- `[sim.effects.NAME]`: the simulated machine's error model, one table per effect "
            "(see `docs/error-model.md`)."),
            "- `[sim.faults]`: faults injected into the simulated machine (see `docs/faults.md`).", ""]
    return "\n".join(out)


if __name__ == "__main__":
    print(schema_markdown(), end="")

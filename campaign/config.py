"""The campaign configuration: one TOML file per campaign.

The schema below is the documentation: `docs/config.md` is generated from it
(`python -m campaign.config > docs/config.md`, checked by a test). An unknown key or an
out-of-range value raises InputError naming the key.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from campaign import capture_methods
from campaign.errors import InputError, read_input_text
from campaign.faults import parse_faults
from campaign.model import model_from_dict
from campaign.specs import (
    JUDGED_PURPOSES,
    REQUIRED,
    AxisSpec,
    CampaignSpec,
    CaptureSpec,
    ControllerSpec,
    DriverSpec,
    EnvironmentSpec,
    FaultPolicy,
    InstrumentSpec,
    Key,
    PlanSpec,
    SimSpec,
    frozen,
    plain,
)
from protocols.serial_line import LineFormat

SECTIONS: dict[str, tuple[type, ...]] = {
    "campaign": (CampaignSpec, FaultPolicy),
    "axis": (AxisSpec,),
    "plan": (PlanSpec,),
    "axis_driver": (ControllerSpec,),
    "instrument": (InstrumentSpec,),
    "environment": (EnvironmentSpec,),
    "capture": (CaptureSpec,),
    "sim": (SimSpec,),
}
"""Each section of the TOML file and the specs that own its keys (campaign.specs)."""

SCHEMA: dict[str, dict[str, Key]] = {
    section: {f.name: f.metadata["key"] for spec in specs for f in fields(spec) if "key" in f.metadata}
    for section, specs in SECTIONS.items()}
"""Every key of every section, from the specs' fields."""

TABLES = {("instrument", "line"), ("sim", "effects"), ("sim", "faults")}
"""Sub-tables validated elsewhere: the serial line format, the error model, the faults."""


def _keys(spec: type, values: Mapping[str, Any]) -> dict[str, Any]:
    """The values of `spec`'s key fields (lists as tuples: a spec is immutable)."""
    return {f.name: tuple(values[f.name]) if isinstance(values[f.name], list) else values[f.name]
            for f in fields(spec) if "key" in f.metadata}


@dataclass(frozen=True)
class Config:
    """A validated config: `sections[name][key]` with every default filled in (as recorded in
    meta.json), the TOML it came from (`data`, `text`, `source`) and the typed specs the rooms read
    (`config.axis`, `config.plan`, ...). Made by `config_from_dict`; `config_with` makes a changed
    copy (validated again). Nothing writes into it."""

    sections: Mapping[str, Mapping[str, Any]]
    source: str
    text: str
    data: Mapping[str, Any]
    campaign: CampaignSpec
    faults: FaultPolicy
    axis: AxisSpec
    plan: PlanSpec
    controller: ControllerSpec
    instrument: InstrumentSpec
    environment: EnvironmentSpec
    capture: CaptureSpec
    sim: SimSpec

    @property
    def base_dir(self) -> Path:
        return Path(self.source).resolve().parent

    @property
    def driver(self) -> DriverSpec:
        """What drivers.factory opens for this campaign."""
        return DriverSpec(self.axis, self.controller, self.instrument, self.sim,
                          vacuum_readings=self.environment.air_correction == "edlen",
                          start_position=self.plan.start, source=self.source)

    @property
    def simulated(self) -> bool:
        """The axis or the laser is simulated."""
        return "sim" in (self.controller.type, self.instrument.type)


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
    choices = key.options()
    if choices and value not in choices:
        raise InputError(f"{where}: key '{name}': '{value}' is not one of {', '.join(choices)}")
    return value


def config_from_dict(data: Mapping[str, Any], source: str = "<config>", text: str = "") -> Config:
    """Validate the TOML `data` and resolve it into specs, once. InputError names the key and `source`."""
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
                raise InputError(f"{source}: unknown key '{section}.{name}'{did_you_mean(name, keys)}")
            values[name] = _check_value(f"{section}.{name}", keys[name], value, source)
        for name, key in keys.items():
            if name not in values:
                if key.default is REQUIRED:
                    raise InputError(f"{source}: missing key '{section}.{name}' ({key.doc})")
                values[name] = key.default
        sections[section] = values
    _check_consistency(sections, source)
    s = sections
    base_dir = str(Path(source).resolve().parent)
    line = LineFormat.from_dict(s["instrument"].get("line", {}), f"{source}: [instrument.line]")
    sim = SimSpec(**_keys(SimSpec, s["sim"]), effects=frozen(s["sim"].get("effects")),
                  faults=frozen(s["sim"].get("faults", {})), base_dir=base_dir, source=source)
    return Config(frozen(sections), source, text, frozen(copy.deepcopy(dict(data))),
                  CampaignSpec(**_keys(CampaignSpec, s["campaign"])), FaultPolicy(**_keys(FaultPolicy, s["campaign"])),
                  AxisSpec(**_keys(AxisSpec, s["axis"])), PlanSpec(**_keys(PlanSpec, s["plan"])),
                  ControllerSpec(**_keys(ControllerSpec, s["axis_driver"])),
                  InstrumentSpec(**_keys(InstrumentSpec, s["instrument"]), line=line),
                  EnvironmentSpec(**_keys(EnvironmentSpec, s["environment"])),
                  CaptureSpec(**_keys(CaptureSpec, s["capture"])), sim)


def config_from_sections(sections: Mapping[str, Any], source: str) -> Config:
    """The config a campaign recorded (`recorded_sections`, in meta.json and plan.jsonl), validated
    again: None stands for a key the file did not give."""
    if not isinstance(sections, Mapping) or not all(isinstance(t, Mapping) for t in sections.values()):
        raise InputError(f"{source}: the recorded config is not a table of sections")
    data = {section: {k: v for k, v in table.items() if v is not None} for section, table in sections.items()}
    return config_from_dict(data, source)


def config_with(config: Config, changes: Mapping[str, Mapping[str, Any]]) -> Config:
    """A copy of `config` with the keys in `changes` (`{section: {key: value}}`) replaced and
    validated again, as if the file had said so (a sub-table given as {} is removed, a key given
    as None too: as if the file had not given it). The text and the source stay those of the file."""
    data = plain(config.data)
    for section, values in changes.items():
        table = data.setdefault(section, {})
        for name, value in values.items():
            if value is None or (section, name) in TABLES and not value:
                table.pop(name, None)
            else:
                table[name] = plain(value)
    return config_from_dict(data, config.source, config.text)


def did_you_mean(name: str, keys: Mapping[str, Any]) -> str:
    """"; did you mean 'dwell_s'?" for a mistyped key of the section whose keys are `keys`; "" when none is close."""
    import difflib

    close = difflib.get_close_matches(name, list(keys), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _section_values(section: str, given: Mapping[str, Any], where: str) -> dict[str, Any]:
    """One section's keys checked and its defaults filled in (sub-tables are not taken here)."""
    keys = SCHEMA[section]
    values: dict[str, Any] = {}
    for name, value in given.items():
        if name not in keys:
            raise InputError(f"{where}: unknown key '{section}.{name}'{did_you_mean(name, keys)}")
        values[name] = _check_value(f"{section}.{name}", keys[name], value, where)
    for name, key in keys.items():
        if name not in values:
            if key.default is REQUIRED:
                raise InputError(f"{where}: missing key '{section}.{name}' ({key.doc})")
            values[name] = key.default
    return values


def capture_spec(given: Mapping[str, Any], where: str) -> CaptureSpec:
    """A CaptureSpec from its keys (a capture record of a plan), validated as the [capture] table is."""
    if not isinstance(given, Mapping):
        raise InputError(f"{where}: the capture spec must be a table")
    return CaptureSpec(**_keys(CaptureSpec, _section_values("capture", given, where)))


RECORD_NAME = re.compile(r"[A-Za-z0-9_\-:;<>\[\]]+")
RECORD_NAME_MAX = 60
"""An EPICS record name: the characters EPICS base's database accepts, at most 60 of them
(PVNAME_STRINGSZ 61 with its terminating zero)."""


def _check_record_name(pv: str, simulated: bool, src: str) -> None:
    """`[axis_driver] pv` names a motor record (not one of its fields)."""
    where = f"{src}: key 'axis_driver.pv'"
    if not pv:
        if simulated:
            return  # the simulated IOC serves SIM:M1
        raise InputError(f"{where}: required for a real IOC's motor record (e.g. pv = \"BL01:MOT1\")")
    if "." in pv:
        raise InputError(f"{where}: '{pv[:80]}' names a field; give the motor record's name without "
                         f"'.{pv.partition('.')[2][:20]}' (axiscal reads and writes its fields itself)")
    if len(pv) > RECORD_NAME_MAX:
        raise InputError(f"{where}: {len(pv)} characters; an EPICS record name has at most {RECORD_NAME_MAX}")
    if not RECORD_NAME.fullmatch(pv):
        bad = next(c for c in pv if not RECORD_NAME.fullmatch(c))
        raise InputError(f"{where}: {bad!a} is not allowed in an EPICS record name (ASCII letters, "
                         "digits and _-:;<>[] only, no spaces)")


def _check_scan(s: Mapping[str, Mapping[str, Any]], src: str) -> None:
    """A method that sweeps (campaign.capture_methods) needs its velocity, within the axis's."""
    capture, axis, plan = s["capture"], s["axis"], s["plan"]
    method = capture_methods.method(capture["method"])
    if not method.live:
        raise InputError(f"{src}: key 'capture.method': \"{method.name}\" is not run by axiscal itself (the "
                         f"stream import's own: axiscal import-stream); axiscal runs "
                         f"{', '.join(capture_methods.names(live=True))}")
    if not method.iso_230_2 and s["campaign"]["purpose"] in JUDGED_PURPOSES:
        raise InputError(f"{src}: key 'campaign.purpose': capture.method = \"{method.name}\" is not an ISO 230-2 "
                         f"test and gets no pass/fail: set purpose = \"diagnostic\" (or \"follow-up\"), not "
                         f"\"{s['campaign']['purpose']}\"")
    if not method.sweeps:
        return
    v, unit = capture["scan_velocity"], axis["unit"]
    if v is None:
        raise InputError(f"{src}: key 'capture.scan_velocity': required with capture.method = "
                         f"\"{capture['method']}\" ({unit}/s)")
    if v > axis["max_velocity"]:
        raise InputError(f"{src}: key 'capture.scan_velocity': {v:g} {unit}/s is above axis.max_velocity = "
                         f"{axis['max_velocity']:g} {unit}/s")
    if plan["cycle"] != "linear":
        raise InputError(f"{src}: key 'plan.cycle': a scan sweeps the whole travel (linear), not the pilgrim "
                         "step cycle")


def _check_consistency(s: Mapping[str, Mapping[str, Any]], src: str) -> None:
    axis, plan = s["axis"], s["plan"]
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
    _check_scan(s, src)
    env, driver, instrument = s["environment"], s["axis_driver"], s["instrument"]
    if axis["kind"] == "rotary" and (env["air_correction"] != "none" or env["normalise_to_20c"]):
        raise InputError(f"{src}: key 'environment.air_correction': air and temperature corrections are "
                         "for linear axes; a rotary axis (angles) takes none")
    if driver["type"] == "ads" and instrument["type"] == "sim":
        raise InputError(f"{src}: key 'instrument.type': a real axis needs a real instrument (serial)")
    if driver["type"] == "epics":
        _check_record_name(driver["pv"], instrument["type"] == "sim", src)
    if instrument["type"] == "serial" and not instrument["port"]:
        raise InputError(f"{src}: key 'instrument.port': required for a serial instrument")
    parse_faults(s["sim"].get("faults", {}), src)
    if "effects" in s["sim"]:
        model_from_dict({"effects": s["sim"]["effects"]}, f"{src}: [sim.effects]")


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
    return _json_value(plain(config.sections))


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
            a, b = _json_value(plain(now.get(name))), then.get(name)
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
           "and one line naming the key (a mistyped key gets the nearest known one: \"did you mean 'dwell_s'?\").",
           ""]
    for section, keys in SCHEMA.items():
        out += [f"## [{section}]", "", "| key | type | default | meaning |", "|---|---|---|---|"]
        for name, key in keys.items():
            default = "required" if key.default is REQUIRED else ("—" if key.default is None else repr(key.default))
            extra = f" One of: {', '.join(key.options())}." if key.options() else ""
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


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")


def _toml_key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name, ensure_ascii=False)


def config_toml(data: Mapping[str, Any], prefix: str = "") -> str:
    """A config's tables (plain or frozen, e.g. `config.data` of a changed copy) as TOML that
    `parse_config` reads back: the keys of a table, then its sub-tables
    ([sim.effects.NAME], [sim.faults.NAME], [instrument.line]); a key whose value is None is left out."""
    data = plain(data)
    lines: list[str] = []
    keys = {k: v for k, v in data.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    if prefix and (keys or not tables):
        lines.append(f"[{prefix}]")
    lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in keys.items() if v is not None]
    if keys:
        lines.append("")
    for name, table in tables.items():
        lines.append(config_toml(table, f"{prefix}.{_toml_key(name)}" if prefix else _toml_key(name)))
    return "\n".join(lines)

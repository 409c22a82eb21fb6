"""The interferometer's ASCII line protocol, as pure code (no I/O).

Default line format (`LineFormat()`), one reading per line:

    POS,<time_s>,<position>,<signal_pct>,<air_temp_c>,<air_pressure_hpa>,<humidity_pct>,<material_temp_c>*HH

    POS,12.5,100.00125,87.5,20.31,1013.25,45.2,20.07*77\\r\\n

- `POS` is the tag; lines with another tag (status lines, echoes) are not readings.
- time_s: the instrument's timestamp, s. position: axis unit (mm or deg) after `position_scale`.
  signal_pct: beam signal strength, % of full scale. air_temp_c °C, air_pressure_hpa hPa,
  humidity_pct % RH, material_temp_c °C.
- An empty field means "not present" (the Reading gets None). time_s, position and the signal
  field(s) must not be empty.
- Numbers are plain decimals with an optional exponent (`-1.5`, `2e-3`); `nan`, `inf`, `1_0` and
  numbers that overflow to infinity are rejected. Spaces and tabs around a field are ignored.
- `*HH` is the XOR of the codes of every character before the `*`, as two hex digits (either
  case when reading, upper case when writing). It is on by default, so a corrupt line or two
  lines run together are detected.
- The line ends in CRLF (written) or LF; a trailing CR/LF is optional when parsing one line.
- In query mode the host sends `?\\r\\n` and the instrument answers with one such line.

Another instrument is described by data, not code: `LineFormat.from_dict` reads a config table,
e.g. `{"tag": "", "separator": ";", "decimal_mark": ",", "fields": ["time_s", "position",
"beam_ok"], "position_scale": 0.001, "checksum": false, "beam_ok_text": "OK",
"beam_lost_text": "LOST"}` for `12,5;100001,25;OK` with the position in µm.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import reduce
from operator import xor
from typing import Any

from protocols.errors import FormatError
from protocols.hardware import Reading

FIELD_NAMES = (
    "time_s",
    "position",
    "signal_pct",
    "beam_ok",
    "air_temp_c",
    "air_pressure_hpa",
    "humidity_pct",
    "material_temp_c",
    "skip",
)
"""The vocabulary of `LineFormat.fields`; `skip` is a field that is read and ignored."""

_OPTIONAL_NUMBERS = ("air_temp_c", "air_pressure_hpa", "humidity_pct", "material_temp_c")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_HEX2 = re.compile(r"[0-9A-Fa-f]{2}")


class LineError(ValueError):
    """A line that is not a valid reading: garbage, partial, bad checksum or a non-finite number."""


@dataclass(frozen=True)
class LineFormat:
    """How one reading is written on the serial line.

    tag: the first field of every reading line; "" for formats without one.
    separator: between fields. decimal_mark: "." or ",".
    fields: the field names in line order, from FIELD_NAMES. Must contain time_s, position and
        signal_pct or beam_ok.
    position_scale: axis unit per instrument unit (0.001 for µm → mm, 25.4 for inch → mm).
    signal_threshold_pct: the beam is OK when signal_pct >= this, %.
    beam_ok_text / beam_lost_text: the values of a beam_ok field.
    checksum: lines end in `*HH` (XOR of all characters before the `*`).
    line_end: written after each line; the driver splits lines at its last character.
    request: what the host sends to ask for one reading in query mode.
    """

    tag: str = "POS"
    separator: str = ","
    decimal_mark: str = "."
    fields: tuple[str, ...] = (
        "time_s",
        "position",
        "signal_pct",
        "air_temp_c",
        "air_pressure_hpa",
        "humidity_pct",
        "material_temp_c",
    )
    position_scale: float = 1.0
    signal_threshold_pct: float = 20.0
    beam_ok_text: str = "1"
    beam_lost_text: str = "0"
    checksum: bool = True
    line_end: str = "\r\n"
    request: str = "?\r\n"

    def __post_init__(self) -> None:
        for problem in _problems(self):
            raise ValueError(problem)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str) -> LineFormat:
        """A LineFormat from a config table; `where` names the table in error messages
        (e.g. `campaign.toml [instrument.line]`). Missing keys take the defaults.

        Raises FormatError with a one-line message naming the key for an unknown key or a bad value.
        """
        known = {f.name for f in dataclasses.fields(cls)}
        for key in d:
            if key not in known:
                raise FormatError(f"{where}: unknown key '{key}' (known: {', '.join(sorted(known))})")
        values = dict(d)
        if "fields" in values:
            if not isinstance(values["fields"], (list, tuple)):
                raise FormatError(f"{where}: key 'fields': must be a list of field names")
            values["fields"] = tuple(values["fields"])
        try:
            return cls(**values)
        except ValueError as e:
            raise FormatError(f"{where}: {e}") from None

    @property
    def terminator(self) -> str:
        """The character at which the driver splits the byte stream into lines."""
        return self.line_end[-1]


def _problems(fmt: LineFormat) -> Iterator[str]:
    """Yield one message per bad value of fmt, each naming the key."""
    for key in ("tag", "separator", "decimal_mark", "beam_ok_text", "beam_lost_text", "line_end", "request"):
        value = getattr(fmt, key)
        if not isinstance(value, str) or not value.isascii():
            yield f"key '{key}': must be an ASCII string"
    for key in ("separator", "line_end", "request", "beam_ok_text", "beam_lost_text"):
        if getattr(fmt, key) == "":
            yield f"key '{key}': must not be empty"
    if fmt.decimal_mark not in (".", ","):
        yield "key 'decimal_mark': must be '.' or ','"
    if (
        fmt.decimal_mark in fmt.separator
        or "*" in fmt.separator
        or fmt.separator.strip("\r\n") != fmt.separator
    ):
        yield f"key 'separator': {fmt.separator!r} cannot separate fields"
    if fmt.separator in fmt.tag or "*" in fmt.tag:
        yield "key 'tag': must not contain the separator or '*'"
    if fmt.line_end.strip("\r\n") != "":
        yield "key 'line_end': must be CR, LF or CRLF"
    for key in ("beam_ok_text", "beam_lost_text"):
        value = getattr(fmt, key)
        if value.strip() != value or fmt.separator in value or "*" in value:
            yield f"key '{key}': must not contain spaces at its ends, the separator or '*'"
    if fmt.beam_ok_text == fmt.beam_lost_text:
        yield "key 'beam_lost_text': must differ from beam_ok_text"
    yield from _field_problems(fmt.fields)
    for key in ("position_scale", "signal_threshold_pct"):
        value = getattr(fmt, key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            yield f"key '{key}': must be a finite number"
    if fmt.position_scale == 0:
        yield "key 'position_scale': must not be 0"
    if not isinstance(fmt.checksum, bool):
        yield "key 'checksum': must be true or false"


def _field_problems(names: tuple[str, ...]) -> Iterator[str]:
    if not all(isinstance(name, str) for name in names):
        yield "key 'fields': must be a list of field names"
        return
    for name in names:
        if name not in FIELD_NAMES:
            yield f"key 'fields': unknown field '{name}' (known: {', '.join(FIELD_NAMES)})"
    for name in set(names) - {"skip"}:
        if names.count(name) > 1:
            yield f"key 'fields': '{name}' appears twice"
    for name in ("time_s", "position"):
        if name not in names:
            yield f"key 'fields': must contain {name}"
    if "signal_pct" not in names and "beam_ok" not in names:
        yield "key 'fields': must contain signal_pct or beam_ok"


def checksum_hex(body: str) -> str:
    """The XOR of the character codes of body, as two upper-case hex digits."""
    low_bytes = body.encode("utf-32-le", "surrogatepass")[::4]  # each character's code & 0xFF
    return f"{reduce(xor, low_bytes, 0):02X}"


def parse_line(text: str, fmt: LineFormat) -> Reading:
    """The Reading carried by one line (with or without its line end).

    Raises LineError for anything that is not a complete, valid reading line in format fmt.
    """
    body = text.rstrip("\r\n")
    if fmt.checksum:
        body, star, given = body.rpartition("*")
        if not star or not _HEX2.fullmatch(given):
            raise LineError("no *HH checksum at the end of the line")
        if given.upper() != checksum_hex(body):
            raise LineError(f"checksum {given} does not match the line (expected {checksum_hex(body)})")
    parts = [part.strip(" \t") for part in body.split(fmt.separator)]
    if fmt.tag:
        if parts[0] != fmt.tag:
            raise LineError(f"line does not start with {fmt.tag!r}")
        parts = parts[1:]
    if len(parts) != len(fmt.fields):
        raise LineError(f"{len(parts)} fields, expected {len(fmt.fields)}")
    values = dict(zip(fmt.fields, parts))

    time_s = _number(values["time_s"], "time_s", fmt)
    position = _number(values["position"], "position", fmt) * fmt.position_scale
    if not math.isfinite(position):
        raise LineError("position overflows after scaling")
    signal_ok = True
    signal_pct = None
    if "signal_pct" in values:
        signal_pct = _number(values["signal_pct"], "signal_pct", fmt)
        signal_ok = signal_pct >= fmt.signal_threshold_pct
    if "beam_ok" in values:
        if values["beam_ok"] not in (fmt.beam_ok_text, fmt.beam_lost_text):
            raise LineError(f"beam_ok field {values['beam_ok']!r} is neither of the beam texts")
        signal_ok = signal_ok and values["beam_ok"] == fmt.beam_ok_text
    env = {name: _number(values[name], name, fmt) if values.get(name) else None for name in _OPTIONAL_NUMBERS}
    return Reading(time_s=time_s, position=position, signal_ok=signal_ok, signal_pct=signal_pct, **env)


def _number(text: str, name: str, fmt: LineFormat) -> float:
    if fmt.decimal_mark == ",":
        if "." in text:
            raise LineError(f"{name}: {text!r} is not a number")
        text = text.replace(",", ".")
    if not _NUMBER.fullmatch(text):
        raise LineError(f"{name}: {text!r} is not a number")
    value = float(text)
    if not math.isfinite(value):
        raise LineError(f"{name}: {text!r} is not finite")
    return value


def format_line(reading: Reading, fmt: LineFormat) -> str:
    """The line (with line end) that carries reading in format fmt; parse_line reads it back.

    Raises ValueError when fmt has a signal_pct field and the reading has no signal_pct.
    """
    parts = [fmt.tag] if fmt.tag else []
    for name in fmt.fields:
        if name == "skip":
            parts.append("")
        elif name == "beam_ok":
            parts.append(fmt.beam_ok_text if reading.signal_ok else fmt.beam_lost_text)
        elif name == "position":
            parts.append(_format_number(reading.position / fmt.position_scale, fmt))
        else:
            value = getattr(reading, name)
            if value is None and name in ("time_s", "signal_pct"):
                raise ValueError(f"the reading has no {name}")
            parts.append("" if value is None else _format_number(value, fmt))
    body = fmt.separator.join(parts)
    if fmt.checksum:
        body += "*" + checksum_hex(body)
    return body + fmt.line_end


def _format_number(value: float, fmt: LineFormat) -> str:
    if not math.isfinite(value):
        raise ValueError(f"cannot write the non-finite number {value}")
    return repr(float(value)).replace(".", fmt.decimal_mark)

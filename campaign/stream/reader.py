"""Read a continuous stream CSV: `time_s` (s) and a reading in the axis unit.

The reading column is the first of POSITION_COLUMNS present. Optional environment columns
(air_temp_c °C, air_pressure_hpa hPa, humidity_pct %, material_temp_c °C) are kept when every value
is a number. Other columns are ignored. Lines starting with `#` are comments. Bad input raises
InputError naming the file and line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from campaign.errors import InputError, read_input_bytes
from protocols.hardware import ENV_FIELDS

if TYPE_CHECKING:
    import pandas as pd

POSITION_COLUMNS = {
    "mm": ("reading_mm", "position_mm", "reading", "position"),
    "deg": ("reading_deg", "position_deg", "reading", "position"),
}
"""Axis unit -> accepted reading columns, in order of preference."""


@dataclass
class Stream:
    """A parsed stream: sample times (s), readings (axis unit), environment columns (per sample)."""

    source: str
    column: str
    time: np.ndarray
    reading: np.ndarray
    env: dict[str, np.ndarray]
    warnings: list[str]


def _line_of_row(path: str, row: int) -> int:
    """The file line (1-based) of data row `row` (0-based), skipping the header, blank and # lines."""
    seen = -2  # the header is the first non-comment line
    with open(path, encoding="utf-8-sig", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            stripped = line.strip()
            if not stripped or stripped.startswith("#"):
                continue
            seen += 1
            if seen == row:
                return number
    return number


def locate(path: str, row: int, time: np.ndarray | None = None) -> str:
    """'FILE:LINE' of data row `row` (0-based), with ' (t = T s)' when the sample times are given."""
    where = f"{path}:{_line_of_row(path, row)}"
    return where if time is None else f"{where} (t = {time[row]:.3f} s)"


def _numeric(frame: pd.DataFrame, column: str) -> np.ndarray | int:
    """The column as float64, or the row index of its first value that is not a finite number."""
    import pandas as pd

    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    return int(np.argmax(bad)) if bad.any() else values


def read_stream(path: str, unit: str) -> Stream:
    """Read and check a stream CSV. InputError (exit 2) names the file, line and column."""
    import pandas as pd

    head = read_input_bytes(path, "a stream CSV", limit=65536)
    if b"\x00" in head:
        raise InputError(f"{path}: not a CSV text file (binary data)")
    try:
        header = [str(c).strip() for c in pd.read_csv(path, comment="#", encoding="utf-8-sig", nrows=0).columns]
        column = _reading_column(header, path, unit)
        frame = pd.read_csv(path, comment="#", encoding="utf-8-sig", skipinitialspace=True, low_memory=False,
                            keep_default_na=False, na_values=[""])  # only an empty cell is missing: 'nan' is said as written
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file is empty") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (bad byte at offset {exc.start})") from None
    except (ValueError, OverflowError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"{path}: not a readable CSV file ({reason[:120]})") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    return stream_from_frame(frame, path, column)


def _reading_column(header: list[str], path: str, unit: str) -> str:
    """The reading column of a stream header; InputError when it or time_s is missing."""
    column = next((c for c in POSITION_COLUMNS[unit] if c in header), None)
    if "time_s" not in header or column is None:
        missing = "'time_s'" if "time_s" not in header else f"a reading ({', '.join(POSITION_COLUMNS[unit])})"
        found = ", ".join(repr(c[:30]) for c in header[:8])
        hint = " (wrong delimiter? use commas)" if len(header) == 1 else ""
        raise InputError(f"{path}: missing column {missing}; found {found}{hint}")
    return column


def stream_from_frame(frame: pd.DataFrame, path: str, column: str) -> Stream:
    """Check the parsed columns (finite numbers, time never going back) and build the Stream."""
    columns = list(frame.columns)
    if frame.empty:
        raise InputError(f"{path}: the header has no data rows")
    arrays = {}
    for name in ("time_s", column):
        got = _numeric(frame, name)
        if isinstance(got, int):
            cell = frame[name].iloc[got]
            if isinstance(cell, float) and math.isnan(cell):  # an empty cell (na_values), or none: a short row
                raise InputError(f"{locate(path, got)}: column '{name}': no value (an empty cell, or a row cut short)")
            raise InputError(f"{locate(path, got)}: column '{name}': {str(cell)[:40]!r} is not a finite number")
        arrays[name] = got
    time = arrays["time_s"]
    back = np.flatnonzero(np.diff(time) < 0)
    if back.size:
        raise InputError(f"{locate(path, int(back[0]) + 1)}: column 'time_s': time goes backwards "
                         f"({time[back[0]]:g} s, then {time[back[0] + 1]:g} s)")
    env, warnings = {}, []
    for name in ENV_FIELDS:
        if name in columns:
            got = _numeric(frame, name)
            if isinstance(got, int):
                warnings.append(f"column '{name}' ignored: not a number at {locate(path, got)}")
            else:
                env[name] = got
    return Stream(path, column, time, arrays[column], env, warnings)

"""The point table: the dataset every part of axiscal exchanges.

A CSV file with a header row (UTF-8, BOM allowed, LF or CRLF). Lines starting with `#` are
comments; a comment of the form `# key: value` is kept as metadata. Columns:

- `run`: integer from 1 to MAX_RUN;
- `direction`: `+` (approach in increasing position) or `-` (decreasing);
- `target_mm` with `deviation_um` (linear axis) or `target_deg` with `deviation_arcsec` (rotary);
  deviation = measured position - target, the ISO 230-2 sign;
- optional: `time_s` (s since campaign start), `air_temp_c` (°C), `air_pressure_hpa` (hPa),
  `humidity_pct` (% RH), `material_temp_c` (°C).

Any other column is ignored by the evaluation; those whose every value is a finite number are
kept in `PointTable.extra` (a recorded campaign's `point`, `capture_wait_s`, `samples`, ...). The Unicode minus sign U+2212 is
read as `-`. A table with a `point` column (the plan index, written by axiscal's recorder) is read
in plan order, whatever order its rows were measured in. Bad input raises `InputError` naming the file, line and column.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from campaign.errors import InputError, read_input_bytes
from protocols.units import UNITS

AXIS_KINDS = {
    "linear": ("target_mm", "deviation_um"),
    "rotary": ("target_deg", "deviation_arcsec"),
}
"""Axis kind -> (target column, deviation column)."""

OPTIONAL_COLUMNS = ("time_s", "air_temp_c", "air_pressure_hpa", "humidity_pct", "material_temp_c")

MAX_RUN = 1_000_000
"""The largest run number a table may hold (a campaign has a few runs; a number such as 1E100 is not one,
and would not fit an integer array)."""
MINUS_SIGNS = str.maketrans({"\u2212": "-", "\u2013": "-"})


@dataclass
class PointTable:
    """A parsed point table; one array element per captured point, in file order, or in plan order when the table has a `point` column.

    run: run number (>= 1). direction: +1 or -1. target: axis unit (mm or deg).
    deviation: measured - target, in µm (linear) or arcsec (rotary).
    optional: the optional columns present, e.g. {"time_s": array of s}.
    extra: the other columns whose every value is a finite number, e.g. {"point": plan indices}.
    meta: `# key: value` comment metadata.
    """

    kind: str
    run: np.ndarray
    direction: np.ndarray
    target: np.ndarray
    deviation: np.ndarray
    optional: dict[str, np.ndarray] = field(default_factory=dict)
    meta: dict[str, str] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<memory>"

    @property
    def position_unit(self) -> str:
        return UNITS[self.kind][0]

    @property
    def deviation_unit(self) -> str:
        return UNITS[self.kind][1]

    @property
    def directions(self) -> list[int]:
        """The directions present, +1 first."""
        return sorted({int(d) for d in self.direction}, reverse=True)

    def __len__(self) -> int:
        return len(self.run)


def _fail(path: str, message: str, line: int | None = None, column: str | None = None) -> InputError:
    where = path
    if line is not None:
        where += f":{line}"
    if column is not None:
        where += f": column '{column}'"
    return InputError(f"{where}: {message}")


def _number(text: str, path: str, line: int, column: str) -> float:
    cleaned = text.strip().translate(MINUS_SIGNS)
    try:
        value = float(cleaned)
    except ValueError:
        raise _fail(path, f"'{text.strip()[:40]}' is not a number", line, column) from None
    if not math.isfinite(value):
        raise _fail(path, f"'{text.strip()[:40]}' is not a finite number", line, column)
    return value


def decode_csv(path: str, raw: bytes) -> str:
    """A CSV file's bytes as text (UTF-8, a BOM dropped); InputError when empty, binary or not UTF-8."""
    if not raw.strip():
        raise _fail(path, "the file is empty")
    if b"\x00" in raw:
        raise _fail(path, "not a CSV text file (binary data)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise _fail(path, f"not UTF-8 text (bad byte at offset {exc.start})") from None


def split_csv(text: str) -> tuple[dict[str, str], list[str] | None, int, list[tuple[int, list[str]]]]:
    """A commented CSV text as axiscal writes them: its `# key: value` comments (metadata), its
    first row (the header, None when there is none) with its line number, and every later row as
    (line number, stripped cells). Blank lines and other comments are skipped."""
    header: list[str] | None = None
    header_line = 0
    meta: dict[str, str] = {}
    rows: list[tuple[int, list[str]]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            key, sep, value = stripped[1:].partition(":")
            if sep and key.strip() and " " not in key.strip():
                meta[key.strip()] = value.strip()
            continue
        cells = [c.strip() for c in stripped.split(",")]
        if header is None:
            header, header_line = cells, number
        else:
            rows.append((number, cells))
    return meta, header, header_line, rows


def parse_points(text: str, path: str = "<input>", partial: bool = False) -> PointTable:
    """Parse point-table CSV text. `path` is used only in error messages. `partial`: a campaign's
    table while it is recorded, whose targets need not all have the same directions yet."""
    meta, header, header_line, rows = split_csv(text)
    if header is None:
        raise _fail(path, "the file has no header row")
    kind = _kind_from_header(header, path, header_line)
    if not rows:
        raise _fail(path, "the header has no data rows", header_line)
    return _build(header, rows, kind, meta, path, partial)


def _kind_from_header(header: list[str], path: str, line: int) -> str:
    if len(header) == 1 and any(sep in header[0] for sep in (";", "\t", "|")):
        raise _fail(path, "not a comma-separated header (wrong delimiter?)", line)
    if len(set(header)) != len(header):
        raise _fail(path, "the header repeats a column name", line)
    kinds = [k for k, (tcol, dcol) in AXIS_KINDS.items() if tcol in header or dcol in header]
    if len(kinds) > 1:
        raise _fail(path, "the header mixes linear (mm/um) and rotary (deg/arcsec) columns", line)
    kind = kinds[0] if kinds else "linear"
    for column in ("run", "direction", *AXIS_KINDS[kind]):
        if column not in header:
            raise _fail(path, f"missing column '{column}'", line)
    return kind


def _build(header: list[str], rows: list[tuple[int, list[str]]], kind: str, meta: dict[str, str], path: str,
           partial: bool = False) -> PointTable:
    target_col, dev_col = AXIS_KINDS[kind]
    index = {name: i for i, name in enumerate(header)}
    optional = [c for c in OPTIONAL_COLUMNS if c in index]
    run, direction, target, deviation = [], [], [], []
    extra: dict[str, list[float]] = {c: [] for c in optional}
    seen: dict[tuple[int, int, float], int] = {}
    for number, cells in rows:
        if len(cells) != len(header):
            raise _fail(path, f"expected {len(header)} fields, found {len(cells)}", number)
        run_value = _number(cells[index["run"]], path, number, "run")
        if not 1 <= run_value <= MAX_RUN or run_value != int(run_value):
            raise _fail(path, f"run must be an integer from 1 to {MAX_RUN:,}, found '{cells[index['run']][:20]}'",
                        number, "run")
        sign = cells[index["direction"]].translate(MINUS_SIGNS)
        if sign not in ("+", "-"):
            raise _fail(path, f"unknown direction '{cells[index['direction']][:20]}' (use + or -)",
                        number, "direction")
        t = _number(cells[index[target_col]], path, number, target_col)
        key = (int(run_value), 1 if sign == "+" else -1, t)
        if key in seen:
            raise _fail(path, f"duplicate point: run {key[0]}, direction {sign}, target {t:g} "
                              f"(first on line {seen[key]})", number)
        seen[key] = number
        run.append(key[0])
        direction.append(key[1])
        target.append(t)
        deviation.append(_number(cells[index[dev_col]], path, number, dev_col))
        for c in optional:
            extra[c].append(_number(cells[index[c]], path, number, c))
    known = {"run", "direction", target_col, dev_col, *optional}
    others = {}
    for name, i in index.items():
        if name not in known:
            values = _numbers_or_none([cells[i] for _, cells in rows])
            if values is not None:
                others[name] = values
    table = PointTable(
        kind=kind,
        run=np.array(run, dtype=int),
        direction=np.array(direction, dtype=int),
        target=np.array(target, dtype=float),
        deviation=np.array(deviation, dtype=float),
        optional={c: np.array(v, dtype=float) for c, v in extra.items()},
        meta=meta,
        source=path,
        extra=others,
    )
    if "point" in others:
        table = _in_plan_order(table)
    if not partial:
        _check_directions(table, path)
    return table


def _in_plan_order(table: PointTable) -> PointTable:
    """A recorded campaign's table is written in measurement order; a point skipped after a fault
    and measured on resume comes last. Its `point` column (the plan index) gives the plan order."""
    order = np.argsort(table.extra["point"], kind="stable")
    if np.all(order == np.arange(len(order))):
        return table
    return replace(table, run=table.run[order], direction=table.direction[order], target=table.target[order],
                   deviation=table.deviation[order], optional={k: v[order] for k, v in table.optional.items()},
                   extra={k: v[order] for k, v in table.extra.items()})


def _numbers_or_none(cells: list[str]) -> np.ndarray | None:
    """The cells as floats when every one is a finite number, else None (a text column)."""
    try:
        values = np.array([float(c.translate(MINUS_SIGNS)) for c in cells], dtype=float)
    except ValueError:
        return None
    return values if np.all(np.isfinite(values)) else None


def _check_directions(table: PointTable, path: str) -> None:
    """Every target must be measured in the same set of directions."""
    per_target: dict[float, set[int]] = {}
    for t, d in zip(table.target, table.direction):
        per_target.setdefault(float(t), set()).add(int(d))
    sets = {frozenset(s) for s in per_target.values()}
    if len(sets) > 1:
        both = frozenset({1, -1})
        odd = sorted(t for t, s in per_target.items() if frozenset(s) != both)
        raise _fail(path, "directions do not match across targets: target(s) "
                          f"{', '.join(f'{t:g}' for t in odd[:5])} measured in one direction only, "
                          "others in both")


def read_points(path: str | Path, partial: bool = False) -> PointTable:
    """Read a point table from a file. Raises InputError for any bad input. `partial`: see
    `parse_points`."""
    name = str(path)
    return parse_points(decode_csv(name, read_input_bytes(path, "a point table")), name, partial)


def header_for(kind: str, optional: tuple[str, ...] = ()) -> list[str]:
    """The column names of a point table for an axis `kind`, with the optional columns given."""
    return ["run", "direction", *AXIS_KINDS[kind], *optional]


def format_row(run: int, direction: int, target: float, deviation: float,
               optional: tuple[float, ...] = ()) -> str:
    """One CSV data line (with LF). Target to 1e-6 axis unit, deviation to 1e-4 µm or arcsec,
    optional columns to 10 significant digits."""
    cells = [str(run), "+" if direction > 0 else "-", f"{target:.6f}", f"{deviation:.4f}"]
    cells += [f"{v:.10g}" for v in optional]
    return ",".join(cells) + "\n"


def write_points_text(table: PointTable) -> str:
    """The CSV text of a whole point table: its metadata as `# key: value` comments, the header,
    the rows."""
    optional = tuple(table.optional)
    lines = [f"# {k}: {v}\n" for k, v in table.meta.items()]
    lines.append(",".join(header_for(table.kind, optional)) + "\n")
    for i in range(len(table)):
        lines.append(format_row(int(table.run[i]), int(table.direction[i]), float(table.target[i]),
                                float(table.deviation[i]), tuple(float(table.optional[c][i]) for c in optional)))
    return "".join(lines)


def write_points(path: str | Path, table: PointTable) -> None:
    """Write a whole point table (used by import and replay; recording appends row by row)."""
    Path(path).write_text(write_points_text(table), encoding="utf-8")

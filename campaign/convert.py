"""Measurement files of other programs to and from the point table (`axiscal convert`).

Formats: `points` (axiscal's point table CSV, campaign.pointtable), `rtl` (Renishaw .rtl) and
`ecmc` (ecmc `*_ISO230.dat`); the text formats live in protocols.measurements. Metadata (machine,
axis, date, operator, environment) is carried both ways where the target format has a place for
it. Every output is written whole or not at all (a temporary file, fsynced, renamed).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from campaign import __version__
from campaign.errors import InputError, read_input_bytes
from campaign.pointtable import PointTable, parse_points, write_points_text
from protocols.measurements import Measurement, Row, ecmc, rtl

FORMATS = {"points": (".csv",), "rtl": (".rtl",), "ecmc": (".dat",)}
"""Format name -> the file extensions that choose it."""
READERS = {"rtl": rtl.parse, "ecmc": ecmc.parse}
WRITERS = {"rtl": rtl.render, "ecmc": ecmc.render}
ENVIRONMENT = ("air_temp_c", "air_pressure_hpa", "humidity_pct", "material_temp_c")
"""The point table's environment columns, carried as one mean value each."""


def format_of(path: str | Path, given: str | None) -> str:
    """`given`, else the format chosen by the file's extension; InputError when neither says."""
    if given:
        return given
    suffix = Path(path).suffix.lower()
    for name, suffixes in FORMATS.items():
        if suffix in suffixes:
            return name
    raise InputError(f"{path}: cannot tell the format from '{suffix or 'no extension'}': "
                     f"give --from/--to ({', '.join(FORMATS)})")


def read_any(path: str | Path, fmt: str, kind: str | None = None) -> PointTable:
    """The point table in `path`, a file of format `fmt`. `kind` (linear or rotary) for formats
    that do not say it. InputError or FormatError for bad input, naming the line."""
    raw = read_input_bytes(path, "a measurement file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")  # Windows programs write their code page; the numbers are ASCII
    if fmt == "points":
        return parse_points(text, str(path))
    return to_points(READERS[fmt](text, str(path), kind or "linear"), str(path), fmt)


def to_points(m: Measurement, source: str, fmt: str) -> PointTable:
    """The point table of a measurement, rows in the file's order, metadata kept."""
    meta = {**m.meta, "source": f"{Path(source).name} ({fmt})"}
    return PointTable(
        kind=m.kind,
        run=np.array([r.run for r in m.rows], dtype=int),
        direction=np.array([r.direction for r in m.rows], dtype=int),
        target=np.array([m.targets[r.target] for r in m.rows], dtype=float),
        deviation=np.array([r.deviation for r in m.rows], dtype=float),
        meta=meta,
        source=source,
    )


def from_points(table: PointTable) -> Measurement:
    """The measurement of a point table. The environment columns become their mean in the
    metadata (the formats hold one value per file)."""
    targets = sorted({float(t) for t in table.target})
    index = {t: i for i, t in enumerate(targets)}
    rows = tuple(Row(int(r), int(d), index[float(t)], float(e))
                 for r, d, t, e in zip(table.run, table.direction, table.target, table.deviation))
    meta = {**table.meta, "software": f"axiscal {__version__}"}
    for column in ENVIRONMENT:
        values = table.optional.get(column)
        if values is not None and column not in meta and np.all(np.isfinite(values)):
            meta[column] = f"{float(np.mean(values)):.2f}"
    return Measurement(table.kind, tuple(targets), rows, meta)


CARRIED_META = {"rtl": set(rtl.USER_TEXT.values()) | set(rtl.ENVIRONMENT.values()) | {"simulated", "software"}}
"""The metadata keys a format has a place for (besides its own `rtl.…` keys); a format not listed
keeps every key (ecmc and the point table: `# key: value` comments)."""


def not_carried(table: PointTable, fmt: str) -> list[str]:
    """What of `table` the format `fmt` has no place for, one phrase each: the per-point columns
    (environment columns are reduced to their mean), the metadata keys it cannot hold."""
    if fmt == "points":
        return []
    lost = []
    environment = [c for c in ENVIRONMENT if c in table.optional]
    if environment:
        lost.append(f"the per-point {', '.join(environment)} (only their mean is kept: a bare table without the "
                    "column has no material temperature per point for the uncertainty budget)")
    other = [c for c in [*table.optional, *table.extra] if c not in ENVIRONMENT]
    if other:
        lost.append(f"the per-point columns {', '.join(other)}")
    carried = CARRIED_META.get(fmt)
    if carried is not None:
        keys = [k for k in table.meta if k not in carried and not k.startswith(f"{fmt}.") and k != "source"]
        if keys:
            lost.append(f"the metadata {', '.join(keys)}")
    return lost


def render_any(table: PointTable, fmt: str) -> str:
    """The text of `table` in format `fmt`."""
    if fmt == "points":
        return write_points_text(table)
    return WRITERS[fmt](from_points(table))


def write_whole(path: str | Path, text: str) -> None:
    """Write `text` to `path` completely or not at all: a temporary file beside it, fsynced, then
    renamed over `path`. InputError when the place cannot be written."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(f"{path}: cannot write ({exc.strerror or exc})") from None


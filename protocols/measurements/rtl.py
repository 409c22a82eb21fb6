"""Renishaw .rtl, the ISO "linear" layout that CARTO and LaserXL export (no vendor description is
public; this follows the layout four independent third-party readers and writers agree on).

Sections are lines ending in `::`. `TARGET DATA::` holds `Target-count: N`, then `Targets :` and
the N targets (mm or degrees; several per line, over several lines) ended by `Flags:` (`0 0 2 0`
bidirectional, `0 1 2 0` unidirectional). `USER-TEXT::` holds `Machine:`, `Serial No:`, `Date:`,
`By:`, `Axis:`, `Location:`, `TITLE:`. `RUNS::` holds `Run-count:`: in a bidirectional file twice
the number of ISO runs, each direction its own run, odd runs forward (increasing position), even
runs reverse. `DEVIATIONS::` then `Run Target Data:` then `run target_number deviation` lines,
target numbers 1..N, deviation in µm (arcsec for a rotary axis), reverse runs listing N..1.
`ENVIRONMENT::`, `EQUIPMENT::` and any unknown section are optional; `EOF::` ends the file.

Read tolerantly: CRLF, blank lines, a BOM, any spacing around `:`, targets over several lines.
Unknown sections and keys are kept in the metadata as `rtl.SECTION` and `rtl.key` (spaces as `_`),
and an unknown section is written back.
"""

from __future__ import annotations

import itertools
import math
import re

from protocols.errors import FormatError
from protocols.measurements import Measurement, Row

SECTION = re.compile(r"^\s*([A-Za-z][A-Za-z0-9 _-]*?)\s*::\s*$")
USER_TEXT = {"Machine": "machine", "Serial No": "serial", "Date": "date", "By": "operator", "Axis": "axis",
             "Location": "location", "TITLE": "title"}
"""USER-TEXT key -> point table metadata key."""
ENVIRONMENT = {"Air temp": "air_temp_c", "Air Press": "air_pressure_hpa", "Air Humid": "humidity_pct",
               "Mat temp 1": "material_temp_c"}
"""ENVIRONMENT key -> metadata key (°C, hPa (mbar), % RH: the metric settings are assumed)."""
NO_DATE = "not recorded"
"""The `Date:` written when the point table gives no measurement date (never an empty value)."""
PER_LINE = 5
"""Targets written per line."""
SIMULATED_TITLE = "SIMULATED, not a measurement of a real axis"
"""The TITLE (before ` | ` and the title, if any) that carries the point table's `simulated` mark,
which the .rtl has no field for; read back into `simulated`."""
SIMULATED_MARK = "yes (not a measurement of a real axis)"
"""The point table's `simulated` value that mark stands for."""


KNOWN = ("HEADER", "TARGET DATA", "USER-TEXT", "RUNS", "DEVIATIONS", "ENVIRONMENT", "EOF")
"""The sections read into the measurement; any other is kept whole in the metadata."""


def _meta_key(name: str) -> str:
    """The metadata key of an .rtl key or section with no point-table meaning: `rtl.` and the
    name with spaces as `_` (a point table's `# key: value` comment takes no space in the key)."""
    return "rtl." + "_".join(name.split())


def _key_value(line: str) -> tuple[str, str] | None:
    if ":" not in line:
        return None
    key, value = line.split(":", 1)
    return key.strip(), value.strip()


def _number(text: str, name: str, line: int, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise FormatError(f"{name}: line {line}: {what} '{text}' is not a number") from None
    if not math.isfinite(value):
        raise FormatError(f"{name}: line {line}: {what} '{text}' is not a finite number")
    return value


def _sections(text: str, name: str) -> dict[str, list[tuple[int, str]]]:
    sections: dict[str, list[tuple[int, str]]] = {}
    current = None
    for number, raw in enumerate(text.lstrip("\ufeff").splitlines(), start=1):
        line = raw.strip()
        match = SECTION.match(line)
        if match:
            current = match.group(1).strip().upper()
            if current in sections:
                raise FormatError(f"{name}: line {number}: section {current}:: appears twice")
            sections[current] = []
            if current == "EOF":
                break
        elif line:
            if current is None:
                raise FormatError(f"{name}: line {number}: '{line[:40]}' before the first section (HEADER::)")
            sections[current].append((number, line))
    for needed in ("TARGET DATA", "RUNS", "DEVIATIONS"):
        if needed not in sections:
            raise FormatError(f"{name}: no {needed}:: section (not an .rtl file?)")
    return sections


def _targets(lines: list[tuple[int, str]], name: str, meta: dict[str, str]) -> tuple[list[float], bool]:
    count = None
    targets: list[float] = []
    bidirectional = None
    reading = False
    last = 0
    for number, line in lines:
        last = number
        lowered = line.lower()
        if lowered.startswith("target-count"):
            value = line.split(":", 1)[1].strip() if ":" in line else ""
            if not value.isdigit() or int(value) < 2:
                raise FormatError(f"{name}: line {number}: Target-count must be a whole number ≥ 2, found '{value}'")
            count = int(value)
        elif lowered.startswith("targets"):
            reading = True
            rest = line.split(":", 1)[1] if ":" in line else ""
            targets += [_number(t, name, number, "target") for t in rest.split()]
        elif lowered.startswith("flags"):
            flags = line.split(":", 1)[1].split() if ":" in line else []
            if len(flags) < 2 or flags[1] not in ("0", "1"):
                raise FormatError(f"{name}: line {number}: Flags must read '0 0 2 0' (bidirectional) "
                                  f"or '0 1 2 0' (unidirectional), found '{line}'")
            bidirectional = flags[1] == "0"
            reading = False
        elif reading:
            targets += [_number(t, name, number, "target") for t in line.split()]
        else:
            pair = _key_value(line)
            if pair:
                meta[_meta_key(pair[0])] = pair[1]
    if count is None:
        raise FormatError(f"{name}: TARGET DATA:: has no Target-count (line {last})")
    if bidirectional is None:
        raise FormatError(f"{name}: TARGET DATA:: has no Flags line after the targets (line {last})")
    if len(targets) != count:
        raise FormatError(f"{name}: Target-count is {count} but {len(targets)} targets are listed (line {last})")
    if any(b <= a for a, b in itertools.pairwise(targets)):
        raise FormatError(f"{name}: the targets must increase (TARGET DATA::, line {last})")
    return targets, bidirectional


def parse(text: str, name: str = "<rtl>", kind: str = "linear") -> Measurement:
    """The measurement in an .rtl file's text. FormatError names the line for bad input."""
    sections = _sections(text, name)
    meta: dict[str, str] = {}
    targets, bidirectional = _targets(sections["TARGET DATA"], name, meta)
    for number, line in sections.get("HEADER", []):
        pair = _key_value(line)
        if pair and pair[1]:
            meta[_meta_key(pair[0])] = pair[1]
    for number, line in sections.get("USER-TEXT", []):
        pair = _key_value(line)
        if pair and pair[1] and pair != ("Date", NO_DATE):
            meta[USER_TEXT.get(pair[0]) or _meta_key(pair[0])] = pair[1]
    if meta.get("title", "").startswith(SIMULATED_TITLE):
        meta["simulated"] = SIMULATED_MARK
        title = meta.pop("title")[len(SIMULATED_TITLE):].removeprefix(" | ")
        if title:
            meta["title"] = title
    for number, line in sections.get("ENVIRONMENT", []):
        pair = _key_value(line)
        if pair and pair[1]:
            key = ENVIRONMENT.get(pair[0])
            numeric = re.fullmatch(r"[-+]?\d+(\.\d*)?", pair[1].split()[0] if pair[1].split() else "")
            if key is not None and numeric:
                meta[key] = pair[1].split()[0]
            else:
                meta[_meta_key(pair[0])] = pair[1]
    for section, lines in sections.items():
        if section not in KNOWN:
            meta[_meta_key(section)] = " | ".join(line for _, line in lines)
    run_count = None
    for number, line in sections["RUNS"]:
        pair = _key_value(line)
        if pair and pair[0].lower() == "run-count":
            if not pair[1].isdigit() or int(pair[1]) < 1:
                raise FormatError(f"{name}: line {number}: Run-count must be a whole number ≥ 1, found '{pair[1]}'")
            run_count = int(pair[1])
    if run_count is None:
        raise FormatError(f"{name}: RUNS:: has no Run-count")
    if bidirectional and run_count % 2:
        raise FormatError(f"{name}: a bidirectional file needs an even Run-count (one run per direction), "
                          f"found {run_count}")
    rows = _deviations(sections["DEVIATIONS"], name, len(targets), run_count, bidirectional)
    return Measurement(kind, tuple(targets), tuple(rows), meta)


def _deviations(lines: list[tuple[int, str]], name: str, n_targets: int, run_count: int,
                bidirectional: bool) -> list[Row]:
    rows: list[Row] = []
    seen: set[tuple[int, int]] = set()
    for number, line in lines:
        if line.lower().startswith("run target data"):
            continue
        cells = line.split()
        if len(cells) != 3 or not cells[0].isdigit() or not cells[1].isdigit():
            raise FormatError(f"{name}: line {number}: expected 'run target_number deviation', found '{line[:60]}'")
        run, target = int(cells[0]), int(cells[1])
        if not 1 <= run <= run_count:
            raise FormatError(f"{name}: line {number}: run {run} outside 1..{run_count} (Run-count)")
        if not 1 <= target <= n_targets:
            raise FormatError(f"{name}: line {number}: target number {target} outside 1..{n_targets}")
        if (run, target) in seen:
            raise FormatError(f"{name}: line {number}: run {run}, target {target} appears twice")
        seen.add((run, target))
        deviation = _number(cells[2], name, number, "deviation")
        if bidirectional:
            rows.append(Row((run + 1) // 2, 1 if run % 2 else -1, target - 1, deviation))
        else:
            rows.append(Row(run, 1, target - 1, deviation))
    expected = run_count * n_targets  # every (run, target) seen lies within these: the rest are missing
    if len(seen) < expected:  # the first missing one lies within the first len(seen) + 1 pairs: no list of them all
        r, t = next((r, t) for r in range(1, run_count + 1) for t in range(1, n_targets + 1) if (r, t) not in seen)
        raise FormatError(f"{name}: DEVIATIONS:: lacks run {r}, target {t} ({expected - len(seen)} values missing)")
    return rows


def _text(value: float) -> str:
    """A number as short as it can be without losing what the point table holds (6 decimals)."""
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def render(m: Measurement) -> str:
    """The .rtl text of `m` (CRLF line ends, as the Windows programs write them). A
    unidirectional measurement must hold + approaches only."""
    bidirectional = m.bidirectional
    if not bidirectional and any(r.direction < 0 for r in m.rows):
        raise FormatError("an .rtl unidirectional file holds forward (+) runs only")
    n = len(m.targets)
    lines = ["HEADER::", "File type  : rtl", "Owner      : axiscal", f"Version no : {m.meta.get('software', '')}", "",
             "TARGET DATA::", "Filetype  : ISO", f"Target-count: {n}", "Targets :"]
    for i in range(0, n, PER_LINE):
        lines.append(" ".join(_text(t) for t in m.targets[i:i + PER_LINE]))
    lines += ["Flags: 0 0 2 0" if bidirectional else "Flags: 0 1 2 0", "", "USER-TEXT::"]
    user = dict(m.meta)
    if user.get("simulated"):  # the mark travels in the title: a simulated campaign stays marked
        user["title"] = SIMULATED_TITLE + (f" | {user['title']}" if user.get("title") else "")
    lines += [f"{key}: {user.get(meta_key) or NO_DATE if key == 'Date' else user.get(meta_key, '')}"
              for key, meta_key in USER_TEXT.items()]
    runs = m.runs
    lines += ["", "RUNS::", f"Run-count: {2 * runs if bidirectional else runs}", "", "DEVIATIONS::", "Run Target Data:"]
    by_point = {(r.run, r.direction, r.target): r.deviation for r in m.rows}
    for run in range(1, runs + 1):
        for direction in ((1, -1) if bidirectional else (1,)):
            file_run = (2 * run - 1 if direction > 0 else 2 * run) if bidirectional else run
            order = range(n) if direction > 0 else range(n - 1, -1, -1)
            for t in order:
                if (run, direction, t) not in by_point:
                    raise FormatError(f"run {run} {'+' if direction > 0 else '-'} lacks target {m.targets[t]:g}: "
                                      ".rtl files hold complete runs only")
                lines.append(f"{file_run} {t + 1} {_text(by_point[(run, direction, t)])}")
    environment = [(key, m.meta[meta_key]) for key, meta_key in ENVIRONMENT.items() if meta_key in m.meta]
    if environment:
        lines += ["", "ENVIRONMENT::"] + [f"{key:<11}: {value}" for key, value in environment]
    for key, value in m.meta.items():
        section = key[4:].replace("_", " ")
        if key.startswith("rtl.") and section.isupper() and section not in KNOWN:
            lines += ["", f"{section}::"] + value.split(" | ")
    lines += ["", "EOF::", ""]
    return "\r\n".join(lines)

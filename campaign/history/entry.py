"""What the store records of a campaign directory or a point table, gathered with the project's
own pieces: the directory reader (campaign.record), the assessment (campaign.assess: ISO 230-2,
outliers, uncertainty budget, verdict), never computed again here.

A campaign directory is known by its `key`: a hash of meta.json and of the first record of
runs.jsonl, both written once when the campaign starts and never rewritten (the start record
carries the process id, so two campaigns started in the same second are still two). Its `state`
hashes what grows (runs.jsonl, points.csv, config.toml): recording the same directory again
changes nothing unless the campaign went on (a resume). A point table outside a campaign directory
is known by the hash of its bytes; one read by `axiscal convert` is recorded as what it is, a
converted table (source "converted": listed with `history list --all`, never trended), and as a
measurement of its own only when asked (`axiscal history import FILE`).

Each campaign keeps its purpose ([campaign] purpose: acceptance, verification, follow-up,
diagnostic; a campaign measured with a compensation table written for it, by `axiscal verify`, is
a verification whatever its config says) and the campaign it follows ([campaign] follows, or a
verification's baseline), and the uncertainty of its A, E, B, R between re-checks
(campaign/history/recheck.py).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from campaign import __version__
from campaign.assess import Assessment, assess, assess_path, campaign_dir_of
from campaign.history.recheck import k_of, recheck_u
from campaign.pointtable import PointTable
from campaign.record import (
    CONFIG_FILE,
    META_FILE,
    POINTS_FILE,
    RUNS_FILE,
    open_campaign,
    recorded_point_indices,
)

PARAMETERS = ("A", "E", "M", "B", "B_mean", "R")
"""The ISO 230-2 parameters recorded (each bidirectional, and A, E, R per direction too)."""
DIRECTIONS = (("both", ""), ("up", "_up"), ("down", "_down"))
UNCERTAIN = ("A", "E", "B", "R")
"""The parameters the uncertainty budget gives a U for (the same U for each direction)."""


@dataclass
class Entry:
    """One campaign (or point table) as the store holds it. `values`: the `campaigns` row;
    `results`: (parameter, direction, value, U) rows; `points`: (run, direction, target,
    deviation, time_s) rows; `baseline`: a verification's baseline (directory or table), if any."""

    values: dict[str, Any]
    results: list[tuple[str, str, float | None, float | None]] = field(default_factory=list)
    points: list[tuple[int, int, float, float, float | None]] = field(default_factory=list)
    baseline: Path | None = None
    compensation: dict[str, Any] | None = None
    recheck: dict[str, float] = field(default_factory=dict)
    """{parameter: standard uncertainty between re-checks} of A, E, B, R (recheck.py)."""

    @property
    def key(self) -> str:
        return str(self.values["key"])


def _hash(*chunks: bytes) -> str:
    h = hashlib.sha256()
    for chunk in chunks:
        h.update(len(chunk).to_bytes(8, "little"))
        h.update(chunk)
    return h.hexdigest()


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        return b""


def directory_key(directory: Path) -> str:
    """The campaign's identity (see the module's docstring)."""
    runs = _read(directory / RUNS_FILE)
    return _hash(_read(directory / META_FILE), runs.split(b"\n", 1)[0])


def directory_state(directory: Path) -> str:
    """What a campaign directory holds now (changes when the campaign goes on)."""
    return _hash(*(_read(directory / name) for name in (RUNS_FILE, POINTS_FILE, CONFIG_FILE)))


def fingerprint(table: PointTable) -> str:
    """The measurement itself, whatever file carries it: its points, rounded (targets to 0.1 µm
    or 0.0001 deg, deviations to 0.01 µm or arcsec), in a fixed order. A campaign and a converted
    copy of its table have the same fingerprint; the trend counts them once."""
    rows = sorted(zip(table.run.tolist(), table.direction.tolist(), (round(t, 4) for t in table.target.tolist()),
                      (round(d, 2) for d in table.deviation.tolist())))
    return _hash(repr(rows).encode())


def utc(text: str | None) -> dt.datetime | None:
    """An ISO 8601 date or time as a naive UTC datetime (the store keeps no zone); None when absent
    or not a date."""
    if not text:
        return None
    try:
        when = dt.datetime.fromisoformat(str(text))
    except ValueError:
        return None
    if when.tzinfo is not None:
        when = when.astimezone(dt.UTC).replace(tzinfo=None)
    return when


def now_utc() -> dt.datetime:
    return dt.datetime.now(dt.UTC).replace(tzinfo=None, microsecond=0)


def _results(a: Assessment) -> list[tuple[str, str, float | None, float | None]]:
    rows = []
    summary, expanded = a.evaluation.summary, a.uncertainty.expanded
    for parameter in PARAMETERS:
        for direction, suffix in DIRECTIONS:
            name = parameter + suffix
            if name not in summary:
                continue
            value = summary[name]
            u = expanded.get(parameter) if parameter in UNCERTAIN and value is not None else None
            rows.append((parameter, direction, value, u))
    return rows


def _points(table: PointTable) -> list[tuple[int, int, float, float, float | None]]:
    times = table.optional.get("time_s")
    return [(int(r), int(d), float(t), float(e), None if times is None else float(times[i]))
            for i, (r, d, t, e) in enumerate(zip(table.run, table.direction, table.target, table.deviation))]


def _instrument(a: Assessment) -> dict[str, Any]:
    if a.config is None:
        return {"recorded": False}
    spec = dataclasses.asdict(a.config.instrument)
    keep = ("type", "model", "serial", "certificate", "wavelength_uncertainty_ppm", "angle_uncertainty_arcsec",
            "resolution", "misalignment_mm", "dead_path_mm")
    return {"recorded": True, **{k: spec.get(k) for k in keep}}


def _plan(a: Assessment, meta: dict[str, Any]) -> dict[str, Any]:
    targets = sorted({round(float(t), 9) for t in a.table.target})
    plan: dict[str, Any] = {"targets": meta.get("targets", targets), "points_planned": meta.get("points_planned"),
                            "plan_seed": meta.get("plan_seed", a.table.meta.get("plan_seed"))}
    if a.config is not None:
        p = a.config.plan
        plan.update(cycles=p.cycles, cycle=p.cycle, dwell_s=p.dwell_s, velocity=p.velocity, overrun=p.overrun,
                    offsets=p.offsets, capture=a.config.capture.method)
    return plan


def _recheck(a: Assessment) -> dict[str, float]:
    t = a.table
    return recheck_u(t.run, t.direction, t.target, t.deviation, k_of(a.evaluation.standard.title))


def _purpose(a: Assessment | None, meta: dict[str, Any]) -> tuple[str, str]:
    """(purpose, follows) of a campaign: its config's [campaign] purpose and follows; a campaign
    measured with a compensation table written for it (`verify`) is a verification of its baseline."""
    purpose: str
    if a is not None and a.config is not None:
        purpose, follows = a.config.campaign.purpose, a.config.campaign.follows
    else:
        section = (meta.get("config") or {}).get("campaign") or {}
        purpose, follows = str(section.get("purpose") or meta.get("purpose") or "acceptance"), str(
            section.get("follows") or meta.get("follows") or "")
    if meta.get("compensation") and purpose == "acceptance":
        purpose = "verification"
    if purpose == "verification" and not follows and meta.get("baseline_dir"):
        follows = str(meta["baseline_dir"])
    return purpose, follows


def _common(a: Assessment, key: str, state: str, source: str, command: str, location: Path,
            when: dt.datetime | None, meta: dict[str, Any]) -> dict[str, Any]:
    table = a.table
    purpose, follows = _purpose(a, meta)
    config = a.config
    machine = meta.get("machine") or table.meta.get("machine") or (config.campaign.machine if config else "")
    axis = meta.get("axis") or table.meta.get("axis") or (config.axis.name if config else "")
    operator = meta.get("operator") or table.meta.get("operator") or ""
    verdict = a.verdict.as_json()
    return {"key": key, "state": state, "source": source, "command": command,
            "machine": str(machine or "unknown"), "axis": str(axis or "unknown"), "axis_kind": table.kind,
            "unit": table.deviation_unit, "position_unit": table.position_unit, "measured_utc": when,
            "operator": str(operator), "points": len(table), "runs": a.evaluation.runs, "simulated": a.simulated,
            "location": str(location), "label": location.name, "standard": a.evaluation.standard.title,
            "verdict": verdict["verdict"], "reasons": verdict["reasons"], "checks": verdict["checks"],
            "tolerances": {k: t for k, t in a.tolerances.items() if t}, "uncertainty": a.uncertainty.as_json(),
            "instrument": _instrument(a), "plan": _plan(a, meta), "fingerprint": fingerprint(table),
            "software": f"axiscal {__version__}", "recorded_utc": now_utc(), "purpose": purpose, "follows": follows}


def directory_entry(directory: str | Path, command: str = "import") -> Entry:
    """The entry of a campaign directory (complete, stopped or still without a point)."""
    path = Path(directory).resolve()
    campaign = open_campaign(path)
    meta = campaign.meta
    key, state = directory_key(path), directory_state(path)
    when = utc(meta.get("created"))
    planned = meta.get("points_planned")
    if not recorded_point_indices(path):  # stopped (or killed) before its first point
        return Entry(_empty(campaign.meta, key, state, command, path, when, campaign.status, planned))
    a = assess_path(path)
    values = _common(a, key, state, "directory", command, path, when, meta)
    values.update(status=campaign.status, points_planned=int(planned) if planned else None,
                  with_compensation=bool(meta.get("compensation")))
    baseline = meta.get("baseline_dir")
    base = None
    if baseline:
        base = Path(str(baseline))
        base = base if base.is_absolute() else (path / base if (path / base).exists() else base)
    return Entry(values, _results(a), _points(a.table), base, meta.get("compensation"), _recheck(a))


def _empty(meta: dict[str, Any], key: str, state: str, command: str, path: Path, when: dt.datetime | None,
           status: str, planned: Any) -> dict[str, Any]:
    kind = str(meta.get("kind", "linear"))
    purpose, follows = _purpose(None, meta)
    units = {"linear": ("um", "mm"), "rotary": ("arcsec", "deg")}.get(kind, ("um", "mm"))
    return {"key": key, "state": state, "source": "directory", "command": command,
            "machine": str(meta.get("machine") or "unknown"), "axis": str(meta.get("axis") or "unknown"),
            "axis_kind": kind, "unit": units[0], "position_unit": units[1], "measured_utc": when,
            "operator": str(meta.get("operator") or ""), "status": status, "points": 0,
            "points_planned": int(planned) if planned else None, "runs": 0, "simulated": bool(
                meta.get("simulated") or meta.get("driver") == "sim"),
            "with_compensation": bool(meta.get("compensation")), "location": str(path), "label": path.name,
            "standard": "", "verdict": "not judged", "reasons": ["no point was recorded"], "checks": [],
            "tolerances": {}, "uncertainty": {}, "instrument": {"recorded": False}, "plan": {},
            "fingerprint": "", "software": f"axiscal {__version__}", "recorded_utc": now_utc(), "purpose": purpose,
            "follows": follows}


def table_entry(table: PointTable, location: str | Path, raw: bytes, command: str) -> Entry:
    """The entry of a point table outside a campaign directory (a converted file, a baseline
    table): judged against the grid it shows, with the budget's defaults named as such
    (campaign.assess), dated by its `# date:` comment when it has one. Read by `convert`, it is a
    converted table (source "converted"); otherwise a measurement of its own (source "table")."""
    path = Path(location).resolve()
    a = assess(table, source=str(path))
    key = _hash(b"table", raw)
    source = "converted" if command == "convert" else "table"
    values = _common(a, key, key, source, command, path, utc(table.meta.get("date")), dict(table.meta))
    values.update(status="table", points_planned=None, with_compensation=False)
    return Entry(values, _results(a), _points(table), recheck=_recheck(a))


def path_entry(path: str | Path, command: str = "import", fmt: str = "points") -> Entry:
    """The entry of a campaign directory, a campaign's points.csv (its directory), or a
    measurement file of format `fmt` (a point table, or another program's file: campaign.convert)."""
    directory = campaign_dir_of(path)
    if directory is not None:
        return directory_entry(directory, command)
    from campaign.convert import read_any
    from campaign.errors import read_input_bytes

    raw = read_input_bytes(path, "a measurement file")
    return table_entry(read_any(path, fmt), path, raw, command)


def assessed_entry(a: Assessment, key: str, location: str | Path, when: dt.datetime, command: str,
                   meta: dict[str, Any] | None = None) -> Entry:
    """The entry of a campaign assessed in memory, with no file behind it (a simulated re-check
    recorded straight into the store, bench/ and the tests' drawn histories): complete, dated
    `when`, known by `key`."""
    values = _common(a, key, key, "table", command, Path(location), when, dict(meta or {}))
    values.update(status="completed", points_planned=len(a.table), with_compensation=False)
    return Entry(values, _results(a), _points(a.table), recheck=_recheck(a))

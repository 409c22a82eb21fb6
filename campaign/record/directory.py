"""The campaign directory, read back: what ran, how it ended, what was recorded.

    config.toml   the config as given (resume compares it with the recorded one in meta.json); a
                  directory whose plan.jsonl is of plan format 2 is read, replayed and resumed without it
    meta.json     written once at the start: format_version, software, host, created (UTC),
                  machine, axis, operator, kind, unit, plan seed, points planned, targets, offsets,
                  capture, driver, the config's sections as recorded, and what the command added
                  (a verification's table and baseline)
    plan.jsonl    the plan that runs: a header (format 2: with the whole validated config), then one
                  record per step, each capture with its CaptureSpec (campaign.plan)
    runs.jsonl    one record per start and per stop of the executor, appended, never rewritten
    raw.csv, points.csv, events.jsonl, events.log: see campaign/record/recorder.py

Format versions: 1 (axiscal 0.1: no plan.jsonl, runs.jsonl or events.jsonl; meta.json rewritten
with a `status`), 2 (this layout). A version-1 directory is read and resumed as it is: its plan is
rebuilt from config.toml and must give the targets meta.json recorded.
"""

from __future__ import annotations

import fcntl
import io
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from campaign.config import Config, config_from_sections, load_config, resume_conflicts
from campaign.errors import InputError
from campaign.plan import Plan, build_plan, plan_from_records, plan_header
from campaign.record.events import check_record
from campaign.specs import CaptureSpec

if TYPE_CHECKING:
    import pandas as pd

    from campaign.pointtable import PointTable
from protocols.plc_contract import CompTable

FORMAT_VERSION = 2
"""The campaign directory layout this software writes."""

CONFIG_FILE, META_FILE, PLAN_FILE, RUNS_FILE = "config.toml", "meta.json", "plan.jsonl", "runs.jsonl"
POINTS_FILE = "points.csv"
POSITIONS_FILE, SWEEPS_FILE, PROFILE_FILE = "positions.csv", "sweeps.csv", "profile.csv"
POSITION_COLUMNS = ("t_s", "step", "controller_time_s", "actual_position")
"""positions.csv: campaign time s, plan step, the controller's own time stamp (s since 1970), its actual position."""
SWEEP_COLUMNS = ("point", "run", "direction", "end", "t_s", "samples", "positions")
"""sweeps.csv: plan index, pass, + or -, end position, campaign time s of the record, readings, controller samples."""
"""A scan's controller stream, its sweeps done (what resume continues after), its dense profile."""
"""The campaign's point table (campaign.pointtable's format), appended point by point."""

COMP_FILE = "plc-compensation.json"
"""The table written to the PLC (axis units) for a campaign measured with compensation; resume
writes it again before anything moves."""


def read_json_lines(path: Path) -> list[dict[str, Any]]:
    """The objects of a JSON-lines file; a torn last line (a crash during a write) is left out, any
    other bad line is an InputError naming it."""
    if not path.exists():
        return []
    lines = path.read_text(encoding="utf-8").splitlines()
    records = []
    for number, line in enumerate(lines, start=1):
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            if number == len(lines):
                break
            raise InputError(f"{path}:{number}: not a JSON object") from None
        if not isinstance(record, dict):
            raise InputError(f"{path}:{number}: not a JSON object")
        records.append(record)
    return records


@dataclass
class CampaignDir:
    """A campaign directory as recorded. `meta`: meta.json; `runs`: the runs.jsonl records."""

    path: Path
    meta: dict[str, Any]
    runs: list[dict[str, Any]]

    @property
    def format_version(self) -> int:
        return int(self.meta.get("format_version", 1))

    @property
    def last_stop(self) -> dict[str, Any] | None:
        """The last stop record, or None when the executor never stopped cleanly here."""
        return self.runs[-1] if self.runs and self.runs[-1].get("record") == "stop" else None

    @property
    def status(self) -> str:
        """completed, interrupted or failed (the last stop); running when the last start has no
        stop yet (a campaign in progress, or a process that was killed: resume treats it as
        interrupted); created when it never started."""
        if self.runs:
            stop = self.last_stop
            return stop["status"] if stop else "running"
        if self.format_version == 1:
            return str(self.meta.get("status", "running"))
        return "created"

    @property
    def recording_now(self) -> bool:
        """Is a process recording here now? (It holds the lock on runs.jsonl, campaign/record/recorder.py.)"""
        try:
            fd = os.open(self.path / RUNS_FILE, os.O_RDONLY)
        except OSError:
            return False
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            return False
        except BlockingIOError:
            return True
        finally:
            os.close(fd)

    @property
    def message(self) -> str:
        stop = self.last_stop
        if stop:
            return str(stop.get("message", ""))
        if self.status == "running":
            return ("still recording" if self.recording_now else
                    "the process ended without a stop record (killed or crashed); axiscal resume continues it")
        return str(self.meta.get("message", ""))

    @property
    def duration_s(self) -> float:
        """Campaign time at the last stop, s (0 when there is none)."""
        stop = self.last_stop
        if stop:
            return float(stop.get("duration_s", 0.0))
        return float(self.meta.get("duration_s", 0.0))

    def _plan_records(self) -> list[dict[str, Any]] | None:
        path = self.path / PLAN_FILE
        if not path.exists():
            if self.format_version >= 2:
                raise InputError(f"{path}: missing (the directory says format version {self.format_version})")
            return None
        return read_json_lines(path)

    def described_config(self) -> Config | None:
        """The config plan.jsonl records (plan format 2), validated again; None for an older plan."""
        records = self._plan_records()
        if records is None:
            return None
        where = str(self.path / PLAN_FILE)
        sections = plan_header(records, where).get("config")
        return None if sections is None else config_from_sections(sections, where)

    def config(self) -> Config:
        """The campaign's config: config.toml as it is now when present (an operator may change the
        keys marked `resume` before a resume), else the one plan.jsonl records (plan format 2: the
        directory describes itself). InputError when there is neither."""
        if (self.path / CONFIG_FILE).is_file():
            return load_config(self.path / CONFIG_FILE)
        described = self.described_config()
        if described is None:
            raise InputError(f"{self.path}: no {CONFIG_FILE}, and its {PLAN_FILE} (an older format) does not "
                             "describe the campaign: restore the config.toml it was recorded with")
        return described

    def recorded_plan(self, capture: CaptureSpec | None = None) -> Plan | None:
        """The plan from plan.jsonl, or None in a version-1 directory. `capture`: how the points of
        an older plan (format 1, whose capture steps do not say) were captured."""
        records = self._plan_records()
        if records is None:
            return None
        return plan_from_records(records, str(self.path / PLAN_FILE), capture)

    def plan_for(self, config: Config) -> Plan:
        """The plan a resume or a replay continues: the recorded one, when `config` (config.toml
        now) still gives the same measurement (only keys marked `resume` in the schema may differ).
        A version-1 directory has no recorded plan: the plan rebuilt from `config` must give the
        recorded targets. InputError naming what differs otherwise."""
        where = self.path / CONFIG_FILE
        refuse = "refused: that would mix two plans in one table; restore it, or start a new campaign"
        if "config" in self.meta:
            conflicts = resume_conflicts(self.meta["config"], config)
            if conflicts:
                more = f" (and {len(conflicts) - 1} more)" if len(conflicts) > 1 else ""
                raise InputError(f"{where}: {conflicts[0]}{more}; {refuse}")
        recorded = self.recorded_plan(config.capture)
        if recorded is not None:
            return recorded
        plan = build_plan(config)
        targets, planned = self.meta.get("targets"), self.meta.get("points_planned")
        if targets is None or planned is None:
            raise InputError(f"{self.path}: recorded without its plan or targets: cannot check that "
                             f"{CONFIG_FILE} still gives it; start a new campaign")
        if len(targets) != len(plan.targets):
            raise InputError(f"{where}: gives {len(plan.targets)} targets now, {len(targets)} when recorded; {refuse}")
        for i, (now, then) in enumerate(zip(plan.targets, targets), start=1):
            if round(now, 9) != round(then, 9):
                raise InputError(f"{where}: target {i} is {now:g} now, {then:g} when recorded; {refuse}")
        if planned != len(plan.points):
            raise InputError(f"{where}: gives {len(plan.points)} points now, {planned} when recorded; {refuse}")
        return plan

    def comp_table(self) -> CompTable | None:
        """The PLC table of a campaign measured with compensation, else None."""
        path = self.path / COMP_FILE
        if not path.exists():
            return None
        try:
            return CompTable(**json.loads(path.read_text(encoding="utf-8")))
        except (ValueError, TypeError) as exc:
            raise InputError(f"{path}: not a compensation table ({exc})") from None


def open_campaign(directory: str | Path) -> CampaignDir:
    """Read a campaign directory's records; InputError when it is not one."""
    path = Path(directory)
    meta_path = path / META_FILE
    if not path.is_dir():
        raise InputError(f"{path}: no such campaign directory")
    if not meta_path.is_file():
        raise InputError(f"{path}: not a campaign directory (no {META_FILE})")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{meta_path}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise InputError(f"{meta_path}: not a JSON object")
    if int(meta.get("format_version", 1)) > FORMAT_VERSION:
        raise InputError(f"{path}: recorded in directory format {meta['format_version']} by "
                         f"{meta.get('software', 'a newer axiscal')}; this axiscal reads up to {FORMAT_VERSION}")
    return CampaignDir(path, meta, read_json_lines(path / RUNS_FILE))


def read_events(directory: str | Path) -> list[dict[str, Any]]:
    """The events.jsonl records of a campaign directory, in order (see campaign/record/events.py);
    none in a version-1 directory. Each is validated as it is read (its kind and that kind's
    payload): InputError naming the line of one that is not an event."""
    path = Path(directory) / "events.jsonl"
    records = read_json_lines(path)
    for number, record in enumerate(records, start=1):
        problem = check_record(record)
        if problem is not None:
            raise InputError(f"{path}:{number}: not an axiscal event: {problem}")
    return records


@dataclass(frozen=True)
class SweepRecord:
    """One row of a scan's sweeps.csv: the sweep (plan index `point`, pass `run`, `direction` +1/-1,
    its `end` position in the axis unit) recorded at campaign time `t_s` (s) after `samples`
    readings and `positions` controller samples were made durable."""

    point: int
    run: int
    direction: int
    end: float
    t_s: float
    samples: int
    positions: int


def read_sweeps(directory: Path, plan: Plan | None = None) -> list[SweepRecord]:
    """The one reader of sweeps.csv (empty list when the file is not there); a torn last line
    (no newline: killed while writing it) is left out. Each row is checked, and against `plan`
    when given: its point is one of the plan's, with the plan's pass and direction. InputError
    naming the file and line otherwise."""
    path = Path(directory) / SWEEPS_FILE
    if not path.exists():
        return []
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.split("\n")[:-1]  # the last element: "" after a newline, or a torn line
    if not lines:
        return []
    if tuple(lines[0].split(",")) != SWEEP_COLUMNS:
        raise InputError(f"{path}: line 1: not a sweeps header (expected {','.join(SWEEP_COLUMNS)})")
    out = []
    for number, line in enumerate(lines[1:], start=2):
        cells = line.split(",")
        try:
            if len(cells) != len(SWEEP_COLUMNS) or cells[2] not in ("+", "-"):
                raise ValueError
            record = SweepRecord(int(cells[0]), int(cells[1]), 1 if cells[2] == "+" else -1, float(cells[3]),
                                 float(cells[4]), int(cells[5]), int(cells[6]))
        except ValueError:
            raise InputError(f"{path}: line {number}: not a sweep record ({','.join(SWEEP_COLUMNS)})") from None
        if plan is not None:
            if not 0 <= record.point < len(plan.points):
                raise InputError(f"{path}: line {number}: point {record.point} is not in the plan "
                                 f"(0 to {len(plan.points) - 1})")
            planned = plan.points[record.point]
            if (record.run, record.direction) != (planned.run, planned.direction):
                sign = "+" if planned.direction > 0 else "-"
                raise InputError(f"{path}: line {number}: point {record.point} is pass {record.run} {cells[2]}, "
                                 f"the plan's pass {planned.run} {sign}")
        out.append(record)
    return out


def scan_results_written(directory: Path) -> bool:
    """A scan's results are in the directory: profile.csv and its table in points.csv (a kill -9
    between the two leaves one of them to write)."""
    points = Path(directory) / POINTS_FILE
    return (Path(directory) / PROFILE_FILE).exists() and points.exists() and points.stat().st_size > 0


def without_torn_line(path: Path) -> bytes:
    """A recorded file's bytes without a torn last line. The recorder ends every line with a newline
    and fsyncs it: a last line without one is a write a crash cut short (its numbers may be cut too),
    the point in progress, which is not recorded. Read only: `axiscal resume` cuts it from the file."""
    from campaign.errors import read_input_bytes

    data = read_input_bytes(path, "a recorded campaign file")
    return data[:data.rfind(b"\n") + 1]


def read_recorded_points(directory: str | Path, partial: bool = True) -> PointTable:
    """A campaign directory's points.csv as recorded so far, without a torn last line
    (without_torn_line); `partial`: see campaign.pointtable.parse_points."""
    from campaign.pointtable import decode_csv, parse_points

    path = Path(directory) / "points.csv"
    return parse_points(decode_csv(str(path), without_torn_line(path)), str(path), partial)


def recorded_point_indices(directory: Path) -> list[int]:
    """The plan indices of the points recorded in points.csv (its `point` column); none while the
    file holds no row yet."""
    if (Path(directory) / SWEEPS_FILE).exists():  # a scan: the sweeps done (points.csv: its table, at the end)
        return [s.point for s in read_sweeps(directory)]
    path = Path(directory) / "points.csv"
    if not path.exists() or not any(ln[:1].isdigit() for ln in without_torn_line(path).splitlines()):
        return []
    return [int(i) for i in read_recorded_points(directory).extra["point"]]


def load_raw(directory: Path) -> pd.DataFrame:
    """raw.csv as a pandas DataFrame (step and point as nullable integers)."""
    import pandas as pd

    path = Path(directory) / "raw.csv"
    if not path.is_file():
        raise InputError(f"{directory}: not a campaign directory (no raw.csv)")
    try:
        return pd.read_csv(io.BytesIO(without_torn_line(path)), dtype={"step": "Int64", "point": "Int64"})
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(f"{path}: cannot read the raw stream ({exc})") from None


def last_raw_state(directory: Path) -> tuple[float, float | None]:
    """(campaign time of the last sample recorded in s, last known axis position or None). The
    state is the later of raw.csv's and a scan's positions.csv's last rows: the two streams are
    buffered apart, so a kill can leave either ahead, and a resumed run's campaign time must start
    after both (its segment of the streams would otherwise take the earlier run's last samples)."""
    raw = load_raw(directory)
    stream = _last_position_sample(directory / POSITIONS_FILE)
    positions = raw.axis_position.dropna()
    raw_state = (float(raw.t_s.iloc[-1]), float(positions.iloc[-1]) if len(positions) else None) if len(raw) else None
    if stream is None:
        return raw_state or (0.0, None)
    if raw_state is None or stream[0] > raw_state[0]:
        return stream
    return raw_state


def _last_position_sample(path: Path) -> tuple[float, float] | None:
    """(campaign time s, actual position) of positions.csv's last whole line (POSITION_COLUMNS: t_s,
    step, controller time, actual); None without one. A last line that cannot be read is an error:
    what a kill leaves is a torn line after the last newline, which is not read."""
    if not path.is_file():
        return None
    with open(path, "rb") as f:
        f.seek(max(0, path.stat().st_size - 4096))
        tail = f.read()
    lines = tail[:tail.rfind(b"\n") + 1].splitlines()
    if not lines or lines[-1].decode("utf-8", "replace").split(",") == list(POSITION_COLUMNS):
        return None  # the header alone: no sample yet
    fields = lines[-1].split(b",")
    try:
        return float(fields[0]), float(fields[3])
    except (ValueError, IndexError):
        raise InputError(f"{path}: last line {lines[-1][:80]!r} is not a position sample") from None
    with open(path, "rb") as f:
        f.seek(max(0, path.stat().st_size - 4096))
        tail = f.read()
    lines = tail[:tail.rfind(b"\n") + 1].splitlines()
    try:
        return float(lines[-1].split(b",", 1)[0]) if lines else None
    except ValueError:  # the header: no sample yet
        return None


def last_reading_offset(directory: Path, plan: Plan) -> float | None:
    """reading − axis position (axis unit) in the last capture window recorded with the beam OK (the
    axis at rest on a target): what the laser's datum was when the campaign stopped; None when
    there is none. Samples taken while moving are left out: their axis position is a tick old."""
    raw = load_raw(directory)
    captures = [v.capture_step for v in plan.visits()]
    still = raw[raw.step.isin(captures) & raw.axis_position.notna() & raw.reading.notna() & (raw.signal_ok == 1)]
    if still.empty:
        return None
    last = still.iloc[-1]
    return float(last.reading - last.axis_position)

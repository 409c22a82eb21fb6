"""A recorded scan's results: its two streams read back from the campaign directory, aligned and
turned into the profile and the point table at the plan's targets (campaign.stream.scan), with the
scan's settings or others (replay).

The streams: raw.csv holds the instrument's readings with the instrument's own stamps
(`instrument_time_s`); positions.csv the controller's actual position with the controller's own
stamps (`controller_time_s`, s since 1970 from the PLC's FILETIME). A resumed scan holds one
segment per run of the executor (runs.jsonl), and one after each fault within a run: after a
restart neither clock need continue where it stopped, so each segment is aligned by itself over
its whole passes, numbered as the plan's. Times in s, positions in the axis unit, deviations in µm (arcsec on a rotary axis).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from campaign.config import Config
from campaign.errors import InputError
from campaign.plan import Plan
from campaign.pointtable import PointTable, write_points_text
from campaign.record import (
    POSITION_COLUMNS,
    POSITIONS_FILE,
    RUNS_FILE,
    SWEEPS_FILE,
    Recorder,
    SweepRecord,
    load_raw,
    read_events,
    read_json_lines,
    read_sweeps,
)
from campaign.stream.align import ControllerStream, InstrumentStream
from campaign.stream.scan import Profile, ScanResult, TableError, analyse_scan, point_table

if TYPE_CHECKING:
    import pandas as pd

def run_start_s(directory: Path, number: int, record: dict[str, Any]) -> float:
    """A runs.jsonl start record's campaign time, s; InputError naming the line when it has none."""
    t_s = record.get("t_s")
    if isinstance(t_s, bool) or not isinstance(t_s, int | float) or not math.isfinite(t_s):
        raise InputError(f"{directory / RUNS_FILE}:{number}: a run's start without a time (t_s)")
    return float(t_s)


@dataclass(frozen=True)
class ScanSettings:
    """How a recorded scan is evaluated: the window about each target (axis unit), the wanted
    timing uncertainty (deviation unit), whether the rest steps are removed, and whether the
    alignment estimates the clocks' rate ratio (False: the offset only)."""

    window: float
    wanted_u: float
    rest_reference: bool = True
    rate: bool = True


def settings_of(config: Config) -> ScanSettings:
    return ScanSettings(config.capture.scan_window, config.capture.scan_wanted_u)


@dataclass(frozen=True)
class Segment:
    """One run of the executor's share of a scan: its whole passes (runs), the sweeps they are
    (plan indices) and the campaign times (s) their streams span, from the rest before the first
    sweep to the last sweep's record."""

    runs: tuple[int, ...]
    sweeps: tuple[int, ...]
    from_s: float
    to_s: float


@dataclass
class RecordedScan:
    """A recorded scan evaluated: the table at the targets and the profile of every whole pass,
    each segment's own result (alignment, moves, rest steps, timing budget) and what was left out."""

    table: PointTable
    profile: Profile
    segments: list[tuple[Segment, ScanResult]]
    left_out: list[str]


def segments(directory: Path, plan: Plan, rest_s: float) -> tuple[list[Segment], list[str]]:
    """The scan's segments (one per run of the executor, runs.jsonl, and one after each fault within
    a run, events.jsonl) with their whole passes; the sweeps of a pass a segment did not finish are
    left out (a retry or a resume measures that pass again)."""

    starts = [run_start_s(directory, number, r) for number, r in enumerate(read_json_lines(directory / RUNS_FILE), 1)
              if r.get("record") == "start"]
    # a fault within a run interrupts the streams too: the sweeps after it are aligned by themselves
    faults = [float(e["t_s"]) for e in read_events(directory) if e["kind"] == "fault"]  # validated as read
    starts = sorted({*starts, *faults})
    if not (directory / SWEEPS_FILE).is_file():
        raise InputError(f"{directory}: not a recorded scan (no {SWEEPS_FILE})")
    sweeps = read_sweeps(directory, plan)
    per_run: dict[int, set[int]] = {}
    for p in plan.points:
        per_run.setdefault(p.run, set()).add(p.index)
    raw = load_raw(directory)
    out: list[Segment] = []
    left: list[str] = []
    bounds = [*starts, float("inf")]
    for lo, hi in itertools.pairwise(bounds):
        # a record at a boundary is before it: a run starts, a fault is raised, after the record at that instant
        mine = [s for s in sweeps if lo < s.t_s <= hi]
        runs = sorted({s.run for s in mine if per_run[s.run] <= {m.point for m in mine if m.run == s.run}})
        partial = sorted({s.run for s in mine} - set(runs))
        if partial:
            left.append(f"pass {', '.join(map(str, partial))}: the sweeps recorded from {lo:g} s on did not finish "
                        "it before the run stopped or a fault (a retry or the resume measured it again)")
        if not runs:
            continue
        out.append(_segment(raw, runs, mine, lo, rest_s))
    return out, left


def _segment(raw: pd.DataFrame, runs: list[int] | tuple[int, ...], mine: list[SweepRecord],
             lo: float, rest_s: float) -> Segment:
    """The segment of the whole passes `runs` among the sweeps `mine` recorded from campaign time `lo`
    on: its streams span from the rest before its first sweep to its last sweep's record."""
    import pandas as pd

    indices = tuple(s.point for s in mine if s.run in runs)
    first, record_s = min(indices), min(s.t_s for s in mine if s.point == min(indices))
    rows = raw[(raw.t_s >= lo) & (raw.t_s <= record_s)]
    other = rows[rows.point.isna() | (rows.point != first)].t_s  # e.g. the recovery after a fault, the re-approach
    if len(other):
        rows = rows[rows.t_s > float(other.max())]
    first_s = float(rows.t_s.min()) if len(rows) and not pd.isna(rows.t_s.min()) else lo
    return Segment(tuple(runs), indices, max(lo, first_s - 0.9 * rest_s), max(s.t_s for s in mine if s.run in runs))


def by_pass(directory: Path, plan: Plan, segment: Segment, rest_s: float) -> list[Segment]:
    """`segment` split into one segment per pass (each aligned by itself when the whole segment
    cannot be: a pass whose streams cannot be aligned must not take the others with it)."""
    sweeps = [s for s in read_sweeps(directory, plan)
              if s.point in segment.sweeps and segment.from_s <= s.t_s <= segment.to_s]
    raw = load_raw(directory)
    return [_segment(raw, (run,), sweeps, segment.from_s, rest_s) for run in segment.runs]


def read_positions(directory: Path) -> pd.DataFrame:
    """positions.csv, the controller's stream, its columns and values checked (a torn last line,
    killed while writing it, left out). InputError naming the file (and line) otherwise."""
    import pandas as pd

    path = directory / POSITIONS_FILE
    if not path.is_file():
        raise InputError(f"{directory}: not a recorded scan (no {POSITIONS_FILE})")
    try:
        frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the controller's stream ({exc})") from None
    if tuple(frame.columns) != POSITION_COLUMNS:
        raise InputError(f"{path}: line 1: not a positions header (expected {','.join(POSITION_COLUMNS)})")
    with open(path, "rb") as f:
        f.seek(max(0, path.stat().st_size - 1))
        torn = f.read(1) not in (b"\n", b"")
    if torn and len(frame):
        frame = frame.iloc[:-1]
    values: pd.DataFrame = frame.apply(pd.to_numeric, errors="coerce")
    bad = values.isna().any(axis=1).to_numpy()
    if bad.any():
        raise InputError(f"{path}: line {int(np.argmax(bad)) + 2}: not a controller sample "
                         f"({','.join(POSITION_COLUMNS)}, numbers)")
    if values.empty:
        raise InputError(f"{path}: holds no sample")
    return values


def scan_streams(directory: Path, segment: Segment | None = None, ctrl: pd.DataFrame | None = None,
                 ) -> tuple[ControllerStream, InstrumentStream]:
    """Both recorded streams of a scan (within `segment`'s campaign times, or all); `ctrl`: positions.csv
    read already (read_positions)."""
    if ctrl is None:
        ctrl = read_positions(directory)
    raw = load_raw(directory)
    good = raw[(raw.signal_ok == 1) & raw.reading.notna() & raw.instrument_time_s.notna()]
    if segment is not None:
        ctrl = ctrl[(ctrl.t_s >= segment.from_s) & (ctrl.t_s <= segment.to_s)]
        good = good[(good.t_s >= segment.from_s) & (good.t_s <= segment.to_s)]
    ctrl = ctrl.drop_duplicates("controller_time_s").sort_values("controller_time_s")
    return (ControllerStream(ctrl.controller_time_s.to_numpy(float), ctrl.actual_position.to_numpy(float)),
            InstrumentStream(good.instrument_time_s.to_numpy(float), good.reading.to_numpy(float)))


def analyse_recorded_scan(directory: str | Path, config: Config, plan: Plan,
                          settings: ScanSettings | None = None) -> RecordedScan:
    """Align, profile and tabulate the scan recorded in `directory` (`settings`: the config's, or
    others), one segment at a time. InputError when no whole pass can be aligned."""
    path = Path(directory)
    s = settings or settings_of(config)
    parts, left_out = segments(path, plan, config.plan.dwell_s)
    results: list[tuple[Segment, ScanResult]] = []
    positions = read_positions(path)
    t0 = float(positions.controller_time_s.iloc[0])  # the controller's stamps are s since 1970: referred to its first
    for segment in parts:
        got, why = _analyse_segment(path, segment, positions, t0, config, plan, s)
        if got is None and len(segment.runs) > 1:  # each pass by itself: one bad pass leaves the others
            for one in by_pass(path, plan, segment, config.plan.dwell_s):
                alone, why_alone = _analyse_segment(path, one, positions, t0, config, plan, s)
                if alone is None:
                    left_out.append(why_alone)
                else:
                    results.append((one, alone))
        elif got is None:
            left_out.append(why)
        else:
            results.append((segment, got))
    if not results:
        raise InputError(f"{path}: no whole pass of the scan could be aligned"
                         + (f" ({'; '.join(left_out)})" if left_out else ""))
    profile = Profile(results[0][1].profile.kind,
                      *(np.concatenate([getattr(r.profile, f) for _, r in results])
                        for f in ("position", "direction", "pass_", "deviation", "time_s")))
    meta = dict(results[0][1].table.meta)
    if len(results) > 1:
        meta["segments"] = "; ".join(
            f"passes {', '.join(map(str, seg.runs))}: clock offset {r.alignment.offset_s * 1e3:.4f} ± "
            f"{r.alignment.offset_uncertainty_s * 1e3:.4f} ms" for seg, r in results)
    for i, why in enumerate(left_out, 1):
        meta[f"left_out_{i}"] = why
    table = point_table(profile, plan.targets, s.window, meta)
    return RecordedScan(table, profile, results, left_out)


def _analyse_segment(path: Path, segment: Segment, positions: pd.DataFrame, t0: float, config: Config, plan: Plan,
                     s: ScanSettings) -> tuple[ScanResult | None, str]:
    """One segment aligned and tabulated, or None and why it could not be."""
    passes = f"pass{'es' if len(segment.runs) > 1 else ''} {', '.join(map(str, segment.runs))}"
    ctrl, inst = scan_streams(path, segment, positions)
    if len(ctrl.time_s) < 10 or len(inst.time_s) < 10:
        return None, f"{passes}: too few samples recorded to align"
    ctrl = ControllerStream(ctrl.time_s - t0, ctrl.position)
    try:
        result = analyse_scan(ctrl, inst, plan.targets, config.instrument.rate_hz, window=s.window,
                              wanted_u=s.wanted_u, kind=config.axis.kind, rest_reference=s.rest_reference,
                              average_s=config.capture.average_s, rate=s.rate)
    except TableError as exc:  # aligned, but no table: said as it is
        return None, f"{passes}: no point table ({exc})"
    except (InputError, ValueError, np.linalg.LinAlgError) as exc:
        return None, f"{passes}: the clocks could not be aligned ({exc})"
    expected = [(p.run, p.direction) for p in plan.points if p.index in segment.sweeps]
    if len(result.moves) != len(expected):
        return None, (f"{passes}: {len(result.moves)} sweeps seen in the controller's stream, "
                      f"{len(expected)} recorded")
    try:
        return _renumbered(result, expected), ""
    except InputError as exc:
        return None, f"{passes}: {exc}"


def _renumbered(result: ScanResult, expected: list[tuple[int, int]]) -> ScanResult:
    """`result` with its passes numbered as the plan's runs (`expected`: (run, direction) of each
    sweep in order): a segment after a resume starts at a later pass."""
    prof = result.profile
    runs = np.zeros(len(prof), dtype=int)
    for move, (run, direction) in zip(result.moves, expected):
        if move.direction != direction:
            raise InputError(f"a sweep of pass {run} moved {'up' if move.direction > 0 else 'down'}, "
                             f"the plan {'up' if direction > 0 else 'down'}")
        runs[(prof.time_s >= move.start_s) & (prof.time_s <= move.end_s)] = run
    return replace(result, profile=replace(prof, pass_=runs))


def finish_scan(recorder: Recorder, config: Config, plan: Plan) -> RecordedScan:
    """Every sweep recorded: the point table and the profile, written into the campaign directory."""
    result = analyse_recorded_scan(recorder.dir, config, plan)
    recorder.scan_results(write_points_text(result.table), result.profile.csv_text())
    return result

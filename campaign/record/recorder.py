"""Writing the campaign directory: crash-safe and append-only.

At the start: config.toml, meta.json and plan.jsonl, each written once (campaign/record/directory.py
says what they hold). While the campaign runs, appended:

    runs.jsonl    a record at each start and each stop of the executor (status, reason, points)
    raw.csv       every sample: time, step, point, axis actual position, reading, beam, environment
    points.csv    the point table (docs/point-table.md) plus capture columns, one row per point
    events.jsonl  the event stream (campaign/record/events.py), one JSON object a line
    events.log    the same events as sentences for people

Every point row is written with one write() and fsynced, after the raw samples before it are
fsynced, so a crash or power cut loses at most the point in progress. Every event and run record
is fsynced. A torn last line (power cut in the middle of a write) is cut off when the directory is
opened again. Nothing is ever rewritten.

One process at a time: the recorder holds an exclusive lock (flock) on runs.jsonl from the moment
it opens the directory until close(), so a second `axiscal resume` (or a new campaign with the same
--out) is refused while the first still records, instead of writing a second copy of its points.
The kernel drops the lock when the process dies, kill -9 included.
"""

from __future__ import annotations

import datetime as dt
import errno
import fcntl
import json
import os
import platform
from pathlib import Path
from typing import Any, TextIO

from campaign import __version__
from campaign.errors import InputError
from campaign.pointtable import AXIS_KINDS, format_row
from campaign.record.directory import (
    CONFIG_FILE,
    FORMAT_VERSION,
    META_FILE,
    PLAN_FILE,
    POSITION_COLUMNS,
    POSITIONS_FILE,
    PROFILE_FILE,
    RUNS_FILE,
    SWEEP_COLUMNS,
    SWEEPS_FILE,
    open_campaign,
    read_json_lines,
    read_sweeps,
)
from campaign.record.events import Event
from protocols.hardware import ENV_FIELDS, Reading

APPENDED = ("raw.csv", "points.csv", "events.jsonl", "events.log", RUNS_FILE, POSITIONS_FILE, SWEEPS_FILE)
"""The files a campaign appends to (a torn last line of each is cut off on reopen)."""

RAW_COLUMNS = ("t_s", "step", "point", "axis_position", "reading", "signal_ok", "signal_pct",
               "instrument_time_s", *ENV_FIELDS)
EXTRA_POINT_COLUMNS = ("point", "reading", "air_correction_um", "material_correction_um",
                       "capture_wait_s", "samples")


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_once(path: Path, text: str) -> None:
    """Write a file of the directory's header (config, meta, plan) completely and durably: a
    temporary file, fsynced, renamed into place, the directory fsynced."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def json_lines(records: list[dict[str, Any]]) -> str:
    return "".join(json.dumps(r, allow_nan=False) + "\n" for r in records)


def cut_torn_tail(path: Path) -> int:
    """Cut an incomplete last line (no newline) off a file; returns the bytes removed."""
    if not path.exists():
        return 0
    data = path.read_bytes()
    keep = data.rfind(b"\n") + 1
    if keep == len(data):
        return 0
    with open(path, "r+b") as f:
        f.truncate(keep)
        f.flush()
        os.fsync(f.fileno())
    return len(data) - keep


def _write_all(fd: int, data: bytes) -> None:
    """Write all of `data` (os.write may write less than asked, e.g. on a nearly full disk)."""
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        if written <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        view = view[written:]


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value)  # shortest round-trip form: replay recomputes bit-identical means
    return str(value)


def lock_directory(path: Path) -> int:
    """Open runs.jsonl for appending and take its exclusive lock; returns the descriptor. InputError
    naming the holder (its pid from its start record) when another process records in `path`."""
    fd = os.open(path / RUNS_FILE, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        starts = [r for r in read_json_lines(path / RUNS_FILE) if r.get("record") == "start"]
        holder = f"pid {starts[-1].get('pid')}, started {starts[-1].get('utc')}" if starts else "starting"
        raise InputError(f"{path}: another axiscal process is recording here ({holder}); "
                         "let it finish, or stop it (Ctrl-C), first") from None
    return fd


class RecordingError(Exception):
    """Writing to the campaign directory failed (disk full, I/O error)."""


class Recorder:
    """Writes one campaign directory; the recording sink of the event stream (its `emit` raises
    RecordingError when the disk refuses, which stops the campaign). Use `Recorder.create` for a
    new campaign and `Recorder.reopen` to append to an interrupted one. `durable` False (only for
    the fake machine's demo, whose points measure nothing): written and flushed to the system as
    always, but not fsynced point by point or event by event, which cost most of its wall time."""

    def __init__(self, directory: Path, meta: dict[str, Any], kind: str, runs_fd: int, durable: bool = True):
        """`runs_fd`: runs.jsonl, open for appending and locked by lock_directory (closed by close())."""
        self.dir = directory
        self.durable = durable
        self.meta = meta
        self.kind = kind
        # long-lived append handles, closed by close()
        self._files: list[TextIO] = []
        self._points_fd = -1
        self._runs_fd = runs_fd
        try:
            self._raw = self._open(directory / "raw.csv", newline="")
            self._points_fd = os.open(directory / "points.csv", os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
            self._events = self._open(directory / "events.jsonl")
            self._log = self._open(directory / "events.log")
        except OSError:
            self.close()
            raise
        self._positions: TextIO | None = None  # opened by the first position sample (a scan)
        self._sweeps_fd = -1
        self._sweeps_done: set[int] = set()
        self.env_columns: tuple[str, ...] | None = None
        self.points_written = 0
        self.fail_next_point_write = False

    def _sync(self, fd: int) -> None:
        """fsync `fd`, unless this recording is not durable (the fake machine's demo)."""
        if self.durable:
            os.fsync(fd)

    def _open(self, path: Path, newline: str | None = None) -> TextIO:
        f = open(path, "a", encoding="utf-8", newline=newline)  # noqa: SIM115 - closed by close()
        self._files.append(f)
        return f

    @classmethod
    def create(cls, directory: str | Path, config_text: str, sections: dict[str, Any], plan_records: list[dict[str, Any]],
               meta: dict[str, Any], kind: str, durable: bool = True) -> Recorder:
        """A new campaign directory: config.toml (`config_text`), meta.json (`meta` with the format
        version, software, host, creation time and the config's `sections`) and plan.jsonl.
        `durable`: see the class (always True for a campaign on a machine)."""
        path = Path(directory)
        try:
            path.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise InputError(f"{path}: is a file, not a campaign directory (give --out a directory)") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot make the campaign directory ({exc.strerror or exc})") from None
        runs_fd = lock_directory(path)
        try:
            if (path / "points.csv").exists() and (path / "points.csv").stat().st_size:
                raise InputError(f"{path}: already holds a campaign (use `axiscal resume {path}` or another --out)")
            os.ftruncate(runs_fd, 0)
            for name in APPENDED:
                if name != RUNS_FILE:
                    (path / name).unlink(missing_ok=True)
        except BaseException:
            os.close(runs_fd)
            raise
        write_once(path / CONFIG_FILE, config_text)
        full = {"format_version": FORMAT_VERSION, "software": f"axiscal {__version__}", "host": platform.node(),
                "created": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"), **meta, "config": sections}
        write_once(path / PLAN_FILE, json_lines(plan_records))
        write_once(path / META_FILE, json.dumps(full, indent=1, allow_nan=False) + "\n")
        rec = cls(path, full, kind, runs_fd, durable)
        rec._raw.write(",".join(RAW_COLUMNS) + "\n")
        rec._raw.flush()
        return rec

    @classmethod
    def reopen(cls, directory: str | Path) -> Recorder:
        """Open an interrupted campaign to append to it (torn tails are cut first)."""
        path = Path(directory)
        meta = open_campaign(path).meta
        runs_fd = lock_directory(path)  # before the tails are cut: they may be another writer's
        try:
            for name in APPENDED:
                cut_torn_tail(path / name)
        except BaseException:
            os.close(runs_fd)
            raise
        rec = cls(path, meta, meta.get("kind", "linear"), runs_fd)
        lines = [ln for ln in (path / "points.csv").read_text(encoding="utf-8").splitlines()
                 if ln and not ln.startswith("#")]
        if lines:
            header = lines[0].split(",")
            rec.env_columns = tuple(c for c in header if c in ENV_FIELDS)
            rec.points_written = len(lines) - 1
        if (path / SWEEPS_FILE).exists():  # a scan: its points are its sweeps until the table is written
            try:
                rec._sweeps_done = {s.point for s in read_sweeps(path)}
            except InputError:
                rec.close()
                raise
            rec.points_written = len(rec._sweeps_done)
        return rec

    def sample(self, t_s: float, step: int, point: int | None, axis_position: float | None,
               reading: Reading) -> None:
        """Append one raw sample (buffered; made durable at the next point)."""
        cells = (t_s, step, point, axis_position, reading.position, reading.signal_ok, reading.signal_pct,
                 reading.time_s, *(getattr(reading, f) for f in ENV_FIELDS))
        try:
            self._raw.write(",".join(_cell(c) for c in cells) + "\n")
        except OSError as exc:  # the buffer flushed onto a full disk
            raise RecordingError(f"{self.dir / 'raw.csv'}: {exc.strerror or exc}") from exc

    def positions(self, t_s: float, step: int, samples: list[tuple[float, float]]) -> None:
        """Append the controller's stream (a scan): each (controller time s, actual position), taken
        in by the PC at campaign time `t_s` during plan step `step` (buffered; durable at the next sweep)."""
        try:
            if self._positions is None:
                path = self.dir / POSITIONS_FILE
                new = not path.exists() or path.stat().st_size == 0
                self._positions = self._open(path, newline="")
                if new:
                    self._positions.write(",".join(POSITION_COLUMNS) + "\n")
            self._positions.write("".join(f"{t_s!r},{step},{tc!r},{x!r}\n" for tc, x in samples))
        except OSError as exc:
            raise RecordingError(f"{self.dir / POSITIONS_FILE}: {exc.strerror or exc}") from exc

    def sweep(self, point: int, run: int, direction: int, end: float, t_s: float, samples: int, positions: int,
              ) -> None:
        """Record a scan's sweep as done, durably: both streams fsynced first, then its row in
        sweeps.csv in one write + fsync (a sweep whose row is missing is scanned again on resume)."""
        try:
            for f in (self._raw, self._positions):
                if f is not None:
                    f.flush()
                    self._sync(f.fileno())
            if self._sweeps_fd < 0:
                path = self.dir / SWEEPS_FILE
                new = not path.exists() or path.stat().st_size == 0
                self._sweeps_fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
                if new:
                    _write_all(self._sweeps_fd, (",".join(SWEEP_COLUMNS) + "\n").encode())
            row = f"{point},{run},{'+' if direction > 0 else '-'},{end!r},{t_s:.6f},{samples},{positions}\n"
            _write_all(self._sweeps_fd, row.encode())
            self._sync(self._sweeps_fd)
        except OSError as exc:
            raise RecordingError(f"{self.dir}: {exc.strerror or exc}") from exc
        self._sweeps_done.add(point)
        self.points_written = len(self._sweeps_done)  # a sweep measured again (a retry, a resume) counts once

    def point(self, run: int, direction: int, target: float, deviation: float, time_s: float,
              env: dict[str, float | None], extra: dict[str, float]) -> None:
        """Append one point row durably: raw stream fsynced first, then the row in one write + fsync.
        Raises RecordingError when the disk refuses; a row cut short is removed on reopen."""
        try:
            self._point(run, direction, target, deviation, time_s, env, extra)
        except OSError as exc:
            raise RecordingError(f"{self.dir}: {exc.strerror or exc}") from exc

    def _point(self, run: int, direction: int, target: float, deviation: float, time_s: float,
               env: dict[str, float | None], extra: dict[str, float]) -> None:
        self._raw.flush()
        self._sync(self._raw.fileno())
        if self.env_columns is None:
            self.env_columns = tuple(f for f in ENV_FIELDS if env.get(f) is not None)
            header = ["run", "direction", *AXIS_KINDS[self.kind], "time_s", *self.env_columns,
                      *EXTRA_POINT_COLUMNS]
            comments = "".join(f"# {k}: {self.meta[k]}\n" for k in ("machine", "axis", "operator", "plan_seed")
                               if k in self.meta)
            if self.meta.get("simulated"):  # the mark travels with the table when it is copied out
                comments += "# simulated: yes (not a measurement of a real axis)\n"
            _write_all(self._points_fd, (comments + ",".join(header) + "\n").encode())
        env_values = [env.get(c) for c in self.env_columns]
        values = (time_s, *(float("nan") if v is None else v for v in env_values),
                  *(extra[c] for c in EXTRA_POINT_COLUMNS))
        row = format_row(run, direction, target, deviation, tuple(float(v) for v in values)).encode()
        if self.fail_next_point_write:
            self.fail_next_point_write = False
            os.write(self._points_fd, row[: len(row) // 2])
            raise OSError(errno.ENOSPC, "No space left on device")
        _write_all(self._points_fd, row)
        self._sync(self._points_fd)
        self.points_written += 1

    def scan_results(self, table_text: str, profile_text: str) -> None:
        """A scan's results, once its sweeps are recorded: profile.csv written whole (`write_once`),
        then the point table at the targets into the (empty) points.csv in one write + fsync. Only
        what is missing is written (a kill -9 between the two leaves the other for resume). The
        table's comments get the campaign's machine, axis, operator, plan seed and simulated mark."""
        comments = "".join(f"# {k}: {self.meta[k]}\n" for k in ("machine", "axis", "operator", "plan_seed")
                           if k in self.meta)
        if self.meta.get("simulated"):
            comments += "# simulated: yes (not a measurement of a real axis)\n"
        try:
            if not (self.dir / PROFILE_FILE).exists():
                write_once(self.dir / PROFILE_FILE, comments + profile_text)
            if not os.fstat(self._points_fd).st_size:
                _write_all(self._points_fd, (comments + table_text).encode())
                self._sync(self._points_fd)
        except OSError as exc:
            raise RecordingError(f"{self.dir}: {exc.strerror or exc}") from exc

    def inject_disk_full(self) -> None:
        """Fault injection: the next point row is cut short by ENOSPC, as on a full disk."""
        self.fail_next_point_write = True

    def emit(self, event: Event) -> None:
        """Append one event to events.jsonl and events.log, both fsynced. RecordingError when the
        disk refuses. A `state` event (a run-state transition, several per point) is written and
        flushed to the system at once but fsynced with the next other event or at close: a crash
        of the process loses none, a power cut at most the transitions since the last fsync."""
        stamp = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
        durable = event.kind != "state"
        for f, text in ((self._events, json.dumps(event.record(stamp), allow_nan=False, ensure_ascii=False)), (self._log, event.line(stamp))):
            try:
                f.write(text + "\n")
                f.flush()
                if durable:
                    self._sync(f.fileno())
            except OSError as exc:
                raise RecordingError(f"{f.name}: {exc.strerror or exc}") from exc

    def start(self, t_s: float, first_point: int, planned: int) -> None:
        """Append the start record of one run of the executor (runs.jsonl)."""
        self._run_record({"record": "start", "t_s": round(t_s, 3), "first_point": first_point,
                          "planned": planned, "software": f"axiscal {__version__}", "host": platform.node(),
                          "pid": os.getpid()})

    def stop(self, t_s: float, status: str, message: str) -> None:
        """Append the stop record: `status` completed, interrupted or failed, with the reason."""
        self._run_record({"record": "stop", "t_s": round(t_s, 3), "status": status, "message": message,
                          "points": self.points_written, "duration_s": round(t_s, 3)})

    def _run_record(self, record: dict[str, Any]) -> None:
        record = {"utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"), **record}
        try:
            _write_all(self._runs_fd, (json.dumps(record, allow_nan=False) + "\n").encode())
            self._sync(self._runs_fd)
        except OSError as exc:
            raise RecordingError(f"{self.dir / RUNS_FILE}: {exc.strerror or exc}") from exc

    def close(self) -> None:
        """Flush, fsync and close every file; each is closed even when another fails (full
        disk). Raises the first OSError afterwards."""
        failure = None
        for f in self._files:
            if f.closed:
                continue
            try:
                f.flush()
                self._sync(f.fileno())
            except OSError as exc:
                failure = failure or exc
            finally:
                try:
                    f.close()
                except OSError as exc:  # close flushes again: the same full disk
                    failure = failure or exc
        for name in ("_points_fd", "_runs_fd", "_sweeps_fd"):
            if getattr(self, name) >= 0:
                os.close(getattr(self, name))
                setattr(self, name, -1)
        if failure is not None:
            raise failure

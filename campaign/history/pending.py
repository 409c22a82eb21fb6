"""The queue of what could not be recorded because the store was unreachable.

A campaign never waits for its store: when the store cannot be reached at the end of a campaign
(or when a table is written), what was to be recorded is appended to
$XDG_DATA_HOME/axiscal/pending.jsonl (one JSON object a line: which store, by a hash of its URL,
never the URL; the campaign directory or the table's record; when) and the user is told in one
line. The next time any axiscal command reaches that store (a campaign's end, `axiscal history
...`), the queue is recorded first and emptied. The campaign directory stays the source of truth:
`axiscal history import DIR` records a campaign whatever the queue says.

Every read and change of the queue holds an exclusive lock (flock on pending.lock beside it), so
that two processes never lose each other's lines; recording what waits is done without it (a
campaign ending meanwhile queues at once), and only the lines recorded are then taken out.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from campaign.history.location import data_dir


def queue_path() -> Path:
    return data_dir() / "pending.jsonl"


def store_id(url: str) -> str:
    """Which store a line waits for: a hash of its URL (the URL itself may hold a password)."""
    return hashlib.sha256(url.encode()).hexdigest()[:32]


@contextmanager
def _locked() -> Iterator[Path]:
    path = queue_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path.with_suffix(".lock"), os.O_RDWR | os.O_CREAT, 0o600)  # never replaced, unlike the queue
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield path
    finally:
        os.close(fd)


def enqueue(url: str, item: dict[str, Any]) -> Path:
    """Append `item` (JSON-able) to the queue of the store at `url`; OSError when the queue
    cannot be written either."""
    line = json.dumps({"store": store_id(url), **item}, default=str) + "\n"
    with _locked() as path, open(path, "a", encoding="utf-8") as f:
        f.write(line)
        f.flush()
        os.fsync(f.fileno())
    return path


def waiting(url: str) -> int:
    """How many lines wait for the store at `url`."""
    path = queue_path()
    if not path.is_file():
        return 0
    sid = store_id(url)
    return sum(1 for item in _lines(path) if item.get("store") == sid)


def _lines(path: Path) -> list[dict[str, Any]]:
    items = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            item = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line torn by a crash: what it named is still in its campaign directory
        if isinstance(item, dict):
            items.append(item)
    return items


def drain(url: str, record: Callable[[dict[str, Any]], object],
          fatal: tuple[type[Exception], ...] = ()) -> tuple[int, list[str]]:
    """Record every line waiting for the store at `url` with `record(item)`; the lines recorded
    (or whose source is gone, said in the problems: one sentence each, for the user) leave the
    queue, a line whose recording fails stays. An exception of a `fatal` type (the store became
    unreachable) stops the draining and is raised, what was recorded having left the queue. The
    lock is held only to read the queue and to take the lines out, never while recording: another
    process's campaign can queue meanwhile (its line stays). Returns (lines recorded, problems)."""
    path = queue_path()
    if not path.is_file() or path.stat().st_size == 0:
        return 0, []
    sid = store_id(url)
    with _locked():
        mine = [item for item in _lines(path) if item.get("store") == sid]
    done, problems = 0, []
    finished: Counter[str] = Counter()
    try:
        for item in mine:
            try:
                record(item)
                done += 1
            except fatal:
                raise
            except LookupError as exc:  # its source is gone: nothing to keep waiting for
                problems.append(f"dropped from the queue: {exc}")
            except Exception as exc:  # noqa: BLE001 - one bad line never blocks the others
                problems.append(f"{item.get('path', '?')}: not recorded, it stays in the queue ({exc})")
                continue
            finished[_line(item)] += 1
    finally:
        if finished:
            _take_out(path, finished)
    return done, problems


def _take_out(path: Path, finished: Counter[str]) -> None:
    """Remove the lines `finished` from the queue as it is now (lines queued meanwhile stay)."""
    with _locked():
        keep = []
        for item in _lines(path):
            if finished[_line(item)] > 0:
                finished[_line(item)] -= 1
            else:
                keep.append(item)
        tmp = path.with_suffix(".tmp")
        tmp.write_text("".join(_line(i) for i in keep), encoding="utf-8")
        os.replace(tmp, path)


def _line(item: dict[str, Any]) -> str:
    return json.dumps(item, default=str) + "\n"

"""The campaign's event stream: every fact the executor reports, emitted once to a list of sinks.

An `Event` is one fact: when (campaign time, s), what kind, a sentence for people, the point it
concerns (plan index, or None) and the details as data. The executor hands each event to its
sinks in order: first the recording sink (the campaign directory's `events.jsonl`, which may stop
the campaign when the disk refuses), then the display sinks (progress bars, the guide's
dashboard), whose failures never stop a campaign.

Each kind has one payload, a TypedDict below (`PAYLOADS`): the executor builds it typed (mypy
checks the fields), and it is validated where an event is made (`Event`) and where one is read
back (`check_record`, used by `campaign.record.read_events`).

The run state (`RunState`) is published the same way: every transition of the executor's state
machine is a `state` event, and every run ends in `stopped` with the reason.

Programs read `events.jsonl` (one JSON object a line: `utc`, `t_s`, `kind`, `message`, `point`,
`data`); `events.log` is the same stream as sentences for people.
"""

from __future__ import annotations

import functools
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Literal, Protocol, TypedDict, Union, get_args, get_origin, get_type_hints


class RunState(StrEnum):
    """The executor's run state, published as `state` events: idle, moving, settling, capturing,
    paused (between points), faulted (halted, waiting for the fault's decision), stopped (the end
    of every run, with its reason)."""

    IDLE = "idle"
    MOVING = "moving"
    SETTLING = "settling"
    CAPTURING = "capturing"
    PAUSED = "paused"
    FAULTED = "faulted"
    STOPPED = "stopped"


TRANSITIONS: Mapping[RunState, frozenset[RunState]] = types.MappingProxyType({
    RunState.IDLE: frozenset({RunState.MOVING, RunState.STOPPED}),
    RunState.MOVING: frozenset({RunState.SETTLING, RunState.CAPTURING, RunState.FAULTED, RunState.STOPPED,
                                RunState.IDLE}),
    RunState.SETTLING: frozenset({RunState.CAPTURING, RunState.MOVING, RunState.FAULTED, RunState.STOPPED}),
    RunState.CAPTURING: frozenset({RunState.MOVING, RunState.PAUSED, RunState.FAULTED, RunState.STOPPED,
                                   RunState.IDLE}),
    RunState.PAUSED: frozenset({RunState.MOVING, RunState.IDLE, RunState.STOPPED}),
    RunState.FAULTED: frozenset({RunState.MOVING, RunState.IDLE, RunState.STOPPED}),
    RunState.STOPPED: frozenset(),
})
"""Where each run state may go: the one state machine of a run (a point is captured after a move,
with a settle between when the plan has one; a pause and a fault hold between points; any state
may stop, and stopped is the end; a scan rests at the end of the travel before its first sweep: a
settle, then a move). A move that follows a move (an overrun, then the target) stays
`moving`: no transition."""


Kind = Literal["start", "point", "fault", "halt", "interrupt", "retry", "skip", "beam", "capture_retry",
               "environment", "serial", "pause", "unpause", "reconnect", "resume", "state", "stop", "display", "sweep"]


class StartData(TypedDict):
    first_point: int
    points: int
    planned: int


class PointData(TypedDict):
    run: int
    direction: int
    target: float
    deviation: float


class FaultData(TypedDict):
    error: str
    error_id: int


class HaltData(TypedDict):
    ok: bool
    why: str


class InterruptData(TypedDict):
    by: str


class NoData(TypedDict):
    pass


class BeamData(TypedDict):
    ok: bool
    signal_pct: float | None


class EnvironmentData(TypedDict):
    field: str
    problem: Literal["out_of_range", "stuck"]


class SerialData(TypedDict):
    lines: int


class ResumeData(TypedDict):
    first_point: int
    points: int
    skipped: list[int]


class StateData(TypedDict):
    state: RunState
    previous: RunState
    reason: str


class StopData(TypedDict):
    status: Literal["completed", "interrupted", "failed"]
    points: int


class DisplayData(TypedDict):
    error: str


class SweepData(TypedDict):
    run: int
    direction: int
    end: float
    samples: int
    positions: int


EventData = Union[StartData, PointData, FaultData, HaltData, InterruptData, NoData, BeamData,  # noqa: UP007
                  EnvironmentData, SerialData, ResumeData, StateData, StopData, DisplayData, SweepData]
"""The payload of some event kind (see PAYLOADS)."""

PAYLOADS: Mapping[str, tuple[type, str]] = types.MappingProxyType({
    "start": (StartData, "the executor starts (or continues); data: first_point, points (to measure), planned"),
    "point": (PointData, "a point is recorded; data: run, direction, target, deviation"),
    "fault": (FaultData, "a fault stopped the current point; data: error (the exception type), error_id"),
    "halt": (HaltData, "the axis was asked to halt; data: ok (false when the halt could not be sent), why"),
    "interrupt": (InterruptData, "the operator interrupted (Ctrl-C or the abort key); data: by"),
    "retry": (NoData, "the point is measured again after a fault"),
    "skip": (NoData, "the point is skipped after a fault (resume measures it later)"),
    "beam": (BeamData, "the beam changed; data: ok, signal_pct"),
    "capture_retry": (NoData, "a capture is retried after beam loss"),
    "environment": (EnvironmentData, ("an environment value was implausible or stuck; data: field, problem "
                                     "(out_of_range, stuck)")),
    "serial": (SerialData, "garbage or partial serial lines were skipped; data: lines"),
    "pause": (NoData, "the operator paused between points"),
    "unpause": (NoData, "the operator resumed after a pause"),
    "reconnect": (NoData, "the controller connection came back"),
    "resume": (ResumeData, ("the campaign continues in this directory; data: first_point, points (to measure), "
                           "skipped (plan indices skipped earlier, measured now)")),
    "state": (StateData, ("the run state changed; data: state, previous (idle, moving, settling, capturing, paused, "
                         "faulted, stopped), reason (why it stopped, or what it does now)")),
    "stop": (StopData, "the executor stopped; data: status (completed, interrupted, failed), points"),
    "display": (DisplayData, "a display sink failed; the campaign goes on (data: error)"),
    "sweep": (SweepData, ("a scan's sweep is recorded (both streams durable); data: run (the pass), direction, end "
                         "(where it ended, axis unit), samples (instrument readings), positions (controller samples)")),
})
"""Every event kind: its payload's TypedDict and what its `data` holds."""

assert set(PAYLOADS) == set(get_args(Kind)), "every Kind has one payload"

KINDS: Mapping[str, str] = types.MappingProxyType({kind: doc for kind, (_, doc) in PAYLOADS.items()})
"""Every event kind, with what its `data` holds."""


def _fits(value: object, hint: Any) -> bool:
    """Whether the JSON value `value` has the type `hint` (int, float, str, bool, a StrEnum, a
    Literal, list[...], X | None)."""
    origin = get_origin(hint)
    if origin is Literal:
        return value in get_args(hint)
    if origin in (Union, types.UnionType):
        return any(_fits(value, arg) for arg in get_args(hint))
    if origin is list:
        (item,) = get_args(hint)
        return isinstance(value, list | tuple) and all(_fits(v, item) for v in value)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if isinstance(hint, type) and issubclass(hint, StrEnum):
        return isinstance(value, str) and value in {m.value for m in hint}
    return isinstance(hint, type) and isinstance(value, hint)


@functools.cache
def _fields(payload: type) -> Mapping[str, Any]:
    """A payload TypedDict's fields and their types (resolved once: events are made per tick)."""
    return types.MappingProxyType(get_type_hints(payload))


def payload_problem(kind: str, data: Mapping[str, Any]) -> str | None:
    """What is wrong with `data` as the payload of an event of `kind` (None when it fits): an
    unknown kind, a missing or unknown field, a value of the wrong type."""
    if kind not in PAYLOADS:
        return f"unknown event kind '{kind}'"
    if not isinstance(data, Mapping):
        return f"{kind} event: data is not an object"
    hints = _fields(PAYLOADS[kind][0])
    missing = sorted(set(hints) - set(data))
    unknown = sorted(set(data) - set(hints))
    if missing or unknown:
        what = ", ".join([f"missing {n}" for n in missing] + [f"unknown {n}" for n in unknown])
        return f"{kind} event: data {what}"
    for name, hint in hints.items():
        if not _fits(data[name], hint):
            return f"{kind} event: data.{name} = {data[name]!r} is not {getattr(hint, '__name__', hint)}"
    return None


@dataclass(frozen=True)
class Event:
    """One fact. t_s: campaign time, s. kind: one of KINDS. message: one sentence with units.
    point: the plan index of the point it concerns, or None. data: the kind's payload (PAYLOADS),
    checked here: a wrong payload is a bug (ValueError)."""

    t_s: float
    kind: Kind
    message: str
    point: int | None = None
    data: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        problem = payload_problem(self.kind, self.data)
        if problem is not None:
            raise ValueError(problem)

    def record(self, utc: str) -> dict[str, Any]:
        """The events.jsonl object, stamped with the wall-clock time `utc` (ISO 8601)."""
        return {"utc": utc, "t_s": round(self.t_s, 3), "kind": self.kind, "message": self.message,
                "point": self.point, "data": {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.data.items()}}

    def line(self, utc: str) -> str:
        """The events.log line (no newline)."""
        return f"{utc} t={self.t_s:.3f}s {self.kind}: {self.message}"


def check_record(record: object) -> str | None:
    """What is wrong with one events.jsonl object (None when it is a valid event record)."""
    if not isinstance(record, dict):
        return "not a JSON object"
    for name, ok in (("t_s", _fits(record.get("t_s"), float)), ("kind", isinstance(record.get("kind"), str)),
                     ("message", isinstance(record.get("message"), str)),
                     ("point", record.get("point") is None or _fits(record.get("point"), int))):
        if not ok:
            return f"{name} missing or of the wrong type"
    return payload_problem(record["kind"], record.get("data", {}))


class EventSink(Protocol):
    """Anything that takes events: the recorder, a progress display, the guide's dashboard."""

    def emit(self, event: Event) -> None:
        ...

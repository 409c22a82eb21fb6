"""The campaign's event stream: every fact the executor reports, emitted once to a list of sinks.

An `Event` is one fact: when (campaign time, s), what kind, a sentence for people, the point it
concerns (plan index, or None) and the details as data. The executor hands each event to its
sinks in order: first the recording sink (the campaign directory's `events.jsonl`, which may stop
the campaign when the disk refuses), then the display sinks (progress bars, the guide's
dashboard), whose failures never stop a campaign.

Programs read `events.jsonl` (one JSON object a line: `utc`, `t_s`, `kind`, `message`, `point`,
`data`); `events.log` is the same stream as sentences for people.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

KINDS = {
    "start": "the executor starts (or continues); data: first_point, points (to measure), planned",
    "point": "a point is recorded; data: run, direction, target, deviation",
    "fault": "a fault stopped the current point; data: error (the exception type), error_id",
    "halt": "the axis was asked to halt; data: ok (false when the halt could not be sent), why",
    "interrupt": "the operator interrupted (Ctrl-C or the abort key); data: by",
    "retry": "the point is measured again after a fault",
    "skip": "the point is skipped after a fault (resume measures it later)",
    "beam": "the beam changed; data: ok, signal_pct",
    "capture_retry": "a capture is retried after beam loss",
    "environment": "an environment value was implausible or stuck; data: field, problem (out_of_range, stuck)",
    "serial": "garbage or partial serial lines were skipped; data: lines",
    "pause": "the operator paused between points",
    "unpause": "the operator resumed after a pause",
    "reconnect": "the controller connection came back",
    "resume": "the campaign continues in this directory; data: first_point, points (to measure), skipped (plan "
              "indices skipped earlier, measured now)",
    "stop": "the executor stopped; data: status (completed, interrupted, failed), points",
    "display": "a display sink failed; the campaign goes on (data: error)",
}
"""Every event kind, with what its `data` holds."""


@dataclass(frozen=True)
class Event:
    """One fact. t_s: campaign time, s. kind: one of KINDS. message: one sentence with units.
    point: the plan index of the point it concerns, or None. data: the details (JSON values)."""

    t_s: float
    kind: str
    message: str
    point: int | None = None
    data: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown event kind '{self.kind}'")

    def record(self, utc: str) -> dict[str, Any]:
        """The events.jsonl object, stamped with the wall-clock time `utc` (ISO 8601)."""
        return {"utc": utc, "t_s": round(self.t_s, 3), "kind": self.kind, "message": self.message,
                "point": self.point, "data": self.data}

    def line(self, utc: str) -> str:
        """The events.log line (no newline)."""
        return f"{utc} t={self.t_s:.3f}s {self.kind}: {self.message}"


class EventSink(Protocol):
    """Anything that takes events: the recorder, a progress display, the guide's dashboard."""

    def emit(self, event: Event) -> None:
        ...

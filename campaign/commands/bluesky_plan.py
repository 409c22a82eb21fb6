"""The campaign's plan as a bluesky plan, and its documents as an axiscal campaign directory
(optional: `pip install bluesky`; docs/epics.md).

In a beamline's session, with ophyd devices for the motor and the laser:

    from campaign.commands.bluesky_plan import axiscal_plan, DocumentLog, campaign_from_documents
    log = DocumentLog()
    RE(axiscal_plan(motor, laser, load_config("x.toml")), log)
    campaign_from_documents(log.documents, "runs/x")     # then axiscal analyze/compensate/report

`axiscal_plan` walks the same plan as `axiscal run` (`build_plan`, checked against the config's
limits before the first message): each move (at its velocity, through the motor's `velocity`
when it has one), the settle, then the capture window's readings of the laser, each point's
readings in an event stream of its own, `axiscal_point_<index>`. The run's start document carries
the config's text. `campaign_from_documents` turns those documents into a campaign directory
(config.toml, meta.json, plan.jsonl, raw.csv, points.csv, runs.jsonl) with the same deviation
code as a campaign (`point_deviation`; no environment sensors are read, so the config's fixed
values apply).

Positions in the axis unit; the laser's reading is the measured position in the axis unit.
Times: the RunEngine's (real) seconds.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterable
from pathlib import Path
from typing import Any

from campaign.config import Config, parse_config, recorded_sections
from campaign.errors import InputError
from campaign.measure import Captured, point_deviation
from campaign.plan import build_plan, check_plan, plan_records
from campaign.record import Event, Recorder, RunState, StateData, StopData
from protocols.hardware import InstrumentError, Reading

STREAM = "axiscal_point_"
"""The event stream of point i is STREAM + str(i)."""
MOVE_GAP_S = 0.05
"""A pause after a move that is not followed by a capture (a turning point), s. Without it the next move
was asked for while ophyd was still handling the last one's DMOV: the new move's status was finished at
once, then again when it really ended, and the RunEngine waited forever (the bluesky run of
tests/test_epics.py over the simulated IOC, its client started again and again by a throwaway script
not kept: 3 hangs in 49 runs without the pause, none in 40 with it; the cause on ophyd's side is
inferred from its error and the IOC's clean DMOV log, not proven)."""

CONFIG_KEY = "axiscal_config"
"""The start document's key that holds the campaign config's text."""


def axiscal_plan(motor: Any, laser: Any, config: Config, md: dict | None = None) -> Generator[Any, Any, Any]:
    """The bluesky plan of `config`'s campaign over `motor` (movable; with `velocity`, e.g. ophyd's
    EpicsMotor, each move's velocity is set) and `laser` (readable: the measured position)."""
    from bluesky import plan_stubs as bps
    from bluesky import preprocessors as bpp

    plan = build_plan(config)
    check_plan(plan, config.axis)
    rate = config.instrument.rate_hz
    metadata = {CONFIG_KEY: config.text, "axiscal_source": config.source, "plan_name": "axiscal_plan",
                "motors": [motor.name], **(md or {})}

    def body() -> Generator[Any, Any, None]:
        velocity = None
        for stop in plan.stops():
            if hasattr(motor, "velocity") and stop.move.velocity != velocity:
                velocity = stop.move.velocity
                yield from bps.mv(motor.velocity, velocity)
            yield from bps.mv(motor, stop.move.position)
            if stop.point is None or stop.capture is None:
                yield from bps.sleep(MOVE_GAP_S)
                continue
            yield from bps.sleep(stop.settle_s)
            for _ in range(max(1, round(stop.capture.window_s * rate))):
                yield from bps.trigger_and_read([laser, motor], name=f"{STREAM}{stop.point.index}")
                yield from bps.sleep(1.0 / rate)

    return (yield from bpp.run_wrapper(body(), md=metadata))


class DocumentLog:
    """A RunEngine subscriber that keeps every (name, document) it is given."""

    def __init__(self) -> None:
        self.documents: list[tuple[str, dict]] = []

    def __call__(self, name: str, doc: dict) -> None:
        self.documents.append((name, doc))


def campaign_from_documents(documents: Iterable[tuple[str, dict]], out: str | Path, laser: str = "laser") -> Path:
    """Write the run of `axiscal_plan` in `documents` as a campaign directory `out`. `laser`: the
    laser's data key in the events. InputError when the documents are not such a run."""
    docs = _checked(documents)
    starts = [(i, doc) for i, name, doc in docs if name == "start"]
    if len(starts) != 1 or CONFIG_KEY not in starts[0][1]:
        raise InputError("the documents hold no single run of axiscal_plan (no start document with the config)")
    where, start = f"document {starts[0][0]} (start)", starts[0][1]
    if not isinstance(start[CONFIG_KEY], str):
        raise InputError(f"{where}: '{CONFIG_KEY}' is {type(start[CONFIG_KEY]).__name__}, not the config's text")
    config = parse_config(start[CONFIG_KEY], str(start.get("axiscal_source", "bluesky start document")))
    t0 = _number(start, "time", where)
    plan = build_plan(config)
    streams: dict[str, str] = {}
    for i, name, doc in docs:
        if name == "descriptor":
            where = f"document {i} (descriptor)"
            streams[str(_field(doc, "uid", where))] = str(doc.get("name", ""))
    readings: dict[int, list[tuple[float, float]]] = {}
    for i, name, doc in docs:
        if name != "event":
            continue
        where = f"document {i} (event)"
        stream = streams.get(str(_field(doc, "descriptor", where)), "")
        if not stream.startswith(STREAM):
            continue
        data = _field(doc, "data", where)
        if not isinstance(data, dict) or laser not in data:
            raise InputError(f"{where}, event {doc.get('seq_num', '?')} of {stream}: has no '{laser}' reading")
        suffix = stream[len(STREAM):]
        if not suffix.isdigit():
            raise InputError(f"{where}: stream '{stream}' names no point (expected {STREAM}<index>)")
        readings.setdefault(int(suffix), []).append((_number(doc, "time", where), _number(data, laser, where)))
    points = {visit.point.index: visit for visit in plan.visits()}
    unknown = sorted(set(readings) - set(points))
    if unknown:
        raise InputError(f"the documents hold readings of points {unknown} the config's plan does not have")
    sections = recorded_sections(config)
    meta = {"machine": config.campaign.machine, "axis": config.axis.name, "operator": config.campaign.operator,
            "kind": config.axis.kind, "unit": config.axis.unit, "plan_seed": plan.seed,
            "points_planned": len(plan.points), "targets": list(plan.targets), "offsets": list(plan.offsets),
            "capture": config.capture.method, "driver": "bluesky", "simulated": config.simulated,
            "bluesky_run": start.get("uid", "")}
    recorder = Recorder.create(out, config.text, sections, plan_records(plan, sections), meta, config.axis.kind)
    try:
        recorder.start(0.0, 0, len(plan.points))
        last = 0.0
        for index in sorted(readings):
            visit, samples = points[index], readings[index]
            for t, position in samples:
                recorder.sample(t - t0, visit.capture_step, index, None, Reading(t - t0, position, True))
            mean = sum(p for _, p in samples) / len(samples)
            got = Captured(mean, len(samples), 0.0, {})
            try:
                deviation, air, material = point_deviation(config.environment, config.axis.unit, visit.point.target, got)
            except InstrumentError as exc:
                raise InputError(f"{config.source}: {exc}: the bluesky run reads no environment sensors") from None
            last = samples[-1][0] - t0
            recorder.point(visit.point.run, visit.point.direction, visit.point.target, deviation, last, {},
                           {"point": index, "reading": mean, "air_correction_um": air,
                            "material_correction_um": material, "capture_wait_s": 0.0, "samples": len(samples)})
        complete = len(readings) == len(plan.points)
        why = "" if complete else f"{len(readings)} of {len(plan.points)} points in the documents"
        reason = "completed" if complete else f"interrupted: {why}"
        recorder.emit(Event(last, "state", f"idle -> stopped: {reason} (a bluesky run)", None,
                            StateData(state=RunState.STOPPED, previous=RunState.IDLE, reason=reason)))
        recorder.emit(Event(last, "stop", f"bluesky run: {len(readings)} of {len(plan.points)} points", None,
                            StopData(status="completed" if complete else "interrupted", points=len(readings))))
        recorder.stop(last, "completed" if complete else "interrupted", why)
    finally:
        recorder.close()
    return Path(out)


def _checked(documents: Iterable[object]) -> list[tuple[int, str, dict]]:
    """(position from 1, name, document) of each (name, document) pair; InputError naming the first
    that is no such pair."""
    docs = []
    for i, item in enumerate(documents, 1):
        if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str)
                and isinstance(item[1], dict)):
            raise InputError(f"document {i}: not a (name, document) pair of a bluesky run")
        docs.append((i, item[0], item[1]))
    return docs


def _field(doc: dict, key: str, where: str) -> Any:
    if key not in doc:
        raise InputError(f"{where}: no '{key}'")
    return doc[key]


def _number(doc: dict, key: str, where: str) -> float:
    """doc[key] as a finite float; InputError saying which field of which document is not one."""
    value = _field(doc, key, where)
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not math.isfinite(number):
        raise InputError(f"{where}: '{key}' is {value!r}, not a finite number")
    return number

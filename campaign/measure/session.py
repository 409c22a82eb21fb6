"""One campaign from config to recorded directory: plan, limit check, hardware, recording, run.

Used by `run`, `demo`, `resume`, `guide` and `verify`. The limits are checked before any hardware
is opened. The hardware comes from an `Opener` the caller passes in (drivers.factory.open_hardware
for the command line, an in-process fake in the tests): `campaign/` never imports the drivers.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol, runtime_checkable

from campaign.config import Config, config_with, recorded_sections
from campaign.errors import CampaignInterrupted, InputError
from campaign.iso230 import Evaluation, evaluate
from campaign.measure.executor import CampaignStopped, Control, Executor, Observer
from campaign.measure.scan import finish_scan
from campaign.model import ErrorModel
from campaign.plan import Plan, build_plan, check_plan, estimate_duration_s, plan_records
from campaign.pointtable import read_points
from campaign.record import (
    Event,
    Recorder,
    RecordingError,
    ResumeData,
    RunState,
    StateData,
    StopData,
    last_raw_state,
    open_campaign,
    read_sweeps,
    recorded_point_indices,
    scan_results_written,
)
from campaign.specs import DriverSpec
from protocols.hardware import Hardware, Reading
from protocols.plc_contract import CompTable


@runtime_checkable
class MachineParts(Protocol):
    """What an opened machine's parts (the second of `Opened`) may offer the session: files to keep
    in the campaign directory, so that a resume reopens the same machine (the opener reads them
    back from `kept_dir`), and a hook for the recorder's disk-full fault injection. The simulated
    machine has both (drivers.factory.SimParts); a real machine has no parts."""

    def kept_files(self) -> dict[str, str]: ...
    def bind_recorder(self, inject_disk_full: Callable[[], None]) -> None: ...


Opened = tuple[Hardware, MachineParts | None]
"""Open hardware and the machine's parts (None on a real machine)."""


class Opener(Protocol):
    """What opens the machine a campaign runs on (`drivers.factory.open_hardware` on the command
    line, `drivers.fake.FakeMachine` in the fast tests and `demo --fake`)."""

    def __call__(self, spec: DriverSpec, speed: float | None = None, model: ErrorModel | None = None,
                 start_position: float | None = None, start_time: float = 0.0, comp: CompTable | None = None,
                 kept_dir: Path | None = None) -> Opened:
        """Open the axis, the instrument and the clock `spec` names and return them with the
        machine's parts (see MachineParts; None on a real machine). `speed`: N times real time
        (simulated machine); `model`: its error model (default: the spec's, or the one kept in
        `kept_dir`); `start_position` (axis unit) and `start_time` (s): where and when it starts;
        `comp`: a compensation table written into the controller (read back, compared, enabled)
        before it returns; `kept_dir`: the campaign directory holding the files the machine kept
        there (a resume reopens the same machine)."""
        ...



@dataclass
class Outcome:
    """How a campaign ended. duration_s: campaign time (simulated on the simulated machine), s."""

    dir: Path
    status: str
    points: int
    planned: int
    duration_s: float
    message: str = ""


def default_out_dir(config: Config) -> Path:
    stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{config.campaign.machine}-{config.axis.name}-{stamp}"


def campaign_meta(config: Config, plan: Plan) -> dict[str, Any]:
    c, a = config.campaign, config.axis
    return {"machine": c.machine, "axis": a.name, "operator": c.operator, "kind": a.kind,
            "unit": a.unit, "plan_seed": plan.seed, "points_planned": len(plan.points),
            "targets": list(plan.targets), "offsets": list(plan.offsets),
            "capture": config.capture.method, "driver": config.controller.type,
            "simulated": config.simulated}


def execute(config: Config, plan: Plan, recorder: Recorder, todo: int | list[int], *, opener: Opener | None = None,
            speed: float | None = None, model: ErrorModel | None = None, observer: Observer | None = None,
            t_offset: float = 0.0, start: float | None = None,
            on_open: Callable[[Hardware, MachineParts | None, Executor], None] | None = None,
            control: Control | None = None,
            opened: Opened | None = None, announce: Event | None = None) -> Outcome:
    """Measure the points `todo` of `plan` (plan indices; an int n: from n to the end) into
    `recorder`, between a start and a stop record. Re-raises
    KeyboardInterrupt after the axis is halted and the recording flushed. `opened`: a (Hardware,
    parts) pair already open, used instead of `opener` (it is closed at the end either way)."""
    if opened is None:
        if opener is None:
            raise ValueError("execute: give an opener or opened hardware")
        try:
            opened = opener(config.driver, speed=speed, model=model, start_position=start, start_time=t_offset,
                            kept_dir=recorder.dir)
        except Exception as exc:
            stopped_unopened(recorder, t_offset, exc)
            recorder.close()  # it was left open (and the directory locked) before
            raise
    hardware, parts = opened
    executor = Executor(plan, config, hardware, recorder, [observer] if observer else [],
                        t0=hardware.clock.now() - t_offset, control=control)
    if parts is not None:
        parts.bind_recorder(recorder.inject_disk_full)
        for name, text in parts.kept_files().items():
            if not (recorder.dir / name).exists():
                (recorder.dir / name).write_text(text, encoding="utf-8")
    status: Literal["completed", "interrupted", "failed"] = "failed"
    message = "stopped by an unexpected error"
    try:
        if on_open:
            on_open(hardware, parts, executor)
        if announce is not None:  # e.g. the resume event, through the run's one emitter
            executor.publish(announce)
        first = todo if isinstance(todo, int) else min(todo)
        recorder.start(executor.now(), first, len(plan.points))
        executor.run(todo)
        if executor.sweeps and not missing_points(recorder.dir, plan):  # a scan: its table from the streams
            finish_scan(recorder, config, plan)
        status, message = "completed", ""
    except CampaignStopped as exc:
        status, message = "interrupted", str(exc)
    except RecordingError as exc:  # the start record could not be written: nothing moved
        status, message = "interrupted", f"recording failed: {exc}"
    except KeyboardInterrupt as exc:
        status, message = "interrupted", "Ctrl-C"
        if isinstance(exc, CampaignInterrupted):
            raise
        raise CampaignInterrupted(recorder.dir) from None
    except InputError as exc:  # e.g. a SafetyError: a motion refused before it was sent
        status, message = "interrupted", str(exc)
        raise
    finally:
        duration = executor.now()
        for failure in hardware.close():
            message = f"{message}; closing: {failure}"
        executor.stop(status if status == "completed" else f"{status}: {message}")  # no-op when it stopped itself
        try:
            executor.publish(Event(duration, "stop", f"campaign {status}" + (f": {message}" if message else ""),
                                   None, StopData(status=status, points=recorder.points_written)))
            recorder.stop(duration, status, message)
        except RecordingError as exc:  # e.g. the disk is full: no stop record, resume treats it as interrupted
            message = f"{message}; could not record the stop: {exc}"
        try:
            recorder.close()
        except OSError as exc:
            message = f"{message}; could not flush the recording: {exc}"
    return Outcome(recorder.dir, status, recorder.points_written, len(plan.points), duration, message)


def publish_stopped(recorder: Recorder, t_s: float, reason: str, point: int | None = None) -> None:
    """Record the one transition of a run that never ran (idle -> stopped, with `reason`), so the
    directory's last state is `stopped` (campaign/record/events.py). A disk that refuses it is
    let go: the run did not start, and the caller's own error says why."""
    try:
        recorder.emit(Event(t_s, "state", f"{RunState.IDLE} -> {RunState.STOPPED}: {reason}", point,
                            StateData(state=RunState.STOPPED, previous=RunState.IDLE, reason=reason)))
    except RecordingError:
        pass


def stopped_unopened(recorder: Recorder, t_s: float, exc: BaseException) -> None:
    """A run whose machine did not open (the opener raised `exc`) ends stopped with that reason."""
    publish_stopped(recorder, t_s, f"interrupted: the machine did not open: {type(exc).__name__}: {exc}")


def start_campaign(config: Config, out: str | Path | None = None, meta_extra: dict[str, Any] | None = None,
                   on_created: Callable[[Path], None] | None = None, durable: bool = True, **kwargs: Any) -> Outcome:
    """A new campaign from `config` into `out` (a new directory); `meta_extra` goes into meta.json.
    `durable` False only for the fake machine's demo (campaign.record.Recorder: no fsync per point).
    The other keywords go to `execute` (`opener` or `opened` is required)."""
    plan = build_plan(config)
    check_plan(plan, config.axis)
    directory = Path(out) if out else default_out_dir(config)
    meta = {**campaign_meta(config, plan), **(meta_extra or {})}
    try:
        recorder = Recorder.create(directory, config.text, recorded_sections(config),
                                   plan_records(plan, recorded_sections(config)), meta,
                                   config.axis.kind, durable=durable)
    except BaseException:
        if kwargs.get("opened") is not None:
            kwargs["opened"][0].close()
        raise
    if on_created is not None:
        on_created(directory)
    return execute(config, plan, recorder, 0, **kwargs)


def open_with_comp(opener: Opener, config: Config, comp: CompTable, speed: float | None = None,
                   start: float | None = None, start_time: float = 0.0, kept_dir: Path | None = None) -> Opened:
    """Open the hardware with `comp` written into the controller (the opener writes it, reads it
    back, compares and enables it; a simulated machine also draws new noise, drivers.factory)."""
    return opener(config.driver, speed=speed, start_position=start, start_time=start_time, comp=comp,
                  kept_dir=kept_dir)


@dataclass
class Resumption:
    """An interrupted campaign, read and ready to continue: its config, the recorded plan, the
    points left to measure (plan indices; `again`: those skipped after a fault) and where and when
    it stopped (campaign time t_last in s, axis position in axis unit or None). Its recorder is open
    (torn tails cut): `close()` it when not continuing."""

    path: Path
    config: Config
    plan: Plan
    todo: list[int]
    again: list[int]
    t_last: float
    position: float | None
    recorder: Recorder
    comp: CompTable | None = None

    def open(self, opener: Opener, speed: float | None = None) -> Opened:
        """The hardware to continue on: a simulated machine starts where and when the campaign
        stopped, with the files it kept (MachineParts); a campaign measured with compensation gets its table
        written again first."""
        if self.comp is not None:
            return open_with_comp(opener, self.config, self.comp, speed, self.position, self.t_last, self.path)
        return opener(self.config.driver, speed=speed, start_position=self.position, start_time=self.t_last,
                      kept_dir=self.path)

    def close(self) -> None:
        self.recorder.close()


def prepare_resume(directory: str | Path, faults: dict[str, Any] | None = None) -> Resumption:
    """Read an interrupted campaign for `continue_campaign`: the recorded plan (see
    `CampaignDir.plan_for`), checked against the limits before anything is touched, and the points
    an earlier run left out: those skipped after a fault, and those after the last one recorded.
    `faults`: a [sim.faults] table to rehearse in the resumed part (the config's own faults are not
    injected again). InputError for a completed campaign."""
    path = Path(directory)
    campaign = open_campaign(path)
    config = campaign.config()  # config.toml, or without it the config plan.jsonl describes
    plan = campaign.plan_for(config)
    # the config's own faults are not injected again on resume; rehearsed ones are
    config = config_with(config, {"sim": {"faults": faults or {}}})
    check_plan(plan, config.axis)  # before anything is touched
    if campaign.status == "completed" and not missing_points(path, plan):
        raise InputError(f"{path}: the campaign is already completed: every point is recorded")
    recorder = Recorder.reopen(path)  # torn tails are cut before anything is read
    try:
        todo = missing_points(path, plan)
        t_last, position = last_raw_state(path)
        last_done = max(set(range(len(plan.points))) - set(todo), default=-1)
        return Resumption(path, config, plan, todo, [i for i in todo if i < last_done], t_last, position, recorder,
                          campaign.comp_table())
    except BaseException:
        recorder.close()
        raise


def continue_campaign(r: Resumption, **kwargs: Any) -> Outcome:
    """Measure the points `r` left out, each re-approached from the overrun in its own direction,
    in plan order, appending to the same files. The keywords go to `execute` (`opener` or
    `opened`)."""
    if not r.todo:  # stopped after its last point, before its stop record
        if r.plan.sweeps and not scan_results_written(r.path):  # a scan killed before (all of) its results
            finish_scan(r.recorder, r.config, r.plan)
        publish_stopped(r.recorder, r.t_last, "completed")
        r.recorder.emit(Event(r.t_last, "stop", "campaign completed: nothing left to measure", None,
                              StopData(status="completed", points=r.recorder.points_written)))
        r.recorder.stop(r.t_last, "completed", "nothing left to measure")
        r.recorder.close()
        return Outcome(r.path, "completed", len(r.plan.points), len(r.plan.points), r.t_last, "nothing left to measure")
    noun = "sweep" if r.plan.sweeps else "point"
    text = f"resumed: {len(r.todo)} of {len(r.plan.points)} {noun}s to measure, from {noun} {r.todo[0] + 1}"
    if r.again:
        text += f"; measured again after a skip: {', '.join(str(i + 1) for i in r.again)}"
    resumed = Event(r.t_last, "resume", text, r.todo[0],
                    ResumeData(first_point=r.todo[0], points=len(r.todo), skipped=list(r.again)))
    return execute(r.config, r.plan, r.recorder, r.todo, t_offset=r.t_last, start=r.position, announce=resumed,
                   **kwargs)


def resume_campaign(directory: str | Path, faults: dict[str, Any] | None = None, *, opener: Opener,
                    speed: float | None = None, **kwargs: Any) -> Outcome:
    """`prepare_resume`, open the hardware, `continue_campaign`: the script way of resuming."""
    r = prepare_resume(directory, faults)
    if not r.todo:
        return continue_campaign(r)
    try:
        opened = r.open(opener, speed)
    except BaseException as exc:
        if isinstance(exc, Exception):
            stopped_unopened(r.recorder, r.t_last, exc)
        r.close()
        raise
    return continue_campaign(r, opened=opened, speed=speed, **kwargs)


def missing_points(directory: Path, plan: Plan) -> list[int]:
    """The plan indices of the points not recorded in the directory's points.csv, ascending. A
    scan's (its sweeps.csv): every sweep from the start of the first pass not recorded whole, so
    that a resumed scan measures whole passes (each run of the executor is aligned by itself:
    campaign.measure.scan)."""
    if plan.sweeps:  # each sweep recorded checked against the plan before anything moves
        done = {s.point for s in read_sweeps(directory, plan)}
    else:
        done = set(recorded_point_indices(directory))
    missing = [i for i in range(len(plan.points)) if i not in done]
    if plan.sweeps and missing:
        runs = {plan.points[i].run for i in missing}
        return [i for i, p in enumerate(plan.points) if p.run in runs]
    return missing


def analyse_dir(directory: str | Path) -> tuple[object, Evaluation]:
    """Read a campaign directory's point table and evaluate it to ISO 230-2:2014."""
    table = read_points(Path(directory) / "points.csv")
    return table, evaluate(table)


def dry_run(config: Config, opener: Opener | None = None, ticks: int = 10, opened: Opened | None = None) -> dict[str, Any]:
    """Talk to the controller read-only and walk the plan: nothing is commanded.

    Reads the axis status, checks every move of the plan against the limits, and reads `ticks`
    sample periods of the interferometer. Returns what it saw (positions in axis unit).
    `opened`: hardware already opened read-only (tests inspect the simulated PLC afterwards)."""
    plan = build_plan(config)
    check_plan(plan, config.axis)
    config = config_with(config, {"axis_driver": {"read_only": True}})
    if opened is None:
        if opener is None:
            raise ValueError("dry_run: give an opener or opened hardware")
        opened = opener(config.driver)
    hardware, _ = opened
    try:
        status = hardware.axis.status()
        readings: list[Reading] = []
        for _ in range(ticks):
            hardware.clock.sleep(1.0 / config.instrument.rate_hz)
            readings.extend(hardware.interferometer.poll())
    finally:
        hardware.close()
    last = readings[-1] if readings else None
    return {"read_only": True, "axis_enabled": status.enabled, "axis_homed": status.homed,
            "axis_error": status.error, "axis_error_id": status.error_id,
            "axis_position": status.actual_position, "readings": len(readings),
            "beam_ok": bool(last and last.signal_ok), "reading": last.position if last else None,
            "points": len(plan.points), "moves": len(plan.stops()), "travel": plan.travel(),
            "estimated_duration_s": estimate_duration_s(plan, config.axis), "plan_within_limits": True}

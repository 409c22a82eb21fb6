"""The executor: interprets a plan's steps on an Axis, an Interferometer and a Clock.

It runs a tick loop at the instrument's sample period: every tick it lets time pass, takes the
readings that arrived, records them in the raw stream, and (while moving) polls the axis. Every
motion is checked against the soft limits and the velocity limit before it is sent. On any fault
or Ctrl-C the axis is halted and the recording is flushed; the campaign can be resumed from the
first missing point.

Each fact (a fault, a halt, a recorded point, a beam change, ...) is emitted once as an Event to
the sinks: the recorder first (events.jsonl; a disk error there stops the campaign), then the
display sinks (Observers), whose failures never stop it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Literal

from campaign import capture_methods
from campaign.capture_methods import mean_env
from campaign.config import Config
from campaign.errors import InputError
from campaign.measure.capture import BeamLost, Captured, NotStable, capture_point
from campaign.measure.deviation import point_deviation
from campaign.measure.env_guard import EnvironmentGuard
from campaign.plan import Capture, Checkpoint, Move, Plan, Settle, Step, check_motion
from campaign.record import (
    TRANSITIONS,
    BeamData,
    DisplayData,
    EnvironmentData,
    Event,
    EventData,
    FaultData,
    HaltData,
    InterruptData,
    Kind,
    NoData,
    PointData,
    Recorder,
    RecordingError,
    RunState,
    SerialData,
    StartData,
    StateData,
    SweepData,
)
from campaign.specs import STREAMING_CONTROLLERS, AxisSpec
from protocols.hardware import (
    Axis,
    AxisError,
    AxisStatus,
    Clock,
    Hardware,
    InstrumentError,
    PositionStream,
    Reading,
    StreamingAxis,
)
from protocols.units import DEVIATION_SCALE, deviation_label


def move_and_wait(axis: Axis, clock: Clock, tick: Callable[[], None], position: float, velocity: float,
                  limits: AxisSpec, move_timeout_s: float,
                  on_status: Callable[[AxisStatus], None] | None = None, poll_s: float = 0.0) -> AxisStatus:
    """The one way axiscal moves an axis: check the soft limits and the velocity limit, command the
    move, then call `tick()` (let a sample period pass) and poll the status until the axis is done
    and in position (`limits.in_position_window`). AxisError on an axis error or after `move_timeout_s`.
    `on_status(status)` sees every status read. `poll_s`: read the status only every `poll_s` s
    (0: every tick; a scan ticks at the instrument's rate, faster than a status read is worth).
    Positions in axis unit, velocity axis unit/s."""
    check_motion(position, velocity, limits)
    axis.start_move(position, velocity)
    start = polled = clock.now()
    window, timeout = limits.in_position_window, move_timeout_s
    while True:
        tick()
        if poll_s and clock.now() - polled < poll_s - 1e-9:
            continue
        polled = clock.now()
        status = axis.status()
        if on_status is not None:
            on_status(status)
        if status.error:
            raise AxisError(f"axis error {status.error_id} (0x{status.error_id:04X}) during the move to "
                            f"{position:g}", status.error_id)
        if status.done and not status.busy and abs(status.actual_position - position) <= window:
            return status
        if clock.now() - start > timeout:
            raise AxisError(f"move to {position:g} not done after {timeout:g} s")


SCAN_STATUS_POLL_S = 0.05
"""A scan reads the axis status every this many s while moving (its position comes as a stream)."""


class CampaignStopped(Exception):
    """The campaign stopped before the end (fault or abort); the directory is resumable."""


FAULTS = (AxisError, InstrumentError, BeamLost, NotStable)


class Observer:
    """A display sink, passive: sees every event, the plan at the start and the live readings, and
    decides nothing (the operator answers through the Control). The CLI shows rich bars, the
    guided session a dashboard. An exception from an observer never stops the campaign (it is
    logged once as a `display` event)."""

    def started(self, plan: Plan, todo: list[int]) -> None:
        """The executor starts to measure the points `todo` (plan indices, ascending)."""
    def reading(self, t_s: float, reading: Reading, target: float | None) -> None: ...
    def emit(self, event: Event) -> None: ...


FaultAnswer = Literal["retry", "skip", "abort"]
FAULT_ANSWERS: tuple[FaultAnswer, ...] = ("retry", "skip", "abort")


class Control:
    """The one control channel from the operator (keys, signals; set from another thread): pause
    between points, abort, and the answers to faults. With `asks_operator` the executor waits for
    an `answer` after a fault; without it the config's FaultPolicy decides."""

    def __init__(self, asks_operator: bool = False) -> None:
        import queue
        import threading

        self._pause = threading.Event()
        self._abort = threading.Event()
        self._wake = threading.Event()
        self._answers: queue.Queue[FaultAnswer] = queue.Queue()
        self.asks_operator = asks_operator
        self.abort_reason = ""

    def answer(self, decision: FaultAnswer) -> None:
        """The operator's answer to the fault the executor waits on: retry, skip or abort."""
        if decision not in FAULT_ANSWERS:
            raise ValueError(f"a fault is answered with {', '.join(FAULT_ANSWERS)}, not {decision!r}")
        self._answers.put(decision)
        self._wake.set()

    def await_answer(self) -> FaultAnswer:
        """Wait (real time) for the operator's answer; "abort" when an abort is requested meanwhile."""
        import queue

        while not self.abort_requested():
            try:
                return self._answers.get(timeout=0.1)
            except queue.Empty:
                continue
        return "abort"

    def pause_requested(self) -> bool:
        return self._pause.is_set()

    def abort_requested(self) -> bool:
        return self._abort.is_set()

    def request_pause(self) -> None:
        self._pause.set()

    def request_resume(self) -> None:
        self._pause.clear()
        self._wake.set()

    def request_abort(self, reason: str = "abort requested") -> None:
        """Abort at the next tick; `reason` goes into the event log (e.g. "key a")."""
        self.abort_reason = reason
        self._abort.set()
        self._wake.set()

    def wait(self, seconds: float) -> None:
        """Wait up to `seconds` of real time, or until resume/abort is requested."""
        self._wake.wait(seconds)
        self._wake.clear()


def stretch_steps(plan: Plan, first: int, last: int, overrun: float) -> list[tuple[int, Step]]:
    """The steps (with their plan index) that measure the consecutive points `first`..`last` (plan
    indices). Unless `first` is the plan's first point, they begin with a re-approach from the
    overrun, so that the point is approached in its own direction; when `last` is the plan's last
    point they include the plan's closing moves."""
    visits = plan.visits()
    steps = list(enumerate(plan.steps))
    closing = visits[last].checkpoint_step
    end = len(steps) if last == len(visits) - 1 or closing is None else closing + 1
    if first == 0:
        return steps[:end]
    visit = visits[first]
    point = visit.point
    if capture_methods.method(visit.capture.spec.method).sweeps:  # back to where the sweep starts, and rest
        low, high = plan.ends()
        start = low if point.direction > 0 else high
        return [(visit.step, Move(start, visit.move.velocity, overrun=True)), (visit.step, Settle(visit.settle_s)),
                *steps[visit.step:end]]
    approach = Move(point.target - point.direction * overrun, visit.move.velocity, overrun=True)
    return [(visit.step, approach)] + steps[visit.step:end]


def stretches(todo: list[int]) -> list[tuple[int, int]]:
    """Runs of consecutive plan indices in `todo` (ascending): [(first, last), ...]."""
    out: list[tuple[int, int]] = []
    for index in todo:
        if out and index == out[-1][1] + 1:
            out[-1] = (out[-1][0], index)
        else:
            out.append((index, index))
    return out


class Executor:
    """Runs one plan. Positions in axis unit, deviations in µm (linear) or arcsec (rotary)."""

    def __init__(self, plan: Plan, config: Config, hardware: Hardware, recorder: Recorder,
                 observers: list[Observer] | tuple[Observer, ...] = (), t0: float | None = None,
                 control: Control | None = None):
        self.plan, self.hw, self.rec = plan, hardware, recorder
        # the specs, resolved once: the executor reads nothing else of the config
        self.axis, self.policy, self.controller = config.axis, config.faults, config.controller
        self.environment, self.overrun = config.environment, config.plan.overrun
        self.observers = list(observers)
        self.control = control or Control()
        self.next_point = 0
        self.retries: dict[int, int] = {}
        self.env_guard = EnvironmentGuard()
        self.skipped_seen = 0
        self.beam_ok = True
        self.tick_s = 1.0 / config.instrument.rate_hz
        self.scale = DEVIATION_SCALE[self.axis.unit]
        self.t0 = hardware.clock.now() if t0 is None else t0
        self.step_index = 0
        self.point_index: int | None = None
        self.axis_position: float | None = None
        self.target: float | None = None
        self.arrival_s = 0.0
        self.readings: list[Reading] = []
        self.halted = False
        self.sweeps = plan.sweeps
        """The plan is a scan: the controller streams its position while the axis sweeps."""
        self.position_stream: PositionStream | None = None
        self.sweep_samples = 0  # instrument readings since the last move started
        self.sweep_positions = 0  # controller samples since the last move started
        self.sweep_beam_lost = False  # a reading with the beam not OK since the last sweep was recorded
        self.state = RunState.IDLE
        self.stop_reason = ""
        self._display_failed = False

    def _enter(self, state: RunState, reason: str = "") -> None:
        """Go to run state `state` and publish the transition (a `state` event); staying in a state
        publishes nothing. A transition the state machine (TRANSITIONS) does not have is a bug.
        The event is recorded like any other (RecordingError propagates) except on the way to
        `stopped`, which nothing may keep from being reached."""
        if state == self.state:
            return
        if state not in TRANSITIONS[self.state]:
            raise RuntimeError(f"run state {self.state} cannot go to {state}")
        previous, self.state = self.state, state
        data = StateData(state=state, previous=previous, reason=reason)
        message = f"{previous} -> {state}" + (f": {reason}" if reason else "")
        if state is RunState.STOPPED:
            self.stop_reason = reason
            self._emit_safely("state", message, self.point_index, data)
        else:
            self.emit("state", message, self.point_index, data)

    def stop(self, reason: str) -> None:
        """End the run in `stopped` with `reason` (completed, or why not), once: every run ends
        there, whatever stopped it. The session calls it when it closes the run."""
        if self.state is not RunState.STOPPED:
            self._enter(RunState.STOPPED, reason or "stopped")

    def now(self) -> float:
        """Seconds since campaign start."""
        return self.hw.clock.now() - self.t0

    def emit(self, kind: Kind, message: str, point: int | None = None, data: EventData | None = None) -> None:
        """Emit one fact now: recorded first (RecordingError propagates), then shown. `data`: the
        kind's payload (campaign.record.PAYLOADS), none for the kinds without one."""
        self.publish(Event(self.now(), kind, message, point, data if data is not None else NoData()))

    def publish(self, event: Event) -> None:
        """The one emitter of a run's events (the executor's own, and the session's resume and stop):
        recorded first (RecordingError propagates), then shown."""
        self.rec.emit(event)
        self._show(lambda obs: obs.emit(event))

    def _show(self, call: Callable[[Observer], None]) -> None:
        """Call every observer; a failing display is recorded once and otherwise ignored."""
        for obs in self.observers:
            try:
                call(obs)
            except Exception as exc:  # noqa: BLE001 - a display must never stop a campaign
                if not self._display_failed:
                    self._display_failed = True
                    try:
                        self.rec.emit(Event(self.now(), "display", f"a display failed: {type(exc).__name__}: "
                                                                   f"{exc}", None, DisplayData(error=type(exc).__name__)))
                    except RecordingError:
                        pass

    def run(self, todo: int | list[int] = 0) -> None:
        """Measure the points `todo` (plan indices; an int n means n to the end) in plan order. On a
        fault the fault policy decides (`_decide`): retry the point, skip it, or abort
        (CampaignStopped, after halting). Ctrl-C or an abort request halts, flushes and re-raises
        KeyboardInterrupt. The run state ends idle (done: the session then stops it, `stop`) or
        stopped with the reason, however the run ended (a failed recovery, an unexpected error)."""
        total = len(self.plan.points)
        points = list(range(todo, total)) if isinstance(todo, int) else sorted(set(todo))
        self._show(lambda obs: obs.started(self.plan, points))
        todo = points
        try:
            if todo and self.sweeps:
                self._open_position_stream()
            if todo:
                self.emit("start", f"measuring {len(todo)} of {total} points, from point {todo[0] + 1}", todo[0],
                          StartData(first_point=todo[0], points=len(todo), planned=total))
            while todo:
                todo = self._run_points(todo)
            self._enter(RunState.IDLE, "every point to measure is done")
        except KeyboardInterrupt:
            by = self.control.abort_reason or "Ctrl-C"
            self._emit_safely("interrupt", f"interrupted ({by}); recording flushed", self.next_point,
                              InterruptData(by=by))
            self._halt("interrupted")
            self.stop(f"interrupted ({by})")
            raise
        except RecordingError as exc:  # an event between steps (retry, skip, pause) could not be written
            self._halt("recording failed")
            self.stop(f"interrupted: recording failed: {exc}")
            raise CampaignStopped(f"recording failed: {exc}") from exc
        except CampaignStopped as exc:  # an abort after a fault, a failed recovery, a recording error
            self.stop(f"interrupted: {exc}")
            raise
        except InputError as exc:  # a motion refused before it was sent (SafetyError)
            self.stop(f"interrupted: {exc}")
            raise
        except BaseException as exc:  # a bug, or an error no fault policy covers: stopped all the same
            self.stop(f"failed: {type(exc).__name__}: {exc}")
            raise
        finally:
            if self.position_stream is not None:
                self.position_stream.close()
                self.position_stream = None

    def _open_position_stream(self) -> None:
        """A scan: the controller streams its actual position with its own time stamps at every
        cycle (ADS device notifications); an axis that cannot is refused before anything moves."""
        axis = self.hw.axis
        if not isinstance(axis, StreamingAxis):
            raise InputError(f"axis_driver.type = \"{self.controller.type}\": this axis cannot stream its actual "
                             "position with the controller's time stamps, which a scan needs (ADS device "
                             f"notifications: the {' and '.join(sorted(STREAMING_CONTROLLERS))} drivers)")
        self.position_stream = axis.stream_positions(0.0, 0.05)

    def _run_points(self, todo: list[int]) -> list[int]:
        """Measure `todo`, one stretch of consecutive points at a time; returns the points still to
        measure after a fault the observer chose to retry or skip, [] at the end."""
        total = len(self.plan.points)
        for first, last in stretches(todo):
            self.next_point = first
            self.sweep_beam_lost = False
            captured: Captured | None = None  # handed from a capture step to its checkpoint
            for index, step in stretch_steps(self.plan, first, last, self.overrun):
                self.step_index = index
                try:
                    captured = self._do(step, captured)
                except RecordingError as exc:
                    self._emit_safely("fault", f"point {self.next_point + 1}: recording failed: {exc}",
                                      self.next_point, FaultData(error="RecordingError", error_id=0))
                    self._halt("recording failed")
                    self.stop(f"interrupted: recording failed: {exc}")
                    raise CampaignStopped(f"recording failed: {exc}") from exc
                except FAULTS as exc:
                    return self._after_fault(exc, todo, total)
                if isinstance(step, Checkpoint):
                    self.next_point = step.point.index + 1
                    self._maybe_pause()
        return []

    def _after_fault(self, exc: Exception, todo: list[int], total: int) -> list[int]:
        """Halt, let the operator (or the policy) decide, get the axis ready again; the points left."""
        point = self.next_point
        self._enter(RunState.FAULTED, f"point {point + 1}: {type(exc).__name__}: {exc}")
        self._emit_safely("fault", f"point {point + 1}: {type(exc).__name__}: {exc}", point,
                          FaultData(error=type(exc).__name__, error_id=getattr(exc, "error_id", 0)))
        self._halt("fault")
        decision = self._decide(exc, total)
        if decision == "abort":
            raise CampaignStopped(str(exc)) from exc
        if decision == "skip" and self.sweeps:  # a scan's table needs whole passes: none is left for later
            raise CampaignStopped(f"a scan cannot skip a sweep: pass {self.plan.points[point].run} (point {point + 1}) "
                                  "is measured again, whole, by `axiscal resume`") from exc
        self._recover(exc)  # CampaignStopped when the axis is not ready again: run() stops
        if self.sweeps:  # a lost connection took the position stream with it; the next sweeps need one
            if self.position_stream is not None:
                self.position_stream.close()
            try:
                self._open_position_stream()
            except AxisError as refused:
                raise CampaignStopped(f"the position stream could not be started again: {refused}") from refused
        if decision == "skip":
            self.emit("skip", f"point {point + 1} skipped (resume measures it later)", point)
            return [p for p in todo if p > point]
        self.emit("retry", f"point {point + 1} measured again", point)
        if self.sweeps:  # a scan measures whole passes: the interrupted one again from its first sweep
            run = self.plan.points[point].run
            again = [i for i, p in enumerate(self.plan.points) if p.run == run and i < point]
            return sorted({*again, *(p for p in todo if p >= point)})
        return [p for p in todo if p >= point]

    def _decide(self, exc: Exception, total: int) -> FaultAnswer:
        """The one fault policy: the operator's answer through the control channel when it asks
        the operator, else the config's (`campaign.on_fault`): retry a point up to
        `campaign.fault_retries` times after an axis fault, a lost connection or beam loss (the one
        retry budget), skip it at once (resume measures it later), or abort; a vanished instrument
        port cannot be retried in this process (resume later)."""
        if self.next_point >= total:
            return "abort"
        if self.control.asks_operator:
            return self.control.await_answer()
        used = self.retries.get(self.next_point, 0)
        if self.policy.on_fault == "abort" or isinstance(exc, InstrumentError):
            return "abort"
        if self.policy.on_fault == "skip":
            return "skip"
        if used >= self.policy.fault_retries:
            return "abort"
        self.retries[self.next_point] = used + 1
        return "retry"

    def _recover(self, exc: Exception) -> None:
        """Get the axis ready again before anything else is commanded: wait for a lost connection
        to return, wait until the halt has brought the axis to rest, then clear any error."""
        if isinstance(exc, AxisError) and exc.error_id == 0:
            self._wait_for_connection(self.controller.reconnect_s)
        end = self.now() + self.controller.move_timeout_s
        try:
            self._wait(self.tick_s)
            status = self.hw.axis.status()
            while status.busy and self.now() < end:
                self._wait(self.tick_s)
                status = self.hw.axis.status()
            if status.busy:
                raise CampaignStopped("the axis did not come to rest after the halt")
            if status.error:
                self.hw.axis.reset()
                self._wait(self.tick_s)
        except AxisError as again:
            raise CampaignStopped(f"axis not ready after the fault: {again}") from again

    def _wait_for_connection(self, limit_s: float) -> None:
        end = self.now() + limit_s
        while True:
            try:
                self.hw.axis.status()
            except AxisError:
                if self.now() >= end:
                    raise CampaignStopped(f"the PLC connection did not come back within {limit_s:g} s") from None
                self._wait(1.0)
                continue
            self.emit("reconnect", "PLC connection back")
            return

    def _maybe_pause(self) -> None:
        """Between points: hold while the control asks for a pause; abort when it asks to."""
        if self.control.pause_requested() and not self.control.abort_requested():
            self._enter(RunState.PAUSED, "the operator asked for a pause")
            self.emit("pause", f"paused after point {self.next_point}: press r to resume, a to abort",
                      self.next_point - 1)
            while self.control.pause_requested() and not self.control.abort_requested():
                self._tick()  # the axis stands; the laser is still read and recorded, the display lives
                self.control.wait(self.tick_s)
            self.emit("unpause", "resumed by the operator")
        if self.control.abort_requested():
            raise KeyboardInterrupt

    def _emit_safely(self, kind: Kind, message: str, point: int | None = None, data: EventData | None = None) -> None:
        """Emit while stopping: a disk error must not keep the axis from being halted (the event
        is still shown, marked as not recorded)."""
        try:
            self.emit(kind, message, point, data)
        except RecordingError as exc:
            event = Event(self.now(), kind, f"{message} (not recorded: {exc})", point,
                          data if data is not None else NoData())
            self._show(lambda obs: obs.emit(event))

    def _halt(self, why: str) -> None:
        try:
            self.hw.axis.halt()
            self.halted = True
            self._emit_safely("halt", f"axis halted ({why})", self.next_point, HaltData(ok=True, why=why))
        except AxisError as exc:
            self._emit_safely("halt", f"halt failed ({why}): {exc}", self.next_point, HaltData(ok=False, why=why))

    def _do(self, step: Step, captured: Captured | None) -> Captured | None:
        """Do one step. `captured`: what the last capture step returned; a capture step returns
        its point, which the checkpoint after it records (and then consumes: None)."""
        if isinstance(step, Move):
            self._enter(RunState.MOVING, "" if step.overrun else f"to point {self.next_point + 1}")
            self._move(step)
            return None
        if isinstance(step, Settle):
            self._enter(RunState.SETTLING)
            self._wait(step.seconds)
            return captured
        if isinstance(step, Capture):
            self._enter(RunState.CAPTURING)
            return self._capture(step)
        self._checkpoint(step, captured)
        return None

    def _tick(self) -> None:
        """Let one sample period pass and record the readings that arrived."""
        if self.control.abort_requested():
            raise KeyboardInterrupt
        self.hw.clock.sleep(self.tick_s)
        t = self.now()
        for reading in self.hw.interferometer.poll():
            self.rec.sample(t, self.step_index, self.point_index, self.axis_position, reading)
            self.readings.append(reading)
            self.sweep_samples += 1
            if not reading.signal_ok:
                self.sweep_beam_lost = True
            self._show_reading(t, reading)
            if reading.signal_ok != self.beam_ok:
                self.beam_ok = reading.signal_ok
                signal = "" if reading.signal_pct is None else f" (signal {reading.signal_pct:g} %)"
                self.emit("beam", ("beam back" if reading.signal_ok else "beam lost") + signal, self.point_index,
                          BeamData(ok=reading.signal_ok, signal_pct=reading.signal_pct))
        if self.position_stream is not None:
            positions = self.position_stream.take()
            if positions:
                self.rec.positions(t, self.step_index, positions)
                self.sweep_positions += len(positions)

    def _show_reading(self, t: float, reading: Reading) -> None:
        self._show(lambda obs: obs.reading(t, reading, self.target))

    def _wait(self, seconds: float) -> None:
        end = self.now() + seconds - 1e-9
        while self.now() < end:
            self._tick()

    def _move(self, step: Move) -> None:
        self.target = None if step.overrun else step.position
        self.point_index = None if step.overrun else self.next_point
        self.sweep_samples = self.sweep_positions = 0

        def seen(status: AxisStatus) -> None:
            self.axis_position = status.actual_position

        move_and_wait(self.hw.axis, self.hw.clock, self._tick, step.position, step.velocity, self.axis,
                      self.controller.move_timeout_s, seen, SCAN_STATUS_POLL_S if self.sweeps else 0.0)
        self.arrival_s = self.now()
        self.readings = []

    def _capture(self, step: Capture) -> Captured:
        """Capture the point as its step says; after beam loss wait for the beam and capture again,
        up to the spec's `retries` times."""
        self.point_index = step.point.index
        if capture_methods.method(step.spec.method).sweeps:  # the sweep and its rest are in the streams
            if self.sweep_beam_lost:  # a sweep with a hole in the instrument's stream: the fault policy decides
                self.sweep_beam_lost = False
                raise BeamLost(f"beam not OK during the sweep of point {step.point.index + 1} or the rest "
                               "before its record")
            last = self.readings[-1].position if self.readings else float("nan")
            return Captured(last, self.sweep_samples, self.now() - self.arrival_s, mean_env(self.readings))
        for attempt in range(step.spec.retries + 1):
            try:
                return capture_point(step, self.scale, self._capture_ticks(), self.now() - self.arrival_s)
            except BeamLost as exc:
                if attempt == step.spec.retries:
                    raise
                self.emit("capture_retry", f"point {step.point.index + 1}: {exc}; capture retried", step.point.index)
                self._wait_for_beam(step.spec.stable_timeout_s)
        raise AssertionError("unreachable: the last attempt returns or raises")

    def _capture_ticks(self) -> Iterator[tuple[float, list[Reading]]]:
        """The running campaign as capture ticks: (time since arrival s, the readings of the tick)."""
        while True:
            self.readings = []
            self._tick()
            yield self.now() - self.arrival_s, self.readings

    def _wait_for_beam(self, timeout_s: float) -> None:
        end = self.now() + timeout_s
        while self.now() < end:
            self._tick()
            if self.readings and self.readings[-1].signal_ok:
                return
        raise BeamLost(f"beam not back within {timeout_s:g} s")

    def _sweep_done(self, index: int, run: int, direction: int, end: float, t: float, samples: int) -> None:
        """Record a scan's sweep (its streams first, durably) and say so."""
        self.rec.sweep(index, run, direction, end, t, samples, self.sweep_positions)
        sign = "+" if direction > 0 else "-"
        self.emit("sweep", f"sweep {index + 1} of {len(self.plan.points)}: pass {run} {sign} to {end:g} "
                           f"{self.axis.unit}, {samples} readings and {self.sweep_positions} controller samples",
                  index, SweepData(run=run, direction=direction, end=end, samples=samples,
                                   positions=self.sweep_positions))

    def _checkpoint(self, step: Checkpoint, captured: Captured | None) -> None:
        point, t = step.point, self.now()
        if captured is None:
            raise ValueError(f"plan step {self.step_index}: a checkpoint without a capture before it")
        if self.sweeps:
            self._sweep_done(point.index, point.run, point.direction, point.target, t, captured.samples)
            self.sweep_beam_lost = False
            return
        env, messages = self.env_guard.check(captured.env, t)
        got = replace(captured, env=env)
        for field, problem, message in messages:
            self.emit("environment", f"point {point.index + 1}: {message}", point.index,
                      EnvironmentData(field=field, problem=problem))
        skipped = self.hw.interferometer.skipped_lines
        if skipped > self.skipped_seen:
            lines = skipped - self.skipped_seen
            self.emit("serial", f"{lines} garbage or partial serial line(s) skipped, not recorded", point.index,
                      SerialData(lines=lines))
            self.skipped_seen = skipped
        deviation, air, material = point_deviation(self.environment, self.axis.unit, point.target, got)
        self.rec.point(point.run, point.direction, point.target, deviation, t, got.env,
                       {"point": point.index, "reading": got.position, "air_correction_um": air,
                        "material_correction_um": material, "capture_wait_s": got.wait_s,
                        "samples": got.samples})
        sign = "+" if point.direction > 0 else "-"
        pos_unit = self.axis.unit
        dev_unit = deviation_label(pos_unit)
        self.emit("point", f"point {point.index + 1}: run {point.run} {sign}, target {point.target:g} {pos_unit}: "
                           f"deviation {deviation:+.4f} {dev_unit}", point.index,
                  PointData(run=point.run, direction=point.direction, target=point.target,
                            deviation=round(deviation, 4)))

"""The live dashboard of `axiscal guide`.

`Dashboard` is the campaign's Observer: progress bars with ETA, the current point, the live reading
and deviation, a chart of the mean deviation per target and direction, warnings, and the fault
prompt (answered with a key, see campaign/guide/keys.py). On a terminal it draws itself with rich
Live; otherwise (a script) it prints one line per event.
Positions in the axis unit (mm or deg), deviations in µm (arcsec on a rotary axis), times in s.
"""

from __future__ import annotations

from collections import deque
from typing import Self

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.panel import Panel
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
from rich.table import Table

from campaign.config import Config
from campaign.guide.keys import Keys
from campaign.measure import BeamLost, Control, FaultAnswer, NotStable, Observer, live_text
from campaign.plan import Plan, Point
from campaign.record import Event, RunState
from protocols.hardware import AxisError, Hardware, InstrumentError, Reading
from protocols.units import deviation_label

BLOCKS = "▁▂▃▄▅▆▇█"
QUIET_KINDS = ("start", "point", "interrupt", "fault", "halt", "stop", "skip", "retry", "state")
"""Events the dashboard shows its own way (progress, the fault prompt, abort()) or not at all."""

WORKING = (RunState.MOVING, RunState.SETTLING, RunState.CAPTURING)
"""The run states in which the axis works through the plan (a pause may be asked for)."""

STATE_COLOUR = {RunState.IDLE: "white", RunState.MOVING: "green", RunState.SETTLING: "green",
                RunState.CAPTURING: "green", RunState.PAUSED: "yellow", RunState.FAULTED: "red",
                RunState.STOPPED: "red"}

SIGNED_BLOCKS = "▁▂▃▄▅▆▇"
"""The deviation chart's levels: an odd number, so that 0 is the middle block (▄) of a scale
symmetric about 0, below it the negative deviations, above it the positive ones."""

CTRL_C_HELP = "Ctrl-C abort"


def key_help(state: RunState | None, request: str | None = None) -> str:
    """The key line for the published run state and the operator's pending request: only the keys
    that do something now."""
    if state is RunState.STOPPED:
        return ""
    if request == "aborting":
        return "aborting: the axis halts and the recording is flushed · Ctrl-C three times: quit at once"
    if state is RunState.PAUSED:
        return f"keys: r resume · a abort · {CTRL_C_HELP}"
    if request == "pause requested":
        return f"keys: r cancel the pause · a abort · {CTRL_C_HELP}"
    return f"keys: p pause after this point · a abort · {CTRL_C_HELP}"


def sparkline(values: list[float | None], lo: float, hi: float, width: int = 1, blocks: str = BLOCKS) -> str:
    """One block of `blocks` per value between lo and hi (`width` characters each); '·' where there is none."""
    out = []
    for v in values:
        if v is None:
            out.append("·" * width)
            continue
        out.append(blocks[level_of(v, lo, hi, len(blocks))] * width)
    return "".join(out)


def signed_sparkline(values: list[float | None], half: float, width: int = 1) -> str:
    """The values on a scale from -half to +half (SIGNED_BLOCKS): 0 is the middle block (▄), -half
    the lowest (▁), +half the highest (▇); a more negative deviation is a lower block."""
    return sparkline(values, -half, half, width, SIGNED_BLOCKS)


def level_of(value: float, lo: float, hi: float, levels: int = len(BLOCKS)) -> int:
    """The block (0 to levels - 1) that shows `value` on a scale from lo to hi."""
    return 0 if hi <= lo else round((value - lo) / (hi - lo) * (levels - 1))


def clock_text(seconds: float) -> str:
    """h:mm:ss for a duration in s."""
    seconds = max(0, round(seconds))
    return f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}"


def error_id_text(error_id: int) -> str:
    """A controller error number in decimal and hex, as TwinCAT's documentation lists them (the
    number is the controller's error id: look it up in its error list)."""
    return f"{error_id} (0x{error_id:04X})"


def describe_fault(error: str, error_id: int, detail: str) -> str:
    """A short sentence for the operator from a fault event (the error's class name, the controller
    error number, the error's text): what happened and what to look at."""
    if error == BeamLost.__name__:
        return f"beam lost ({detail}). Check the beam path and the optics"
    if error == NotStable.__name__:
        return f"reading not stable ({detail}). Check for vibration or air draught"
    if error == AxisError.__name__ and error_id:
        return f"axis error {error_id_text(error_id)}: {detail}. Check the drive"
    if error == AxisError.__name__:
        return f"lost connection to the controller ({detail}). Check the network cable"
    if error == InstrumentError.__name__:
        return f"lost connection to the interferometer ({detail}). Check its cable"
    return f"{error}: {detail}"


class Dashboard(Observer):
    """The campaign on screen, a passive sink of the event stream. `on_fault`: "ask" (the operator
    answers a fault prompt with a key, which goes to the executor through `control`), or anything
    else (the executor's FaultPolicy decides, [campaign] on_fault; the dashboard only shows what it
    did). `hw`: the hardware the campaign runs on.

    Points are counted from 1 on screen, like the progress bars; points.csv's `point` column holds
    the plan index (from 0). The ETAs are machine time: the time per point measured so far (pauses
    left out) times the points left."""

    def __init__(self, console: Console, config: Config, plan: Plan, control: Control, on_fault: str | None,
                 hw: Hardware | None = None, keys: Keys | None = None) -> None:
        self.console, self.plan, self.control, self.on_fault, self.keys = console, plan, control, on_fault, keys
        self.hw, self.tick_s = hw, 1.0 / config.instrument.rate_hz
        self.unit = config.axis.unit
        self.dev_unit = deviation_label(self.unit)
        self.runs = config.plan.cycles
        self.per_run = len(plan.points) // self.runs
        self.state: RunState | None = None
        """The executor's run state as published (its `state` events); None before the run starts."""
        self.state_reason = ""
        self.request: str | None = None
        """The operator's request the executor has not acted on yet: "pause requested", "aborting"."""
        self.abort_reason: str | None = None
        self.prompt: str | None = None
        self.warnings: deque[str] = deque(maxlen=4)
        self.done: set[int] = set()
        self.todo: list[int] = list(range(len(plan.points)))
        self.skipped: set[int] = set()
        self.t_s, self.paused_s = 0.0, 0.0
        self.started_s: float | None = None
        self.pause_began: float | None = None
        self.measured_now = 0
        self.run = 1
        self.live_text = "no reading yet"
        self.deviations: dict[int, list[list[float]]] = {d: [[] for _ in plan.targets] for d in (1, -1)}
        self.progress = Progress(TextColumn("{task.description:<12}"), BarColumn(bar_width=50),
                                 MofNCompleteColumn(), TextColumn("points  {task.fields[eta]}"))
        self.overall = self.progress.add_task("campaign", total=len(plan.points), eta="")
        self.run_task = self.progress.add_task(f"run 1 of {self.runs}", total=self.per_run, eta="")
        self.live = Live(self, console=console, refresh_per_second=4) if console.is_terminal else None

    def __enter__(self) -> Self:
        if self.live is not None:
            self.live.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live is not None:
            self.live.stop()

    # -- what the operator sees ------------------------------------------------------------------

    def __rich__(self) -> Group:
        parts: list[RenderableType] = [self.progress, self._status(), self._chart()]
        if self.warnings:
            parts.append("\n".join(f"[yellow]warning:[/] {w}" for w in self.warnings))
        if self.prompt:
            parts.append(Panel(self.prompt, title="FAULT", border_style="bold red"))
        else:
            parts.append(f"[dim]{key_help(self.state, self.request)}[/]")
        return Group(*parts)

    def current(self) -> int | None:
        """The plan index of the point being measured (the first one to do), None at the end."""
        return next((i for i in self.todo if i not in self.done and i not in self.skipped), None)

    def _status(self) -> Table:
        grid = Table.grid(padding=(0, 2))
        grid.add_column(style="bold")
        grid.add_column()
        grid.add_row("state", self.state_text())
        index = self.current()
        if index is not None and self.state is not RunState.STOPPED:
            p = self.plan.points[index]
            arrow = "+ (up ↑)" if p.direction > 0 else "- (down ↓)"
            grid.add_row("point", f"{index + 1} of {len(self.plan.points)}: run {p.run} of {self.runs}, "
                                  f"target {p.target:.3f} {self.unit}, direction {arrow}")
        grid.add_row("live", self.live_text)
        skipped = f", skipped: {len(self.skipped)} point{'s' if len(self.skipped) > 1 else ''}" if self.skipped else ""
        grid.add_row("time", f"{clock_text(self.t_s)} of campaign time{skipped}")
        return grid

    def _chart(self) -> Table:
        means = {d: [sum(v) / len(v) if v else None for v in lists] for d, lists in self.deviations.items()}
        known = [m for ms in means.values() for m in ms if m is not None]
        grid = Table.grid(padding=(0, 2))
        grid.add_column(style="bold")
        grid.add_column()
        grid.add_row("deviation", f"mean per target, {self.plan.targets[0]:g} to {self.plan.targets[-1]:g} "
                                  f"{self.unit}" + (f", {min(known):+.2f} to {max(known):+.2f} {self.dev_unit}"
                                                    if known else ""))
        width = max(1, 48 // len(self.plan.targets))
        half = max((abs(m) for m in known), default=0.0) or 1.0  # one scale for both directions
        for direction, label in ((1, "↑ +"), (-1, "↓ -")):
            grid.add_row(f"  {label}", signed_sparkline(means[direction], half, width))
        if known:
            middle = SIGNED_BLOCKS[len(SIGNED_BLOCKS) // 2]
            grid.add_row("  0", f"[dim]{middle * width * len(self.plan.targets)}[/] "
                                f"[dim](0 {self.dev_unit}; the scale is ±{half:.2f} {self.dev_unit})[/]")
        return grid

    def state_text(self) -> str:
        """The published run state as the operator sees it, with the operator's pending request
        and, once stopped, the reason."""
        if self.state is None:
            return "[bold]STARTING[/]"
        text, colour = self.state.upper(), STATE_COLOUR[self.state]
        if self.state is RunState.PAUSED and self.pause_began is not None:
            text += f" for {clock_text(self.t_s - self.pause_began)} (r resumes, a aborts)"
        if self.state is RunState.STOPPED:
            colour = "green" if self.state_reason == "completed" else "red"
            text += f": {self.state_reason}" if self.state_reason else ""
        elif self.request:
            text += f" · {self.request}"
        return f"[bold {colour}]{text}[/]"

    def say(self, message: str, warning: bool = True) -> None:
        """A warning on the dashboard (one line in a script)."""
        if warning:
            self.warnings.append(message)
        if self.live is None or not self.live.is_started:
            self.console.print(f"[yellow]{'warning: ' if warning else ''}[/]{message}")

    # -- keys -----------------------------------------------------------------------------------

    def on_key(self, key: str) -> None:
        if self.prompt is not None and key in ("r", "s", "a"):  # the answer to the fault prompt
            self.prompt = None
            answers: dict[str, FaultAnswer] = {"r": "retry", "s": "skip", "a": "abort"}
            self.control.answer(answers[key])
            if key == "a":
                self.request = "aborting"
            return
        if key == "p" and self.state in WORKING and not self.control.pause_requested():
            self.control.request_pause()
            self.request = "pause requested"
            self.say("pause requested: the axis stops after this point", warning=False)
        elif key == "r" and self.control.pause_requested():
            self.control.request_resume()
            if self.request == "pause requested":
                self.request = None
        elif key == "a" and not self.control.abort_requested():
            self.abort("a pressed")

    def abort(self, why: str) -> None:
        self.abort_reason = f"aborted by the operator ({why})"
        self.control.request_abort(self.abort_reason)
        self.request = "aborting"
        self.say(f"{why}: aborting, the axis halts and the recording is flushed")

    # -- Observer (a display sink of the event stream) ---------------------------------------------

    def started(self, plan: Plan, todo: list[int]) -> None:
        self.todo = list(todo)
        self.done = {p.index for p in plan.points} - set(todo)
        self._update_bars()

    def reading(self, t_s: float, reading: Reading, target: float | None) -> None:
        self.t_s = t_s
        self.live_text = live_text(reading, target, self.unit)

    def point_done(self, point: Point, deviation: float, t_s: float) -> None:
        self.deviations[point.direction][point.target_index].append(deviation)
        self.done.add(point.index)
        self.skipped.discard(point.index)
        self.measured_now += 1
        self.t_s = t_s
        self._update_bars()
        if self.live is None and self._done_in(point.run) == self.per_run:
            self.console.print(f"run {point.run} of {self.runs} done at {clock_text(t_s)} of campaign time "
                               f"({len(self.done)} of {len(self.plan.points)} points measured)")

    def _done_in(self, run: int) -> int:
        return sum(1 for i in self.done | self.skipped if self.plan.points[i].run == run)

    def _per_point_s(self) -> float | None:
        """Machine time per point measured in this session, pauses left out, s."""
        if self.started_s is None or not self.measured_now:
            return None
        return max(self.t_s - self.started_s - self.paused_s, 0.0) / self.measured_now

    def _update_bars(self) -> None:
        index = self.current()
        run = self.plan.points[index].run if index is not None else self.run
        if run != self.run:  # a new run: a new bar, so that its ETA starts afresh
            self.run = run
            self.progress.reset(self.run_task, total=self.per_run, description=f"run {run} of {self.runs}")
        per_point = self._per_point_s()
        left = len(self.plan.points) - len(self.done) - len(self.skipped)
        left_in_run = self.per_run - self._done_in(run)

        def eta(points: int) -> str:
            return "" if per_point is None else f"ETA {clock_text(points * per_point)} machine time"

        self.progress.update(self.overall, completed=len(self.done) + len(self.skipped), eta=eta(left))
        self.progress.update(self.run_task, completed=self._done_in(run), eta=eta(left_in_run))

    def emit(self, event: Event) -> None:
        kind = event.kind
        if kind == "state":
            self._state(event)
        elif kind == "start":
            self.started_s = event.t_s
        elif kind == "point" and event.point is not None:
            self.point_done(self.plan.points[event.point], event.data["deviation"], event.t_s)
        elif kind == "pause":
            self.pause_began = event.t_s
            self.say("PAUSED: press r to resume, a to abort", warning=False)
        elif kind == "unpause":
            self.paused_s += event.t_s - (self.pause_began if self.pause_began is not None else event.t_s)
            self.pause_began = None
            self.say("resumed", warning=False)
        elif kind == "fault":
            self._fault(event)
        elif kind in ("retry", "skip"):
            self._answered(event)
        elif kind == "resume":
            self.say(event.message, warning=False)
        elif kind == "stop":
            self.prompt = None
        elif kind not in QUIET_KINDS or (kind == "halt" and not event.data.get("ok")):
            self.say(f"{kind}: {event.message}")

    def _state(self, event: Event) -> None:
        """The executor's run state changed: show it (the one state, never derived here)."""
        self.state, self.state_reason = RunState(event.data["state"]), str(event.data["reason"])
        if self.state is RunState.PAUSED or self.state is RunState.STOPPED:
            self.request = None if self.request == "pause requested" else self.request
        if self.state is RunState.STOPPED:
            self.request = None
        if self.live is None and self.state is RunState.STOPPED:
            self.console.print(f"state: {self.state}" + (f" ({self.state_reason})" if self.state_reason else ""))

    def _fault(self, event: Event) -> None:
        """A fault event: the axis is halted. When the operator answers faults (`on_fault` "ask"),
        show the prompt; the answer goes to the executor through the Control (`on_key`)."""
        point = event.point if event.point is not None else 0
        detail = event.message.split(": ", 2)[-1]
        text = (f"point {point + 1}: {describe_fault(str(event.data.get('error', '')), int(event.data.get('error_id', 0)), detail)}. "
                "The axis is halted.")
        self.say(text)
        if self.on_fault == "ask" and self.control.asks_operator:
            self.prompt = f"{text}\nPress r to retry the point, s to skip it (resume measures it later), a to abort."

    def _answered(self, event: Event) -> None:
        """The executor went on after a fault (a retry or skip event)."""
        point = event.point if event.point is not None else 0
        self.prompt = None
        self.say(f"fault at point {point + 1}: {event.kind}", warning=False)
        if event.kind == "skip":
            self.skipped.add(point)
            self._update_bars()

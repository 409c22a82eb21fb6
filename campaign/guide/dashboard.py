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

from rich.console import Console, Group
from rich.live import Live
from rich.panel import Panel
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from campaign.guide.keys import Keys
from campaign.measure.capture import BeamLost, NotStable
from campaign.measure.executor import Control, Observer
from campaign.plan import Plan
from campaign.record.events import Event
from protocols.hardware import AxisError, InstrumentError
from protocols.units import DEVIATION_SCALE

BLOCKS = "▁▂▃▄▅▆▇█"
LIVE_DEVIATION_BAND = 100.0
"""The live deviation is shown within this distance of the target, µm (arcsec); else the distance."""
QUIET_KINDS = ("start", "point", "interrupt", "fault", "halt", "stop", "skip", "retry")
"""Events the dashboard shows its own way (progress, the fault prompt, abort()) or not at all."""

KEY_HELP = "keys: p pause after this point · r resume · a abort · Ctrl-C abort (twice: halt at once)"


def sparkline(values: list[float | None], lo: float, hi: float, width: int = 1) -> str:
    """One block per value between lo and hi (`width` characters each); '·' where there is none."""
    out = []
    for v in values:
        if v is None:
            out.append("·" * width)
            continue
        level = 0 if hi <= lo else round((v - lo) / (hi - lo) * (len(BLOCKS) - 1))
        out.append(BLOCKS[level] * width)
    return "".join(out)


def describe_fault(exc: Exception) -> str:
    """A short sentence for the operator: what happened and what to look at."""
    if isinstance(exc, BeamLost):
        return f"beam lost ({exc}). Check the beam path and the optics"
    if isinstance(exc, NotStable):
        return f"reading not stable ({exc}). Check for vibration or air draught"
    if isinstance(exc, AxisError) and exc.error_id:
        return f"axis error {exc.error_id} ({exc}). Check the drive"
    if isinstance(exc, AxisError):
        return f"lost connection to the controller ({exc}). Check the network cable"
    if isinstance(exc, InstrumentError):
        return f"lost connection to the interferometer ({exc}). Check its cable"
    return f"{type(exc).__name__}: {exc}"


class Dashboard(Observer):
    """The campaign on screen. `on_fault`: "ask" (a prompt through `keys`); the fixed answer "retry"
    (at most campaign.fault_retries times per point, then abort), "skip" or "abort"; or None (the
    config's own policy, [campaign] on_fault). `hw`: the hardware the campaign runs on."""

    def __init__(self, console: Console, config, plan: Plan, control: Control, on_fault: str | None,
                 hw=None, keys: Keys | None = None):
        self.console, self.plan, self.control, self.on_fault, self.keys = console, plan, control, on_fault, keys
        self.hw, self.tick_s = hw, 1.0 / config["instrument"]["rate_hz"]
        self.max_retries, self.retries = config["campaign"]["fault_retries"], {}
        self.unit = config["axis"]["unit"]
        self.dev_unit = "µm" if self.unit == "mm" else "arcsec"
        self.scale = DEVIATION_SCALE[self.unit]
        self.runs = config["plan"]["cycles"]
        self.state = "starting"
        self.abort_reason: str | None = None
        self.prompt: str | None = None
        self.warnings: deque[str] = deque(maxlen=4)
        self.next_point, self.measured, self.skipped, self.t_s = 0, 0, 0, 0.0
        self.live_text = "no reading yet"
        self.deviations: dict[int, list[list[float]]] = {d: [[] for _ in plan.targets] for d in (1, -1)}
        self.progress = Progress(TextColumn("{task.description:<12}"), BarColumn(bar_width=50),
                                 MofNCompleteColumn(), TextColumn("points  ETA"), TimeRemainingColumn())
        self.overall = self.progress.add_task("campaign", total=len(plan.points))
        self.run_task = self.progress.add_task(f"run 1 of {self.runs}", total=len(plan.points) // self.runs)
        self.live = Live(self, console=console, refresh_per_second=4) if console.is_terminal else None

    def __enter__(self) -> Self:
        if self.live is not None:
            self.live.start()
        return self

    def __exit__(self, *exc) -> None:
        if self.live is not None:
            self.live.stop()

    # -- what the operator sees ------------------------------------------------------------------

    def __rich__(self) -> Group:
        parts = [self.progress, self._status(), self._chart()]
        if self.warnings:
            parts.append("\n".join(f"[yellow]warning:[/] {w}" for w in self.warnings))
        if self.prompt:
            parts.append(Panel(self.prompt, title="FAULT", border_style="bold red"))
        else:
            parts.append(f"[dim]{KEY_HELP}[/]")
        return Group(*parts)

    def _status(self) -> Table:
        grid = Table.grid(padding=(0, 2))
        grid.add_column(style="bold")
        grid.add_column()
        colour = {"RUNNING": "green", "PAUSED": "yellow", "FAULT": "red", "ABORTING": "red"}
        grid.add_row("state", f"[bold {colour.get(self.state, 'white')}]{self.state}[/]")
        if self.next_point < len(self.plan.points):
            p = self.plan.points[self.next_point]
            arrow = "+ (up ↑)" if p.direction > 0 else "- (down ↓)"
            grid.add_row("point", f"{p.index} (from 0, as in points.csv), run {p.run} of {self.runs}, "
                                  f"target {p.target:.3f} {self.unit}, direction {arrow}")
        grid.add_row("live", self.live_text)
        skipped = f", skipped: {self.skipped} point{'s' if self.skipped > 1 else ''}" if self.skipped else ""
        grid.add_row("time", f"{self.t_s:.1f} s of campaign time{skipped}")
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
        lo, hi = (min(known), max(known)) if known else (0.0, 0.0)
        for direction, label in ((1, "↑ +"), (-1, "↓ -")):
            grid.add_row(f"  {label}", sparkline(means[direction], lo, hi, width))
        return grid

    def say(self, message: str, warning: bool = True) -> None:
        """A warning on the dashboard (one line in a script)."""
        if warning:
            self.warnings.append(message)
        if self.live is None or not self.live.is_started:
            self.console.print(f"[yellow]{'warning: ' if warning else ''}[/]{message}")

    # -- keys -----------------------------------------------------------------------------------

    def on_key(self, key: str) -> None:
        if key == "p" and self.state == "RUNNING":
            self.control.request_pause()
            self.state = "PAUSE REQUESTED"
            self.say("pause requested: the axis stops after this point", warning=False)
        elif key == "r" and self.control.pause_requested():
            self.control.request_resume()
            if self.state == "PAUSE REQUESTED":
                self.state = "RUNNING"
        elif key == "a" and not self.control.abort_requested():
            self.abort("a pressed")

    def abort(self, why: str) -> None:
        self.abort_reason = f"aborted by the operator ({why})"
        self.control.request_abort(self.abort_reason)
        self.state = "ABORTING"
        self.say(f"{why}: aborting, the axis halts and the recording is flushed")

    # -- Observer (a display sink of the event stream) -------------------------------------------------------------------------------

    def started(self, plan: Plan, todo: list[int]) -> None:
        self.state = "RUNNING" if not self.control.abort_requested() else self.state

    def reading(self, t_s, reading, target) -> None:
        self.t_s = t_s
        text = f"reading {reading.position:.4f} {self.unit}"
        if target is not None:
            deviation = (reading.position - target) * self.scale
            text += (f", deviation {deviation:+.2f} {self.dev_unit}" if abs(deviation) <= LIVE_DEVIATION_BAND
                     else f", {target - reading.position:+.3f} {self.unit} to the target")
        if reading.signal_pct is not None:
            text += f", signal {reading.signal_pct:.0f} %"
        self.live_text = text + ("" if reading.signal_ok else " [bold red]BEAM LOST[/]")

    def point_done(self, point, deviation) -> None:
        self.deviations[point.direction][point.target_index].append(deviation)
        self.measured += 1
        self.next_point = point.index + 1
        self._advance(point)

    def _advance(self, point) -> None:
        per_run = len(self.plan.points) // self.runs
        self.progress.update(self.overall, completed=self.measured + self.skipped)
        in_run = sum(1 for p in self.plan.points[:point.index + 1] if p.run == point.run)
        self.progress.update(self.run_task, description=f"run {point.run} of {self.runs}", completed=in_run)
        if self.live is None and in_run == per_run:
            self.console.print(f"run {point.run} of {self.runs} done at {self.t_s:.1f} s of campaign time "
                               f"({self.measured} points measured)")

    def emit(self, event: Event) -> None:
        kind = event.kind
        if kind == "point":
            self.point_done(self.plan.points[event.point], event.data["deviation"])
        elif kind == "pause":
            self.state = "PAUSED"
            self.say("PAUSED: press r to resume, a to abort", warning=False)
        elif kind == "unpause":
            self.state = "RUNNING"
            self.say("resumed", warning=False)
        elif kind not in QUIET_KINDS or (kind == "halt" and not event.data.get("ok")):
            self.say(f"{kind}: {event.message}")

    def fault(self, exc: Exception, point: int) -> str | None:
        text = f"point {point}: {describe_fault(exc)}. The axis is halted."
        state, self.state = self.state, "FAULT"
        self.say(text)
        decision = self._decide(text, point)
        self.say(f"fault at point {point}: {decision or 'as the config says ([campaign] on_fault)'}",
                 warning=False)
        if decision == "skip":
            self.skipped += 1
            self.next_point = point + 1
            self._advance(self.plan.points[point])
        self.state = state if decision != "abort" else "ABORTING"
        return decision

    def _decide(self, text: str, point: int) -> str | None:
        if self.on_fault == "ask" and self.keys is not None:
            self.prompt = f"{text}\nPress r to retry the point, s to skip it, a to abort."
            try:
                return self.keys.ask({"r": "retry", "s": "skip", "a": "abort"}, self.control)
            finally:
                self.prompt = None
        if self.on_fault == "retry":
            self.retries[point] = self.retries.get(point, 0) + 1
            return "retry" if self.retries[point] <= self.max_retries else "abort"
        return self.on_fault

"""Rich progress for a running campaign: overall and per-run bars and the live reading (stderr)."""

from __future__ import annotations

from typing import Self

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeRemainingColumn
from rich.table import Column

from campaign.measure.executor import Observer
from campaign.measure.live import live_text
from campaign.plan import Plan
from campaign.record import Event
from protocols.hardware import Reading

FIXED_WIDTH = 40
"""Characters the progress line's other columns take (description 10, bar 10, counts 9, time left 7,
a space after each): the live text gets the rest of the terminal's width."""


def fit(text: str, width: int) -> str:
    """The live text within `width` characters, its trailing ", "-separated parts dropped whole (a
    value is never cut in the middle); the first part alone when nothing else fits."""
    parts = text.split(", ")
    while len(parts) > 1 and len(", ".join(parts)) > width:
        parts.pop()
    return ", ".join(parts)


class RichProgress(Observer):
    """Shows the campaign on stderr; use as a context manager around the run."""

    def __init__(self, unit: str = "mm"):
        """`unit`: the axis unit, mm or deg; the live reading as campaign.measure.live shows it."""
        self.console = Console(stderr=True)
        # numbers never cut (no_wrap, a minimum width each); on a narrow terminal the bar and then
        # the live text give way, the live text cut at its end with an ellipsis
        self.progress = Progress(TextColumn("{task.description}", table_column=Column(no_wrap=True, min_width=10)),
                                 BarColumn(bar_width=10),
                                 MofNCompleteColumn(table_column=Column(no_wrap=True, min_width=9)),
                                 TimeRemainingColumn(table_column=Column(no_wrap=True, min_width=7)),
                                 TextColumn("{task.fields[live]}",
                                            table_column=Column(no_wrap=True, overflow="ellipsis", ratio=1)),
                                 console=self.console, transient=False)
        self.unit = unit
        self.overall: TaskID | None = None
        self.run_task: TaskID | None = None
        self.per_run = 0
        self.run_word = "run"
        self._last_reading_t = -1.0
        self._latest: tuple[float, Reading, float | None] | None = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.overall is not None:
            if self._latest is not None:  # the last reading, which the throttle may have held back
                self._show(*self._latest)
            self.progress.stop()

    def started(self, plan: Plan, todo: list[int]) -> None:
        self.progress.start()
        self.points = plan.points
        self.runs = max(p.run for p in self.points)
        self.per_run = len(self.points) // self.runs
        self.done = {p.index for p in self.points} - set(todo)
        run = self.points[todo[0]].run if todo else self.runs
        # a scan's points are its sweeps, two per pass: the bars count them as such
        self.run_word = "pass" if plan.sweeps else "run"
        self.overall = self.progress.add_task("sweeps" if plan.sweeps else "campaign", total=len(self.points),
                                              completed=len(self.done), live="")
        self.run_task = self.progress.add_task(f"{self.run_word} {run}/{self.runs}", total=self.per_run,
                                               completed=self._done_in(run), live="")

    def _done_in(self, run: int) -> int:
        return sum(1 for i in self.done if self.points[i].run == run)

    def reading(self, t_s: float, reading: Reading, target: float | None) -> None:
        self._latest = (t_s, reading, target)
        if t_s - self._last_reading_t < 0.5:
            return
        self._show(t_s, reading, target)

    def _show(self, t_s: float, reading: Reading, target: float | None) -> None:
        if self.overall is None or self.run_task is None:
            return
        self._last_reading_t = t_s
        self._latest = None
        text = fit(live_text(reading, target, self.unit), self.console.width - FIXED_WIDTH)
        self.progress.update(self.overall, live=f"t={t_s:7.1f} s")
        self.progress.update(self.run_task, live=text)

    def emit(self, event: Event) -> None:
        if event.kind in ("point", "sweep") and event.point is not None and self.overall is not None \
                and self.run_task is not None:
            run = event.data["run"]
            self.done.add(event.point)
            self.progress.update(self.overall, completed=len(self.done))
            self.progress.update(self.run_task, description=f"{self.run_word} {run}/{self.runs}",
                                 completed=self._done_in(run))
        elif event.kind not in ("start", "stop", "state"):  # the run states: the bars show the work
            self.console.print(f"[yellow]{event.kind}:[/] {event.message}")

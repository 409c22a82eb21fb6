"""Rich progress for a running campaign: overall and per-run bars and the live reading (stderr)."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from campaign.measure.executor import Observer
from campaign.plan import Plan
from campaign.record.events import Event
from protocols.units import DEVIATION_SCALE


class RichProgress(Observer):
    """Shows the campaign on stderr; use as a context manager around the run."""

    def __init__(self, unit: str = "mm"):
        """`unit`: the axis unit, mm or deg; the live deviation is shown in µm or arcsec."""
        self.console = Console(stderr=True)
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TimeRemainingColumn(), TextColumn("{task.fields[live]}"),
                                 console=self.console, transient=False)
        self.unit, self.scale = unit, DEVIATION_SCALE[unit]
        self.dev_unit = "µm" if unit == "mm" else "arcsec"
        self.overall = self.run_task = None
        self.per_run = 0
        self._last_reading_t = -1.0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.overall is not None:
            self.progress.stop()

    def started(self, plan: Plan, first_point: int) -> None:
        self.progress.start()
        points = plan.points
        runs = max(p.run for p in points)
        self.per_run = len(points) // runs
        done_in_run = first_point % self.per_run
        run = points[first_point].run if first_point < len(points) else runs
        self.overall = self.progress.add_task("campaign", total=len(points), completed=first_point, live="")
        self.run_task = self.progress.add_task(f"run {run}/{runs}", total=self.per_run,
                                               completed=done_in_run, live="")
        self.runs = runs

    def reading(self, t_s, reading, target) -> None:
        if t_s - self._last_reading_t < 0.5 or self.overall is None:
            return
        self._last_reading_t = t_s
        text = f"{reading.position:10.4f} {self.unit}"
        if target is not None:
            text += f"  dev {(reading.position - target) * self.scale:+8.2f} {self.dev_unit}"
        if not reading.signal_ok:
            text += "  [red]BEAM LOST[/]"
        self.progress.update(self.overall, live=f"t={t_s:7.1f} s")
        self.progress.update(self.run_task, live=text)

    def emit(self, event: Event) -> None:
        if event.kind == "point":
            run = event.data["run"]
            self.progress.advance(self.overall)
            done = event.point + 1 - (run - 1) * self.per_run
            self.progress.update(self.run_task, description=f"run {run}/{self.runs}", completed=done)
        elif event.kind not in ("start", "stop"):
            self.console.print(f"[yellow]{event.kind}:[/] {event.message}")

"""Rich renderings shared by the commands: the ISO 230-2 per-target table and axis summary."""

from __future__ import annotations

import json
import sys

from rich.console import Console
from rich.table import Table

from campaign.iso230 import Evaluation

SUMMARY_ROWS = (
    ("A", "accuracy, bidirectional"), ("A_up", "accuracy, + direction"), ("A_down", "accuracy, - direction"),
    ("E", "systematic deviation, bidirectional"), ("E_up", "systematic deviation, +"),
    ("E_down", "systematic deviation, -"), ("M", "mean bidirectional deviation range"),
    ("B", "reversal value (max |B_i|)"), ("B_mean", "mean reversal value"),
    ("R", "repeatability, bidirectional"), ("R_up", "repeatability, +"), ("R_down", "repeatability, -"),
    ("Pa", "VDI 3441 position deviation"), ("Ps_max", "VDI 3441 max position scatter"),
    ("U_max", "VDI 3441 max reversal span"), ("P", "VDI 3441 position uncertainty"),
)


def fmt(value: float | None, digits: int = 3) -> str:
    """A number to `digits` decimals, or 'n/a' when it is unavailable."""
    return "n/a" if value is None else f"{value:.{digits}f}"


def target_table(ev: Evaluation) -> Table:
    u = ev.unit
    table = Table(title=f"Per target ({ev.standard.title})", header_style="bold")
    for head in (f"target {ev.position_unit}", "n+", "n-", f"x̄↑ {u}", f"x̄↓ {u}", f"s↑ {u}", f"s↓ {u}",
                 f"B_i {u}", f"R↑_i {u}", f"R↓_i {u}", f"R_i {u}", f"x̄_i {u}"):
        table.add_column(head, justify="right")
    for t in ev.targets:
        table.add_row(f"{t.target:g}", str(t.n_up), str(t.n_down), fmt(t.mean_up), fmt(t.mean_down),
                      fmt(t.s_up), fmt(t.s_down), fmt(t.B), fmt(t.R_up), fmt(t.R_down), fmt(t.R), fmt(t.mean))
    return table


def summary_table(ev: Evaluation, title: str | None = None) -> Table:
    table = Table(title=title or f"Axis summary ({ev.standard.title}, {ev.runs} runs)", header_style="bold")
    table.add_column("parameter")
    table.add_column("meaning")
    table.add_column(f"value ({ev.unit})", justify="right")
    for key, meaning in SUMMARY_ROWS:
        if key in ev.summary:
            table.add_row(key, meaning, fmt(ev.summary[key]))
    return table


def make_console() -> Console:
    """A rich console; wide enough for the per-target table when stdout is not a terminal."""
    return Console() if sys.stdout.isatty() else Console(width=160)


def print_evaluation(ev: Evaluation, console: Console | None = None, per_target: bool = True) -> None:
    console = console or make_console()
    if per_target:
        console.print(target_table(ev))
    console.print(summary_table(ev))
    for warning in ev.warnings:
        console.print(f"[yellow]warning:[/] {warning}")


def print_json(obj: dict) -> None:
    """One JSON object on stdout (NaN never appears: unavailable values are null)."""
    json.dump(obj, sys.stdout, indent=1, allow_nan=False)
    sys.stdout.write("\n")

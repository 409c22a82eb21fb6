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


def unit_label(unit: str) -> str:
    """A deviation unit as people read it: µm or arcsec."""
    return {"um": "µm"}.get(unit, unit)


def verdict_line(verdict) -> str:
    """The verdict in one coloured word with its reasons (rich markup)."""
    colour = {"pass": "bold green", "fail": "bold red"}.get(verdict.verdict, "bold yellow")
    return f"[{colour}]{verdict.word}[/]: " + "; ".join(verdict.reasons)


def budget_table(budget) -> Table:
    """The uncertainty budget: each term's standard uncertainty and source, then U (k = 2)."""
    unit = unit_label(budget.unit)
    table = Table(title=f"Measurement uncertainty (k = {budget.k:g})", header_style="bold")
    table.add_column("term")
    table.add_column(f"u {unit}", justify="right")
    table.add_column("for")
    table.add_column("input")
    for term in budget.terms:
        table.add_row(term.name, f"{term.u:.3f}", " ".join(term.applies), term.source)
    for key, value in budget.expanded.items():
        table.add_row(f"[bold]U({key})[/]", f"[bold]{value:.3f}[/]", key, "expanded, k = 2")
    return table


def outlier_lines(outliers, unit: str) -> list[str]:
    """One line per outlier, and what it does to the scatter (empty when there is none)."""
    u = unit_label(unit)
    if not outliers.found:
        return []
    lines = [(f"{len(outliers.found)} outlier(s) (studentised residual against the pooled scatter, "
              f"{100 * outliers.alpha:g} % for the campaign; they stay in the result):")]
    for o in outliers.found:
        lines.append(f"  run {o.run}, direction {'+' if o.direction > 0 else '-'}, target {o.target:g}: "
                     f"deviation {o.deviation:+.3f} {u}, score {o.score:.1f} > {o.critical:.1f}")
    lines.append(f"  pooled scatter s = {outliers.s_with:.3f} {u} with them, {outliers.s_without:.3f} {u} without")
    return lines


def print_assessment(a, console: Console, per_target: bool = True) -> None:
    """Evaluation, outliers, uncertainty and verdict of an Assessment (campaign/assess.py)."""
    print_evaluation(a.evaluation, console, per_target)
    for line in outlier_lines(a.outliers, a.evaluation.unit):
        console.print(f"[yellow]{line}[/]" if line.endswith(":") else line)
    if per_target:
        console.print(budget_table(a.uncertainty))
    console.print(verdict_line(a.verdict))
    for note in a.verdict.notes:
        console.print(f"note: {note}")
    console.print(f"[dim]decision rule: {a.verdict.rule}[/]")


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

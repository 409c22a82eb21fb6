"""Rich renderings shared by the commands: the ISO 230-2 per-target table and axis summary, the
verdict, the uncertainty budget, the outliers.

Tables fit the console (80 columns and up): a number is never cut. The per-target table is split
in two below WIDE columns unless asked for wide; every number column folds rather than crop.
Units are printed as people read them (µm, arcsec).
"""

from __future__ import annotations

import json
import os
import sys
from typing import Protocol

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from campaign.iso230 import Evaluation
from campaign.outliers import Outliers
from campaign.uncertainty import Budget
from campaign.verdict import Verdict
from protocols.units import counted, unit_label

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


WIDE = 110
"""Console width (columns) from which the per-target table is one table."""


def number_column(table: Table, head: str) -> None:
    """A right-aligned column whose numbers are never cut (they fold onto a second line instead)."""
    table.add_column(head, justify="right", overflow="fold")


def target_tables(ev: Evaluation, wide: bool = True) -> list[Table]:
    """The per-target statistics: one table when `wide`, else two that fit 80 columns (the means
    and scatter per direction; the reversal, repeatabilities and bidirectional mean)."""
    u = unit_label(ev.unit)
    columns = [(f"target {ev.position_unit}", lambda t: f"{t.target:g}"), ("n+", lambda t: str(t.n_up)),
               ("n-", lambda t: str(t.n_down)), (f"x̄↑ {u}", lambda t: fmt(t.mean_up)),
               (f"x̄↓ {u}", lambda t: fmt(t.mean_down)), (f"s↑ {u}", lambda t: fmt(t.s_up)),
               (f"s↓ {u}", lambda t: fmt(t.s_down)), (f"B_i {u}", lambda t: fmt(t.B)),
               (f"R↑_i {u}", lambda t: fmt(t.R_up)), (f"R↓_i {u}", lambda t: fmt(t.R_down)),
               (f"R_i {u}", lambda t: fmt(t.R)), (f"x̄_i {u}", lambda t: fmt(t.mean))]
    groups = [columns] if wide else [columns[:7], columns[:1] + columns[7:]]
    titles = [f"Per target ({ev.standard.title})"] if wide else \
        [f"Per target ({ev.standard.title}): means and scatter", "Per target: reversal, repeatability, mean"]
    tables = []
    for title, group in zip(titles, groups):
        table = Table(title=title, header_style="bold")
        for head, _ in group:
            number_column(table, head)
        for t in ev.targets:
            table.add_row(*(cell(t) for _, cell in group))
        tables.append(table)
    return tables


def target_table(ev: Evaluation) -> Table:
    """The per-target statistics in one table."""
    return target_tables(ev)[0]


def summary_table(ev: Evaluation, title: str | None = None) -> Table:
    table = Table(title=title or f"Axis summary ({ev.standard.title}, {counted(ev.runs, 'run')})", header_style="bold")
    table.add_column("parameter")
    table.add_column("meaning")
    number_column(table, f"value ({unit_label(ev.unit)})")
    for key, meaning in SUMMARY_ROWS:
        if key in ev.summary:
            table.add_row(key, meaning, fmt(ev.summary[key]))
    return table


def verdict_line(verdict: Verdict) -> str:
    """The verdict in one coloured word with its reasons (rich markup)."""
    colour = {"pass": "bold green", "fail": "bold red"}.get(verdict.verdict, "bold yellow")
    return f"[{colour}]{verdict.word}[/]: " + escape("; ".join(verdict.reasons))


def budget_table(budget: Budget) -> Table:
    """The uncertainty budget: each term's standard uncertainty and source, then U (k = 2)."""
    unit = unit_label(budget.unit)
    table = Table(title=f"Measurement uncertainty (k = {budget.k:g})", header_style="bold")
    table.add_column("term", overflow="fold")
    number_column(table, f"u {unit}")
    table.add_column("for", overflow="fold")
    table.add_column("input", overflow="fold")
    for term in budget.terms:
        table.add_row(term.name, f"{term.u:.3f}", " ".join(term.applies), term.source)
    for key, value in budget.expanded.items():
        table.add_row(f"[bold]U({key})[/]", f"[bold]{value:.3f}[/]", key, "expanded, k = 2")
    return table


def outlier_lines(outliers: Outliers, unit: str) -> list[str]:
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


class Assessed(Protocol):
    """What the console shows of an Assessment (campaign/assess.py, a room above this one)."""

    @property
    def evaluation(self) -> Evaluation: ...
    @property
    def outliers(self) -> Outliers: ...
    @property
    def uncertainty(self) -> Budget: ...
    @property
    def verdict(self) -> Verdict: ...


def print_assessment(a: Assessed, console: Console, per_target: bool = True, wide: bool = False) -> None:
    """Evaluation, outliers, uncertainty and verdict of an Assessment (campaign/assess.py)."""
    print_evaluation(a.evaluation, console, per_target, wide)
    for line in outlier_lines(a.outliers, a.evaluation.unit):
        console.print(f"[yellow]{line}[/]" if line.endswith(":") else line)
    if per_target:
        console.print(budget_table(a.uncertainty))
    console.print(verdict_line(a.verdict))
    for note in a.verdict.notes:
        console.print(f"note: {note}")
    console.print(f"[dim]decision rule: {a.verdict.rule}[/]")


def make_console(stderr: bool = False) -> Console:
    """A rich console on stdout (stderr with `stderr`, when stdout carries JSON): the terminal's
    width, or COLUMNS when set. When the stream is not a terminal (a file or a pipe), tables are laid
    out for 120 columns and a line of text is never wrapped: a file path in it may be any length,
    and a line that is read by grep or a program stays one line."""
    stream = sys.stderr if stderr else sys.stdout
    if stream.isatty() or os.environ.get("COLUMNS"):
        return Console(stderr=stderr)
    return Console(width=120, stderr=stderr, soft_wrap=True)


def print_evaluation(ev: Evaluation, console: Console | None = None, per_target: bool = True,
                     wide: bool = False) -> None:
    """The per-target table(s) (one when the console is WIDE or `wide`) and the axis summary."""
    console = console or make_console()
    if per_target:
        for table in target_tables(ev, wide or console.width >= WIDE):
            console.print(table)
    console.print(summary_table(ev))
    for warning in ev.warnings:
        console.print(f"[yellow]warning:[/] {warning}")


def print_json(obj: dict) -> None:
    """One JSON object on stdout (NaN never appears: unavailable values are null)."""
    json.dump(obj, sys.stdout, indent=1, allow_nan=False)
    sys.stdout.write("\n")

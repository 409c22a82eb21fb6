"""Plots people would rather look at than read. matplotlib with the Agg backend (no screen)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from campaign.errors import InputError
from campaign.iso230 import Evaluation
from campaign.pointtable import PointTable
from protocols.units import unit_label

FORMATS = (".png", ".svg")
DIRECTION_STYLE = {1: ("+ (forward)", "tab:blue"), -1: ("- (reverse)", "tab:red")}


def pyplot() -> Any:
    """matplotlib.pyplot with the Agg backend (no screen), imported when a plot is drawn: it is the
    slowest import of axiscal, and most commands draw nothing."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def check_plot_path(path: str | Path) -> Path:
    """The plot path, if its extension is one we write (PNG or SVG) and it can be a file: not a directory,
    and under no file (checked before a campaign runs, so that its end is not lost to the plot; a folder
    that does not exist yet, such as the campaign's own, is made when the plot is written); InputError
    otherwise."""
    out = Path(path)
    if out.suffix.lower() not in FORMATS:
        raise InputError(f"--plot: {path}: unsupported plot format '{out.suffix}' (use .png or .svg)")
    if out.is_dir():
        raise InputError(f"--plot: {path}: is a directory, not a plot file")
    existing = next((p for p in out.parents if p.exists()), None)
    if existing is not None and not existing.is_dir():
        raise InputError(f"--plot: {path}: {existing} is a file, not a directory to write it in")
    return out


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def draw_evaluation(ax: Any, table: PointTable, ev: Evaluation, label: str = "") -> None:
    """Draw the usual laser-software plot on `ax`: per direction the mean deviation with a ±ks
    band and each run's points."""
    k = ev.standard.k
    targets = np.array([t.target for t in ev.targets])
    for direction, (name, colour) in DIRECTION_STYLE.items():
        suffix = "up" if direction > 0 else "down"
        known = [getattr(t, f"mean_{suffix}") for t in ev.targets]
        if any(m is None for m in known):
            continue
        sds = np.array([getattr(t, f"s_{suffix}") or 0.0 for t in ev.targets])
        means = np.array(known, dtype=float)
        ax.plot(targets, means, "-", color=colour, lw=1.8, label=f"mean {name}")
        ax.fill_between(targets, means - k * sds, means + k * sds, color=colour, alpha=0.15,
                        label=f"±{k:g}s {name}")
        pick = table.direction == direction
        ax.plot(table.target[pick], table.deviation[pick], ".", color=colour, ms=4, alpha=0.6)
    s = ev.summary
    ax.set_title(f"{label}A = {_fmt(s['A'] if s['A'] is not None else s['A_up'] or s['A_down'])}  "
                 f"E = {_fmt(s['E'])}  B = {_fmt(s['B'])}  R = {_fmt(s['R'])} {unit_label(ev.unit)}", fontsize=10)
    ax.set_xlabel(f"target ({ev.position_unit})")
    ax.set_ylabel(f"deviation ({unit_label(ev.unit)})")
    ax.axhline(0, color="grey", lw=0.6)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")


def plot_evaluation(table: PointTable, ev: Evaluation, out: str | Path, title: str = "") -> Path:
    """Write the evaluation plot to `out` (.png or .svg). Returns the path written."""
    path = check_plot_path(out)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 5.5))
    draw_evaluation(ax, table, ev)
    fig.suptitle(title or f"{ev.standard.title}: {Path(table.source).name}", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

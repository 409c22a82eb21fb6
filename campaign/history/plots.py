"""The history's plots (matplotlib, Agg): the trend of an axis, and two campaigns compared."""

from __future__ import annotations

import datetime as dt
import itertools
from pathlib import Path
from typing import Any

import numpy as np

from campaign.history.axis import TRENDED, AxisTrend
from campaign.history.compare import Comparison
from campaign.history.trend import YEAR_S
from campaign.plot import check_plot_path, pyplot
from protocols.units import unit_label

NAMES = {"A": "accuracy A", "E": "systematic deviation E", "B": "reversal B", "R": "repeatability R"}


def draw_trend(trend: AxisTrend) -> Any:
    """The trend figure: A, E, B, R over time with their U as error bars, the fitted drift (each
    segment between jumps), the tolerance and the predicted crossing on A."""
    plt = pyplot()
    unit = unit_label(trend.unit)
    fig, axes = plt.subplots(2, 2, figsize=(12, 7.5))
    for ax, parameter in zip(axes.flat, TRENDED):
        fit = trend.fits.get(parameter)
        obs = fit.observations if fit else []
        ax.set_title(f"{NAMES[parameter]} ({unit})", fontsize=10)
        ax.grid(True, alpha=0.3)
        if not obs:
            ax.text(0.5, 0.5, "no campaign with a value and its U", ha="center", transform=ax.transAxes)
            continue
        ax.errorbar([o.when for o in obs], [o.value for o in obs], yerr=[o.U for o in obs], fmt="o", ms=4,
                    capsize=3, color="tab:blue", label="campaign, ±U (k = 2)")
        if fit is not None and fit.rate is not None:
            bounds = [0, *fit.step_at, len(obs)]
            for start, stop in itertools.pairwise(bounds):
                when = [obs[start].when, obs[stop - 1].when]
                tau = np.array([fit.years(w) for w in when])
                ax.plot(when, fit.fitted(tau, start), "-", color="tab:orange", lw=1.5,
                        label=f"drift {fit.rate:+.2f} ± {fit.U_rate:.2f} {unit}/year" if start == 0 else None)
        for jump in trend.jumps:
            if jump.parameter == parameter:
                middle = jump.before.when + (jump.after.when - jump.before.when) / 2
                ax.axvline(middle, color="tab:red", ls=":", lw=1)
                ax.annotate(f" jump {jump.jump:+.1f} ± {jump.U:.1f}", (middle, (jump.before.value + jump.after.value) / 2),
                            fontsize=8, color="tab:red", ha="left", va="center")
        if parameter == "A":
            _draw_crossing(ax, trend, unit)
        ax.legend(fontsize=8, loc="upper left")
    for ax in axes.flat:
        ax.tick_params(axis="x", labelrotation=30)
    fig.suptitle(f"History of machine {trend.machine}, axis {trend.axis}: {len(trend.counted)} campaigns", fontsize=12)
    fig.tight_layout()
    return fig


def _draw_crossing(ax: Any, trend: AxisTrend, unit: str) -> None:
    fit, c = trend.fits["A"], trend.crossing
    if trend.tolerance:
        ax.axhline(trend.tolerance, color="tab:red", lw=1.2, label=f"tolerance {trend.tolerance:g} {unit}")
    if fit.rate is None or c is None or c.state != "predicted" or c.date is None or c.U_assumed is None:
        return
    end = c.latest or c.date + (c.date - fit.last.when)
    span = np.linspace(0.0, (end - fit.last.when).total_seconds() / YEAR_S, 60)
    when = [fit.last.when + dt.timedelta(seconds=float(t) * YEAR_S) for t in span]
    predicted = np.array([fit.predict(float(t)) for t in span])
    ax.plot(when, predicted[:, 0] + c.U_assumed, "--", color="tab:purple", lw=1.2, label="predicted A + U")
    ax.fill_between(when, predicted[:, 0] - fit.k * predicted[:, 1] + c.U_assumed,
                    predicted[:, 0] + fit.k * predicted[:, 1] + c.U_assumed, color="tab:purple", alpha=0.15)
    ax.axvline(c.date, color="tab:purple", lw=1)
    ax.annotate(f"crossing {c.date.date().isoformat()}", (c.date, trend.tolerance or 0.0), fontsize=8,
                color="tab:purple", ha="right", va="bottom")


def save(fig: Any, out: str | Path) -> Path:
    path = check_plot_path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    pyplot().close(fig)
    return path


def draw_compare(c: Comparison) -> Any:
    """Two campaigns' mean deviation curves (each direction, thin; both, thick) and their
    difference with U."""
    plt = pyplot()
    unit = unit_label(c.unit)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 7), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    for row, ev, colour in ((c.first, c.evaluations[0], "tab:blue"), (c.second, c.evaluations[1], "tab:red")):
        when = "undated" if row["measured_utc"] is None else row["measured_utc"].date().isoformat()
        targets = [t.target for t in ev.targets]
        for suffix, style in (("up", ":"), ("down", "--")):
            means = [getattr(t, f"mean_{suffix}") for t in ev.targets]
            if all(m is not None for m in means):
                top.plot(targets, means, style, color=colour, lw=0.9, alpha=0.7)
        both = [t.mean if t.mean is not None else (t.mean_up if t.mean_up is not None else t.mean_down)
                for t in ev.targets]
        top.plot(targets, both, "-o", color=colour, ms=3, lw=1.8, label=f"{row['label']} ({when})")
    top.set_ylabel(f"mean deviation ({unit})")
    top.set_title("mean deviation per target (dotted ↑, dashed ↓, solid: both)", fontsize=10)
    top.grid(True, alpha=0.3)
    top.legend(fontsize=8)
    rows = [r for r in c.rows if r["U"] is not None]
    bottom.errorbar([r["target"] for r in rows], [r["difference"] for r in rows], yerr=[r["U"] for r in rows],
                    fmt="o-", ms=4, capsize=3, color="tab:green", label="second − first, ±U (k = 2)")
    bottom.axhline(0, color="grey", lw=0.8)
    bottom.set_xlabel(f"target ({c.position_unit})")
    bottom.set_ylabel(f"difference ({unit})")
    bottom.grid(True, alpha=0.3)
    bottom.legend(fontsize=8)
    fig.tight_layout()
    return fig

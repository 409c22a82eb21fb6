"""The HTML report a technician hands to quality: one self-contained file (CSS inline, plots as
base64 PNG, nothing fetched), readable offline and printable.

It shows the campaign (machine, axis, operator, date), the environment (from points.csv), the
plan, the ISO 230-2 summary and per-target table with units, the plot, pass or fail against
`[campaign] tolerance` (on A), and, when a baseline campaign is given, before and after side by side.
"""

from __future__ import annotations

import base64
import io
import json
from dataclasses import dataclass, replace
from html import escape
from pathlib import Path

from campaign.config import Config, load_config
from campaign.errors import InputError
from campaign.iso230 import Evaluation, evaluate
from campaign.plot import draw_evaluation, pyplot
from campaign.pointtable import PointTable, read_points
from campaign.record.directory import RUNS_FILE, CampaignDir, read_json_lines
from campaign.report.html import (
    comparison_table,
    environment_table,
    facts_table,
    key_figures,
    page,
    section,
    summary_table,
    target_table,
    unit_label,
    verdict_box,
)


@dataclass
class Campaign:
    """A recorded campaign directory, read and evaluated. `config` is None without config.toml."""

    directory: Path
    meta: dict
    config: Config | None
    table: PointTable
    evaluation: Evaluation


def load_campaign(directory: str | Path) -> Campaign:
    """Read DIR/meta.json, DIR/points.csv and DIR/config.toml; InputError if it is no campaign."""
    path = Path(directory)
    if not path.is_dir():
        raise InputError(f"{path}: not a campaign directory (no such directory)")
    for name in ("meta.json", "points.csv"):
        if not (path / name).is_file():
            raise InputError(f"{path}: not a campaign directory (no {name})")
    try:
        meta = json.loads((path / "meta.json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        reason = " ".join(str(exc).split())[:80]
        raise InputError(f"{path / 'meta.json'}: not valid JSON ({reason})") from None
    if not isinstance(meta, dict):
        raise InputError(f"{path / 'meta.json'}: not a JSON object")
    config = load_config(path / "config.toml") if (path / "config.toml").is_file() else None
    table = read_points(path / "points.csv")
    recorded = CampaignDir(path, meta, read_json_lines(path / RUNS_FILE))  # status from the run records
    meta = {**meta, "status": recorded.status, "duration_s": recorded.duration_s}
    return Campaign(path, meta, config, table, evaluate(table))


def baseline_of(campaign: Campaign) -> Path | None:
    """meta.json's `baseline_dir` (absolute, or relative to the campaign directory), if set."""
    value = campaign.meta.get("baseline_dir")
    if not value:
        return None
    path = Path(str(value))
    beside = campaign.directory / path
    return beside if not path.is_absolute() and beside.exists() else path


def accuracy(ev: Evaluation) -> tuple[str, float | None]:
    """The accuracy the tolerance applies to: A, or the worse one-direction A when A is unavailable."""
    s = ev.summary
    if s.get("A") is not None:
        return "A", s["A"]
    one_way = [(k, s[k]) for k in ("A_up", "A_down") if s.get(k) is not None]
    return max(one_way, key=lambda kv: kv[1]) if one_way else ("A", None)


def tolerance_of(campaign: Campaign) -> float | None:
    """`[campaign] tolerance` (deviation unit), or None when it is not set (0)."""
    if campaign.config is None or not campaign.config["campaign"]["tolerance"]:
        return None
    return float(campaign.config["campaign"]["tolerance"])


def plot_png(campaigns: list[tuple[str, Campaign]]) -> str:
    """The deviation plot(s) side by side (same deviation scale), as a base64 PNG data URI."""
    size = (10.0, 4.8) if len(campaigns) == 1 else (6.4 * len(campaigns), 4.6)  # inches
    plt = pyplot()
    fig, axes = plt.subplots(1, len(campaigns), figsize=size, sharey=True, squeeze=False)
    for ax, (label, c) in zip(axes[0], campaigns):
        printable = replace(c.evaluation, unit=unit_label(c.evaluation.unit))  # µm, not um
        draw_evaluation(ax, c.table, printable, f"{label}: " if label else "")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _date(c: Campaign) -> str:
    return str(c.meta.get("created", c.meta.get("start_time", "date unknown"))).replace("T", " ").replace("+00:00", " UTC")


def _campaign_facts(c: Campaign) -> list[tuple[str, str]]:
    m = c.meta
    axis = m.get("axis", c.config["axis"]["name"] if c.config else "?")
    kind = f"{m.get('kind', c.table.kind)}, {c.table.position_unit}"
    seconds = m.get("duration_s")
    duration = f"{seconds / 60:.1f} min" if isinstance(seconds, (int, float)) else "–"
    rows = [("Machine", m.get("machine", "unknown")), ("Axis", f"{axis} ({kind})"),
            ("Operator", m.get("operator") or "not recorded"), ("Date", _date(c)),
            ("Status", f"{m.get('status', 'unknown')}, {len(c.table)} points"), ("Duration", duration),
            ("Software", m.get("software", "axiscal")), ("Campaign directory", str(c.directory))]
    if c.config and c.config["campaign"]["description"]:
        rows.insert(2, ("Description", c.config["campaign"]["description"]))
    return rows


def _plan_facts(c: Campaign) -> list[tuple[str, str]]:
    unit = c.table.position_unit
    targets = sorted({float(t) for t in c.table.target})
    listed = ", ".join(f"{t:g}" for t in targets)
    rows = [("Targets", f"{len(targets)}: {listed} {unit}"), ("Runs", str(c.evaluation.runs)),
            ("Directions", " and ".join("+" if d > 0 else "−" for d in c.table.directions))]
    if c.config:
        p, cap = c.config["plan"], c.config["capture"]
        method = (f"fixed dwell, mean of the last {cap['average_s']:g} s" if cap["method"] == "dwell" else
                  f"stability trigger, {cap['stable_tolerance']:g} {unit_label(c.evaluation.unit)} band "
                  f"for {cap['stable_window_s']:g} s")
        rows += [("Cycle", f"{p['cycle']}, overrun {p['overrun']:g} {unit}"),
                 ("Dwell", f"{p['dwell_s']:g} s"), ("Velocity", f"{p['velocity']:g} {unit}/s"),
                 ("Capture", method), ("Target offsets", p["offsets"])]
    rows.append(("Plan seed", str(c.meta.get("plan_seed", c.table.meta.get("plan_seed", "not recorded")))))
    return rows


def _comparison(before: Campaign, after: Campaign) -> str:
    plots = plot_png([(f"before ({before.directory.name})", before),
                      (f"after ({after.directory.name})", after)])
    name, value_after = accuracy(after.evaluation)
    value_before = before.evaluation.summary.get(name)
    unit = unit_label(after.evaluation.unit)
    if value_after is not None and value_before:
        lead = (f"{name} went from {value_before:.2f} {unit} to {value_after:.2f} {unit}: "
                f"{abs(1 - value_after / value_before) * 100:.0f} % "
                f"{'smaller' if value_after <= value_before else 'larger'}.")
    else:
        lead = f"{name} cannot be compared: it is unavailable in one of the campaigns."
    sources = (f"Before: {before.directory} ({_date(before)}). After: {after.directory} ({_date(after)}). "
               "Ratio = after / before; smaller is better.")
    return section("Before and after", f"<p class='lead'>{escape(lead)}</p><p>{escape(sources)}</p>"
                   + comparison_table(before.evaluation, after.evaluation)
                   + f"<img class='plot' alt='Deviation before and after' src='{plots}'>")


def render_report(campaign: Campaign, before: Campaign | None = None) -> str:
    """The whole HTML document for `campaign` (the after campaign when `before` is given)."""
    ev = campaign.evaluation
    machine, axis = campaign.meta.get("machine", "?"), campaign.meta.get("axis", "?")
    title = f"Positioning accuracy: machine {machine}, axis {axis}"
    name, value = accuracy(ev)
    parts = [verdict_box(name, value, tolerance_of(campaign), unit_label(ev.unit)), key_figures(ev),
             "<div class='columns'>" + section("Campaign", facts_table(_campaign_facts(campaign)))
             + section("Plan", facts_table(_plan_facts(campaign))) + "</div>",
             section("Environment", environment_table(campaign.table.optional))]
    if before is not None:
        parts.append(_comparison(before, campaign))
    plot = plot_png([("", campaign)])
    parts += [section(f"Result ({ev.standard.title}, {ev.runs} runs)", summary_table(ev)),
              section("Deviation plot", f"<img class='plot' alt='Deviation per target' src='{plot}'>"),
              section("Per target", target_table(ev))]
    if ev.warnings:
        items = "".join(f"<li>{escape(w)}</li>" for w in ev.warnings)
        parts.append(section("Warnings", f"<ul class='warnings'>{items}</ul>"))
    operator = campaign.meta.get("operator") or "not recorded"
    subtitle = f"{ev.standard.title}. Measured {_date(campaign)}. Operator: {operator}."
    return page(title, "".join(parts), subtitle)


def write_report(directory: str | Path, out: str | Path, before: str | Path | None = None) -> Path:
    """Read the campaign (and the baseline: `before`, else meta.json's baseline_dir), write the HTML."""
    campaign = load_campaign(directory)
    baseline = Path(before) if before else baseline_of(campaign)
    previous = load_campaign(baseline) if baseline else None
    if previous is not None and previous.table.kind != campaign.table.kind:
        raise InputError(f"{baseline}: a {previous.table.kind} axis, but {directory} is "
                         f"a {campaign.table.kind} axis")
    path = Path(out)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(render_report(campaign, previous), encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror})") from None
    return path

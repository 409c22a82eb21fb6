"""Closed-loop verification: measure again with the compensation active.

The table goes into the PLC's compensation variables over ADS (written, read back, compared, then
enabled) — on a real PLC and on the simulated one alike; the simulated PLC then applies it exactly
as FB_AxiscalCompensation does. The campaign runs as usual into a new directory whose meta.json
names the baseline. The before and after are written as tables like Li et al. 2022's tables 7–12
(`verification.md`) and as a plot (`verification.png`).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from campaign.compensation.grid import ControllerTable
from campaign.compensation.table_file import KEPT_TABLE
from campaign.config import Config
from campaign.errors import InputError, SafetyError
from campaign.iso230 import Evaluation, evaluate
from campaign.measure.executor import Observer
from campaign.measure.session import Opener, Outcome, open_with_comp, start_campaign
from campaign.plan import Move, Plan, check_motion
from campaign.plot import draw_evaluation, pyplot
from campaign.pointtable import PointTable, read_points
from campaign.record import COMP_FILE, open_campaign, read_recorded_points
from campaign.views import SUMMARY_ROWS
from protocols.plc_contract import CompTable
from protocols.units import DEVIATION_SCALE, unit_label

SUMMARY_KEYS = tuple((key, dict(SUMMARY_ROWS)[key]) for key in ("M", "E", "R_up", "R_down", "B", "A_up", "A_down", "A"))
"""The before/after rows: each parameter by the key and meaning the ISO 230-2 summary uses (A_up,
not A↑), so that the two tables read alike."""


def correction_limits(config: Config, max_rate: float | None, max_accel: float | None) -> tuple[float, float]:
    """(rate limit axis unit/s, acceleration limit axis unit/s²) of the applied correction, from
    `max_rate` in µm/s and `max_accel` in µm/s² (arcsec on a rotary axis): the one unit of every
    correction rate axiscal takes, as in `axiscal correction`. Defaults: a tenth of the axis'
    velocity and acceleration limits (the 2024 motion-planning patent makes the bound proportional to the axis' maximum
    acceleration)."""
    axis = config.axis
    scale = DEVIATION_SCALE[axis.unit]
    return (max_rate / scale if max_rate else 0.1 * axis.max_velocity,
            max_accel / scale if max_accel else 0.1 * axis.max_acceleration)


SPAN_FACTOR = 1.5
"""A table spanning more than this many times the plan's travel was made for a longer axis."""


def table_fits(table: ControllerTable, provenance: dict[str, str], config: Config, plan: Plan,
               where: str, force: bool = False) -> list[str]:
    """Warnings where the table and the campaign about to measure may disagree; InputError, before
    anything is written to the controller, where they certainly do: the table's range does not cover
    the plan's targets (the controller would get no compensation at some of them), it spans far more
    than the plan's travel (SPAN_FACTOR), or it says it was made for another machine or axis. With
    `force` the last two are warnings (the range must still cover the targets)."""
    end = table.start + table.spacing * (len(table.forward) - 1)
    unit = config.axis.unit
    lo, hi = min(plan.targets), max(plan.targets)
    if lo < table.start - 1e-9 or hi > end + 1e-9:
        raise InputError(f"{where}: the table covers {table.start:g} to {end:g} {unit}, the plan's targets "
                         f"{lo:g} to {hi:g} {unit}: made for another axis or range; refused")
    certain = []
    if (end - table.start) > SPAN_FACTOR * (hi - lo):
        certain.append(f"the table spans {table.start:g} to {end:g} {unit}, the plan only {lo:g} to {hi:g} {unit}")
    for key, now in (("machine", config.campaign.machine), ("axis", config.axis.name)):
        then = provenance.get(key)
        if then and then != now:
            certain.append(f"the table was made for {key} '{then}', the config measures {key} '{now}'")
    if certain and not force:
        raise InputError(f"{where}: {'; '.join(certain)}: another axis' table? Nothing was written to the "
                         "controller (--force loads it anyway)")
    corrected_within_limits(table, plan, config, where)
    warnings = [f"{w} (loaded anyway: --force)" for w in certain]
    if not provenance:
        warnings.append("the table does not say which machine and axis it was made for (the linuxcnc, heidenhain "
                        "and fanuc formats have no comments to say it in): check that it is this axis' table")
    return warnings


def corrected_within_limits(table: ControllerTable, plan: Plan, config: Config, where: str) -> None:
    """Refuse (SafetyError, exit 2; --force does not load it) a table whose correction would take
    the motor outside the soft limits anywhere the plan moves: with the table active the motor goes
    to the commanded position plus the correction, so a wrong value (a half-written line, a table in
    µm read as mm) moves it as far as the value says. Checked at every table point within the
    plan's moves and at their ends, in both directions (between points the correction is linear)."""
    axis = config.axis
    moves = [step.position for step in plan.steps if isinstance(step, Move)]
    if not moves:
        return
    lo, hi = min(moves), max(moves)
    inside = table.positions[(table.positions > lo) & (table.positions < hi)]
    for position in [lo, *inside.tolist(), hi]:
        for direction in (1, -1):
            motor = position + table.correction(position, direction) * table.unit_factor
            try:
                check_motion(motor, axis.max_velocity, axis)  # the limits every motion is checked against
            except SafetyError as exc:
                raise SafetyError(f"{where}: moving {'+' if direction > 0 else '-'} at {position:g} {axis.unit} the "
                                  f"table's correction takes the motor there: {exc}; a wrong value in the table? "
                                  "Nothing was written to the controller") from None


def run_verification(config: Config, table: ControllerTable, out: Path, *, opener: Opener,
                     baseline: Path | None = None, max_rate: float | None = None, max_accel: float | None = None,
                     speed: float | None = None, observer: Observer | None = None,
                     source: Path | None = None, identity: dict[str, str] | None = None) -> Outcome:
    """Write `table` to the controller, then run the campaign of `config` into `out`. `source`:
    the table file as given, kept byte for byte in the campaign directory (KEPT_TABLE plus its
    suffix), and `identity` (`table_identity`: its name, format, checksum, source campaign),
    recorded in meta.json's `compensation`, so that the report names what was verified."""
    rate, accel = correction_limits(config, max_rate, max_accel)
    comp = table.to_plc(rate, accel, enabled=True)
    opened = open_with_comp(opener, config, comp, speed)
    kept = KEPT_TABLE + source.suffix if source is not None else None
    compensation: dict[str, object] = {"file": COMP_FILE, "mode": table.mode, "points": len(table.forward),
                                       "start": table.start, "spacing": table.spacing, "overrun": table.overrun,
                                       "max_rate": rate, "max_accel": accel}
    if identity is not None:
        compensation["table"] = {**identity, "kept": kept}
    extra: dict[str, object] = {"compensation": compensation}
    if baseline is not None:
        extra["baseline_dir"] = str(baseline.resolve())
    return start_campaign(config, out, opened=opened, observer=observer, meta_extra=extra,
                          on_created=lambda directory: save_comp(directory, comp, source, kept))


def save_comp(directory: Path, comp: CompTable, source: Path | None = None, kept: str | None = None) -> None:
    """Keep the controller's table in the campaign directory, so that resume writes it again, and
    the table file it came from as given (`kept`), so that the campaign names what it verified."""
    (directory / COMP_FILE).write_text(json.dumps(dataclasses.asdict(comp), indent=1), encoding="utf-8")
    if source is not None and kept is not None:
        (directory / kept).write_bytes(source.read_bytes())


def baseline_points(path: Path, config: Config) -> PointTable:
    """The before point table: a points CSV, or a campaign directory that describes itself (meta.json,
    its config in config.toml or in plan.jsonl, points.csv) and measured the machine and axis
    `config` measures. InputError naming the directory otherwise, before anything moves."""
    if not path.is_dir():
        return read_points(path)
    campaign = open_campaign(path)
    try:
        recorded = campaign.config()
    except InputError as exc:
        raise InputError(f"--before {path}: not a baseline campaign: {exc}") from None
    for what, then, now in (("machine", recorded.campaign.machine, config.campaign.machine),
                            ("axis", recorded.axis.name, config.axis.name),
                            ("axis kind", recorded.axis.kind, config.axis.kind)):
        if then != now:
            raise InputError(f"--before {path}: the baseline measured {what} '{then}', the config measures "
                             f"{what} '{now}': compare like with like")
    if not (path / "points.csv").is_file():
        raise InputError(f"--before {path}: the baseline campaign recorded no points.csv")
    return read_recorded_points(path, partial=False)


def direction_table(table: PointTable, ev: Evaluation, direction: int) -> list[str]:
    """Markdown rows: per target each run's deviation, the mean and s (Li et al. 2022 tables 7, 8)."""
    runs = sorted({int(r) for r in table.run})
    suffix = "up" if direction > 0 else "down"
    lines = ["| target " + table.position_unit + " | " + " | ".join(str(r) for r in runs) + " | mean | s |",
             "|---" * (len(runs) + 3) + "|"]
    for t in ev.targets:
        pick = (table.target == t.target) & (table.direction == direction)
        by_run = {int(r): d for r, d in zip(table.run[pick], table.deviation[pick])}
        cells = [f"{by_run[r]:.3f}" if r in by_run else "–" for r in runs]
        mean, s = getattr(t, f"mean_{suffix}"), getattr(t, f"s_{suffix}")
        lines.append(f"| {t.target:g} | " + " | ".join(cells) +
                     f" | {'–' if mean is None else f'{mean:.3f}'} | {'–' if s is None else f'{s:.3f}'} |")
    return lines


def write_report(directory: Path, after: PointTable, before: PointTable | None) -> dict[str, Any]:
    """verification.md and verification.png in `directory`; returns the before/after summaries."""
    ev_after = evaluate(after)
    ev_before = evaluate(before) if before is not None else None
    unit = unit_label(ev_after.unit)
    md = [f"# Verification: {directory}", ""]
    for label, table, ev in (("Before compensation", before, ev_before), ("After compensation", after, ev_after)):
        if table is None or ev is None:
            continue
        for direction, name in ((1, "forward (+)"), (-1, "reverse (-)")):
            md += [f"## {label}: {name} deviations, {unit}", ""] + direction_table(table, ev, direction) + [""]
    md += [f"## Accuracy, {unit}", "", "| parameter | meaning | before | after |", "|---|---|---|---|"]
    result = {"after": ev_after.summary, "before": ev_before.summary if ev_before else None}
    for key, name in SUMMARY_KEYS:
        b = ev_before.summary.get(key) if ev_before else None
        a = ev_after.summary.get(key)
        md.append(f"| {key} | {name} | {'–' if b is None else f'{b:.3f}'} | {'–' if a is None else f'{a:.3f}'} |")
    (directory / "verification.md").write_text("\n".join(md) + "\n", encoding="utf-8")
    panels = [(before, ev_before, "before: "), (after, ev_after, "after: ")] \
        if before is not None and ev_before is not None else [(after, ev_after, "after: ")]
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(7 * len(panels), 5), squeeze=False)
    for ax, (table, ev, label) in zip(axes[0], panels):
        draw_evaluation(ax, table, ev, label)
    fig.tight_layout()
    fig.savefig(directory / "verification.png", dpi=100)
    plt.close(fig)
    return result

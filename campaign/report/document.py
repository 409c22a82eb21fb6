"""The HTML report a technician hands to quality: one self-contained file (CSS inline, plots as
base64 PNG, nothing fetched), readable offline and printable.

It shows the verdict with its decision rule and reasons (campaign/assess.py: the same verdict
`analyze` and the guide give), the key figures, the campaign (machine, axis, operator, date, a
SIMULATED mark for the simulated machine), the instrument's traceability and the correction
methods, the plan, the environment, the ISO 230-2 summary, the uncertainty budget, the outliers,
the plot, the per-target and per-run tables, and, when a baseline campaign is given, before and
after side by side. It takes a campaign directory or a point table file.
"""

from __future__ import annotations

import base64
import io
import os
from dataclasses import replace
from html import escape
from pathlib import Path
from typing import Any

from campaign import capture_methods
from campaign.assess import Assessment, assess_path
from campaign.errors import InputError
from campaign.iso230 import Evaluation
from campaign.plot import draw_evaluation, pyplot
from campaign.record import open_campaign
from campaign.report.history import history_section
from campaign.report.html import (
    budget_table,
    comparison_table,
    environment_table,
    facts_table,
    key_figures,
    outliers_table,
    page,
    per_run_table,
    section,
    sign_off,
    summary_table,
    target_table,
    verdict_box,
)
from campaign.uncertainty import TYPICAL
from campaign.verdict import completeness
from protocols.units import counted, unit_label


def baseline_of(a: Assessment) -> Path | None:
    """meta.json's `baseline_dir` (absolute, or relative to the campaign directory), if set."""
    value = (a.meta or {}).get("baseline_dir")
    if not value or a.directory is None:
        return None
    path = Path(str(value))
    beside = a.directory / path
    return beside if not path.is_absolute() and beside.exists() else path


def accuracy_envelope(ev: Evaluation) -> tuple[float, float] | None:
    """(lowest, highest) of x̄ ± k·s over every target and direction: the band whose width is A."""
    k = ev.standard.k
    ends = [(m - k * (sd or 0.0), m + k * (sd or 0.0)) for t in ev.targets
            for m, sd in ((t.mean_up, t.s_up), (t.mean_down, t.s_down)) if m is not None]
    if not ends:
        return None
    return min(lo for lo, _ in ends), max(hi for _, hi in ends)


def draw_tolerance(ax: Any, ev: Evaluation, tolerance: float | None) -> None:
    """The tolerance on A as a band of its width, centred on the measured envelope (x̄ ± k·s of
    every target and direction): the envelope fits inside it exactly when A is within tolerance."""
    envelope = accuracy_envelope(ev)
    if not tolerance or envelope is None:
        return
    middle = (envelope[0] + envelope[1]) / 2
    lo, hi = middle - tolerance / 2, middle + tolerance / 2
    for y in (lo, hi):
        ax.axhline(y, color="#c62828", lw=1.2, ls="--")
    ax.axhspan(lo, hi, color="#c62828", alpha=0.05,
               label=f"tolerance on A: {tolerance:g} {unit_label(ev.unit)} wide, centred on the measured band")
    ax.legend(fontsize=8, loc="best")


def plot_png(campaigns: list[tuple[str, Assessment]]) -> str:
    """The deviation plot(s) side by side (same deviation scale), as a base64 PNG data URI, each
    with its tolerance band on A (`draw_tolerance`)."""
    plt = pyplot()
    size = (10.0, 4.8) if len(campaigns) == 1 else (6.4 * len(campaigns), 4.6)  # inches
    fig, axes = plt.subplots(1, len(campaigns), figsize=size, sharey=True, squeeze=False)
    for ax, (label, c) in zip(axes[0], campaigns):
        printable = replace(c.evaluation, unit=unit_label(c.evaluation.unit))  # µm, not um
        draw_evaluation(ax, c.table, printable, f"{label}: " if label else "")
        draw_tolerance(ax, c.evaluation, c.tolerances.get("A"))
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _date(a: Assessment) -> str:
    meta = a.meta or {}
    return str(meta.get("created", meta.get("start_time", "date unknown"))).replace("T", " ").replace("+00:00", " UTC")


def _label(a: Assessment) -> str:
    return a.directory.name if a.directory is not None else Path(a.source).name


def campaign_id(a: Assessment) -> str:
    """The campaign's id: its directory's name (machine, axis, start time), or the table's file name."""
    return _label(a)


def where(path: str | Path, here: Path | None) -> str:
    """`path` relative to the report's folder `here` (how a reader who files both finds it), else as given."""
    if here is None:
        return str(path)
    relative = os.path.relpath(Path(path).resolve(), here.resolve())
    return "the report's own folder" if relative == "." else relative


def located(path: Path, here: Path | None) -> str:
    """`where`, said as relative to the report when it is."""
    place = where(path, here)
    return place if here is None or place == "the report's own folder" else f"{place} (relative to this report)"


def named(a: Assessment, here: Path | None) -> str:
    """A campaign as the report names it: its id and where it is, relative to the report."""
    return f"campaign {campaign_id(a)} ({where(a.directory if a.directory is not None else a.source, here)})"


def _campaign_facts(a: Assessment, here: Path | None = None) -> list[tuple[str, str]]:
    m = a.meta or {}
    axis = m.get("axis", a.config.axis.name if a.config else a.table.meta.get("axis", "?"))
    kind = f"{m.get('kind', a.table.kind)}, {a.table.position_unit}"
    rows = [("Machine", m.get("machine", a.table.meta.get("machine", "unknown"))), ("Axis", f"{axis} ({kind})"),
            ("Operator", m.get("operator") or a.table.meta.get("operator") or "not recorded"), ("Date", _date(a))]
    if a.simulated:
        rows.insert(0, ("Machine type", "SIMULATED machine (axiscal's simulator), not a measurement of a real axis"))
    if a.directory is not None:
        recorded = open_campaign(a.directory)
        planned = f" of {a.planned.points} planned" if a.planned else ""
        status, duration = recorded.status, f"{recorded.duration_s / 60:.1f} min"
        if status == "running":  # no stop record: killed, crashed, or still recording
            status = "recording now" if recorded.recording_now else f"stopped: {recorded.message}"
            times = a.table.optional.get("time_s")
            duration = f"{float(times.max()) / 60:.1f} min to the last point" if times is not None else "not recorded"
        rows += [("Status", f"{status}, {len(a.table)}{planned} points"), ("Duration", duration),
                 ("Software", m.get("software", "axiscal")),
                 ("Campaign directory", located(a.directory, here))]
    else:
        rows += [("Points", str(len(a.table))), ("Point table", where(a.source, here))]
    if a.config and a.config.campaign.description:
        rows.insert(2, ("Description", a.config.campaign.description))
    return rows


def _instrument_facts(a: Assessment) -> list[tuple[str, str]]:
    """Traceability: the laser and its certificate, and how the readings were corrected."""
    if a.config is None:
        return [("Instrument", "not recorded (a point table without its campaign)"),
                ("Corrections", "not recorded")]
    inst, env = a.config.instrument, a.config.environment
    model = inst.model or ("axiscal's simulated interferometer" if a.simulated else "not recorded")
    certificate = inst.certificate or "not recorded"
    ppm = inst.wavelength_uncertainty_ppm
    air = ("by axiscal: updated Edlén equation (NIST form) from the air sensors, readings taken in vacuum "
           f"wavelength {env.wavelength_nm:g} nm" if env.air_correction == "edlen" else
           "by the instrument (its own environmental compensation)")
    material = (f"normalised to 20 °C with the material temperature, α = {env.expansion_ppm_per_k:g} µm/m·K"
                if env.normalise_to_20c else "not normalised to 20 °C (the uncertainty budget counts the "
                                                "uncorrected expansion)")
    if a.table.kind == "rotary":
        arcsec = inst.angle_uncertainty_arcsec
        accuracy = ("Angle uncertainty", f"{arcsec:g} arcsec (k = 2), from the certificate" if arcsec is not None
                    else f"not given: the budget uses {TYPICAL['angle_uncertainty_arcsec']:g} arcsec, a typical "
                         "specification")
    else:
        accuracy = ("Length uncertainty", f"{ppm:g} µm/m (k = 2), from the certificate" if ppm is not None else
                    f"not given: the budget uses {TYPICAL['wavelength_uncertainty_ppm']:g} µm/m, a typical "
                    "specification")
    return [("Laser", model), ("Serial number", inst.serial or "not recorded"),
            ("Calibration certificate", certificate), accuracy,
            ("Air correction", air), ("Material temperature", material)]


def _compensation_facts(a: Assessment, here: Path | None) -> list[tuple[str, str]] | None:
    """The compensation table a verification measured with (meta.json's `compensation`, written by
    `axiscal verify`): its file, format, mode, grid, checksum, the campaign it was computed from and
    when, and the copy kept in the campaign directory. None for a campaign without one."""
    comp = (a.meta or {}).get("compensation")
    if not isinstance(comp, dict):
        return None
    unit = a.table.position_unit
    table = comp.get("table") if isinstance(comp.get("table"), dict) else {}
    rows = []
    if table:
        rows += [("Table file", str(table.get("name", "not recorded"))), ("Format", str(table.get("format", "?"))),
                 ("SHA-256", str(table.get("sha256", "not recorded")))]
    else:
        kept_only = comp.get("file", "plc-compensation.json")
        rows.append(("Table file", f"not recorded (an older axiscal kept only the controller's copy, {kept_only})"))
    points, spacing, start = comp.get("points"), comp.get("spacing"), comp.get("start")
    rows += [("Mode", {"bi": "bidirectional (a table per direction)", "uni": "unidirectional (one table)"}
              .get(str(comp.get("mode")), str(comp.get("mode"))))]
    if isinstance(points, int) and isinstance(spacing, (int, float)) and isinstance(start, (int, float)):
        rows.append(("Grid", (f"{points} points from {start:g} every {spacing:g} {unit} "
                             f"(to {start + spacing * (points - 1):g} {unit})")))
    if table:
        source = table.get("source_campaign")
        measured = table.get("source_measured", "")
        when = f", measured {measured.replace('T', ' ')}" if measured else ""
        rows.append(("Computed from", f"campaign {source}{when}" if source
                     else "not said by the table (its format has no comments)"))
        if written := table.get("source_written"):
            rows.append(("Table written", written.replace("T", " ")))
        if table.get("source_machine") or table.get("source_axis"):
            rows.append(("Made for", f"machine {table.get('source_machine', '?')}, axis {table.get('source_axis', '?')}"))
        if table.get("kept") and a.directory is not None:
            rows.append(("Kept as", where(a.directory / str(table["kept"]), here)))
    return rows


def _plan_facts(a: Assessment) -> list[tuple[str, str]]:
    unit = a.table.position_unit
    targets = sorted({float(t) for t in a.table.target})
    listed = ", ".join(f"{t:g}" for t in targets)
    rows = [("Targets", f"{len(targets)}: {listed} {unit}"), ("Runs", str(a.evaluation.runs)),
            ("Directions", " and ".join("+" if d > 0 else "−" for d in a.table.directions))]
    if a.config:
        p, cap = a.config.plan, a.config.capture
        method = capture_methods.method(cap.method).describe(cap, unit, unit_label(a.evaluation.unit))
        rows += [("Cycle", f"{p.cycle}, overrun {p.overrun:g} {unit}"),
                 ("Dwell", f"{p.dwell_s:g} s"), ("Velocity", f"{p.velocity:g} {unit}/s"),
                 ("Capture", method), ("Target offsets", p.offsets)]
    seed = (a.meta or {}).get("plan_seed", a.table.meta.get("plan_seed", "not recorded"))
    rows.append(("Plan seed", str(seed)))
    return rows + _scan_facts(a.table.meta)


SCAN_FACTS = (("scan", "Scan"), ("clock_offset_ms", "Clock offset, ms"), ("clock_rate_error_ppm", "Clock rate error, ppm"),
              ("timing_u", "Timing uncertainty"), ("speed_limit", "Speed limit"), ("deviation", "Deviation"),
              ("segments", "Segments"))
"""What a scan's table says of itself (campaign.stream.scan, campaign.measure.scan), as the report shows it."""


def _scan_facts(meta: dict[str, str]) -> list[tuple[str, str]]:
    """A scan's alignment, timing budget, speed limit, rest steps, warnings and what was left out."""
    method = capture_methods.METHODS.get(meta.get("capture", ""))
    if method is None or not method.sweeps:  # only a sweeping method's table carries these facts
        return []
    rows = [(label, meta[key]) for key, label in SCAN_FACTS if key in meta]
    rows += [("Warning", v) for k, v in meta.items() if k.startswith("warning_")]
    rows += [("Left out", v) for k, v in meta.items() if k.startswith("left_out_")]
    return rows


def _comparison(before: Assessment, after: Assessment, here: Path | None = None) -> str:
    plots = plot_png([(f"before ({_label(before)})", before), (f"after ({_label(after)})", after)])
    unit = unit_label(after.evaluation.unit)
    value_after, value_before = after.evaluation.summary.get("A"), before.evaluation.summary.get("A")
    if value_after is not None and value_before:
        lead = (f"A went from {value_before:.2f} {unit} to {value_after:.2f} {unit}: "
                f"{abs(1 - value_after / value_before) * 100:.0f} % "
                f"{'smaller' if value_after <= value_before else 'larger'}.")
    else:
        lead = "A cannot be compared: it is unavailable in one of the campaigns."
    sources = (f"Before: {named(before, here)}, {_date(before)}. After: {named(after, here)}, {_date(after)}. "
               "Changes compare magnitudes (|after| / |before|); smaller is better.")
    for label, c in (("before", before), ("after", after)):
        if missing := completeness(c.table, c.planned):
            sources += (f" The {label} campaign is incomplete ({'; '.join(missing)}): its figures are from the "
                        "points measured, and the comparison is not like for like.")
    return section("Before and after", f"<p class='lead'>{escape(lead)}</p><p>{escape(sources)}</p>"
                   + comparison_table(before.evaluation, after.evaluation)
                   + f"<img class='plot' alt='Deviation before and after' src='{plots}'>")


def assumptions(a: Assessment) -> list[str]:
    """What the verdict rests on beyond the measurement: an instrument specification assumed (no
    certificate value in the config) or a calibration not recorded. Empty when both are recorded."""
    if a.config is None:
        return [("an instrument and a calibration not recorded (a point table without its campaign; the "
                 "uncertainty uses a typical laser specification)")]
    inst = a.config.instrument
    said = []
    if a.table.kind == "rotary" and inst.angle_uncertainty_arcsec is None:
        said.append(f"an assumed instrument specification ({TYPICAL['angle_uncertainty_arcsec']:g} arcsec, "
                    "typical, not from a certificate)")
    if a.table.kind != "rotary" and inst.wavelength_uncertainty_ppm is None:
        said.append(f"an assumed instrument specification ({TYPICAL['wavelength_uncertainty_ppm']:g} µm/m, "
                    "typical, not from a certificate)")
    if not inst.certificate:
        said.append("a calibration not recorded (no certificate in the config)")
    return said


def render_report(a: Assessment, before: Assessment | None = None, here: Path | None = None) -> str:
    """The whole HTML document for `a` (the after campaign when `before` is given). `here`: the
    folder the report is written to; the campaigns are named relative to it."""
    ev = a.evaluation
    meta = a.meta or {}
    machine = meta.get("machine", a.table.meta.get("machine", "?"))
    axis = meta.get("axis", a.table.meta.get("axis", "?"))
    title = f"Positioning accuracy: machine {machine}, axis {axis}" + (" (SIMULATED)" if a.simulated else "")
    rests_on = assumptions(a) if a.verdict.verdict in ("pass", "fail") else []
    parts = [verdict_box(a.verdict, a.tolerances, ev.unit, rests_on), key_figures(ev, a.uncertainty),
             "<div class='columns'>" + section("Campaign", facts_table(_campaign_facts(a, here)))
             + section("Plan", facts_table(_plan_facts(a))) + "</div>",
             "<div class='columns'>" + section("Instrument and corrections", facts_table(_instrument_facts(a)))
             + section("Environment", environment_table(a.table.optional)) + "</div>"]
    if (comp := _compensation_facts(a, here)) is not None:
        parts.append(section("Compensation table verified", facts_table(comp)))
    if before is not None:
        parts.append(_comparison(before, a, here))
    plot = plot_png([("", a)])
    parts += [section(f"Result ({ev.standard.title}, {counted(ev.runs, 'run')})", summary_table(ev)),
              section("Measurement uncertainty", budget_table(a.uncertainty)),
              section("Outliers", outliers_table(a.outliers, ev.unit)),
              section("Deviation plot", f"<img class='plot' alt='Deviation per target' src='{plot}'>"),
              history_section(str(machine), str(axis)),
              section("Per target", target_table(ev)),
              section("Per run", per_run_table(a.table))]
    if ev.warnings:
        items = "".join(f"<li>{escape(w)}</li>" for w in ev.warnings)
        parts.append(section("Warnings", f"<ul class='warnings'>{items}</ul>"))
    operator = meta.get("operator") or a.table.meta.get("operator") or "not recorded"
    parts.append(sign_off(a.verdict.word, operator if operator != "not recorded" else ""))
    subtitle = f"{ev.standard.title}. Measured {_date(a)}. Operator: {operator}. Campaign {campaign_id(a)}."
    return page(title, "".join(parts), subtitle, campaign_id(a))


def write_report(source: str | Path, out: str | Path, before: str | Path | None = None,
                 tolerance: float | None = None) -> Path:
    """Assess the campaign directory or point table `source` (and the baseline: `before`, else
    meta.json's baseline_dir), write the HTML. `tolerance`: on A, instead of the config's."""
    a = assess_path(source, tolerance)
    baseline = Path(before) if before else baseline_of(a)
    previous = assess_path(baseline) if baseline else None
    if previous is not None and previous.table.kind != a.table.kind:
        raise InputError(f"{baseline}: a {previous.table.kind} axis, but {source} is a {a.table.kind} axis")
    path = Path(out)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(render_report(a, previous, path.parent), encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror})") from None
    return path

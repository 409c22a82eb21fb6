"""HTML building blocks of the report (campaign/report/document.py): the page with its inline CSS, tables and
the pass/fail box. Every text that comes from a file is escaped."""

from __future__ import annotations

from collections.abc import Sequence
from html import escape

import numpy as np

from campaign.iso230 import Evaluation
from campaign.outliers import Outliers
from campaign.pointtable import UNITS, PointTable
from campaign.uncertainty import Budget
from campaign.verdict import NAMES, Verdict
from campaign.views import SUMMARY_ROWS, fmt
from protocols.units import unit_label

ENVIRONMENT = (("air_temp_c", "Air temperature", "°C", 2), ("air_pressure_hpa", "Air pressure", "hPa", 1),
               ("humidity_pct", "Relative humidity", "%", 1),
               ("material_temp_c", "Material temperature", "°C", 2))
"""points.csv column, name, unit, decimals."""

CSS = """
body { font-family: "DejaVu Sans", "Liberation Sans", Arial, sans-serif; color: #1d2630; margin: 0;
       background: #eef1f4; font-size: 15px; line-height: 1.4; }
main { max-width: 1120px; margin: 0 auto; padding: 24px 28px 40px; background: #fff; }
h1 { font-size: 26px; margin: 0 0 4px; }
h2 { font-size: 18px; margin: 0 0 8px; padding-bottom: 4px; border-bottom: 2px solid #d5dbe1; }
.subtitle { color: #52606d; margin: 0 0 18px; }
section { margin: 0 0 22px; break-inside: avoid; }
.columns { display: flex; gap: 28px; }
.columns > section { flex: 1; }
table { border-collapse: collapse; width: 100%; font-size: 14px; }
th, td { padding: 4px 8px; border-bottom: 1px solid #e3e7eb; text-align: left; vertical-align: top; }
th { background: #f4f6f8; font-weight: 600; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.facts th { width: 34%; background: none; color: #52606d; font-weight: normal; }
.verdict { display: flex; align-items: center; gap: 20px; padding: 14px 20px; border-radius: 8px;
           margin: 0 0 22px; border: 2px solid; }
.verdict .word { font-size: 34px; font-weight: 700; letter-spacing: 2px; }
.verdict p, .verdict ul { margin: 0; font-size: 16px; }
.verdict p.rule { font-size: 13px; margin-top: 6px; }
.pass { background: #e6f4ea; border-color: #2e7d32; color: #1b5e20; }
.fail { background: #fdecea; border-color: #c62828; color: #8e1b1b; }
.none { background: #f4f6f8; border-color: #9aa5b1; color: #3e4c59; }
img.plot { width: 100%; height: auto; border: 1px solid #e3e7eb; margin-top: 10px; }
.figures { display: flex; gap: 14px; margin: 0 0 22px; }
.figures div { flex: 1; border: 1px solid #d5dbe1; border-radius: 8px; padding: 8px 14px; }
.figures .key { display: block; color: #52606d; font-size: 13px; }
.figures .value { font-size: 26px; font-weight: 700; margin-right: 6px; font-variant-numeric: tabular-nums; }
.figures .unit { color: #52606d; }
.lead { font-size: 16px; margin: 0 0 10px; }
.better { color: #1b5e20; } .worse { color: #8e1b1b; }
ul.warnings { margin: 0; padding-left: 20px; color: #8a5a00; }
footer { color: #7b8794; font-size: 12px; margin-top: 28px; }
.verdict p.rests { font-size: 14px; margin-top: 6px; font-weight: 600; }
table.signoff td { height: 44px; vertical-align: bottom; }
table.signoff td.line { border-bottom: 1px solid #1d2630; }
@media print { body { background: #fff; font-size: 12px; } main { padding: 0; max-width: none; }
               .columns { display: block; } h2 { break-after: avoid; } tr, img.plot { break-inside: avoid; } }
"""


def page_css(campaign: str) -> str:
    """The printed page: A4, with the campaign id at the foot of every page and "page N of M"
    (CSS page margin boxes, which headless Chromium's print-to-PDF draws)."""
    quoted = campaign.replace("\\", "\\\\").replace('"', '\\"').replace("<", "\\3C ").replace("\n", " ")
    return ("@page { size: A4; margin: 14mm 12mm 16mm 12mm; "
            f'@bottom-left {{ content: "Campaign {quoted}"; font-size: 9pt; color: #52606d; }} '
            '@bottom-right { content: "Page " counter(page) " of " counter(pages); font-size: 9pt; '
            "color: #52606d; } }")


def page(title: str, body: str, subtitle: str = "", campaign: str = "") -> str:
    """A complete HTML document with the CSS inline; printed, each page names `campaign` and its number."""
    return (f"<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'>\n"
            f"<title>{escape(title)}</title>\n<style>{CSS}{page_css(campaign)}</style>\n</head>\n<body>\n<main>\n"
            f"<h1>{escape(title)}</h1>\n<p class='subtitle'>{escape(subtitle)}</p>\n{body}\n"
            f"<footer>Made by axiscal. Deviation = measured − target (ISO 230-2 sign).</footer>\n"
            f"</main>\n</body>\n</html>\n")


def section(title: str, body: str) -> str:
    return f"<section>\n<h2>{escape(title)}</h2>\n{body}\n</section>\n"


def _table(head: list[str], rows: Sequence[Sequence[object]], numeric_from: int = 1, css: str = "",
           numeric: tuple[int, ...] | None = None) -> str:
    """A table; columns from `numeric_from` on (or the columns `numeric`) are right-aligned numbers.
    Cells are escaped here."""
    def is_num(i: int) -> bool:
        return i in numeric if numeric is not None else i >= numeric_from

    def cells(tag: str, values: Sequence[object]) -> str:
        return "".join(f"<{tag}{' class=num' if is_num(i) else ''}>{escape(str(v))}</{tag}>"
                       for i, v in enumerate(values))
    body = "".join(f"<tr>{cells('td', r)}</tr>" for r in rows)
    return f"<table class='{css}'><thead><tr>{cells('th', head)}</tr></thead><tbody>{body}</tbody></table>"


def facts_table(rows: list[tuple[str, str]]) -> str:
    body = "".join(f"<tr><th>{escape(str(k))}</th><td>{escape(str(v))}</td></tr>" for k, v in rows)
    return f"<table class='facts'><tbody>{body}</tbody></table>"


def environment_table(optional: dict[str, np.ndarray]) -> str:
    """Mean, minimum and maximum of each environment column present in points.csv."""
    rows = [[name, f"{np.mean(optional[col]):.{d}f}", f"{np.min(optional[col]):.{d}f}",
             f"{np.max(optional[col]):.{d}f}", unit]
            for col, name, unit, d in ENVIRONMENT if col in optional]
    if not rows:
        return "<p>No environment readings in points.csv.</p>"
    return _table(["Quantity", "Mean", "Minimum", "Maximum", "Unit"], rows)


def summary_table(ev: Evaluation) -> str:
    unit = unit_label(ev.unit)
    rows = [[key, meaning, fmt(ev.summary[key]), unit] for key, meaning in SUMMARY_ROWS if key in ev.summary]
    return _table(["Parameter", "Meaning", "Value", "Unit"], rows, numeric_from=2)


def target_table(ev: Evaluation) -> str:
    u = unit_label(ev.unit)
    head = [f"Target ({ev.position_unit})", "n↑", "n↓", f"x̄↑ ({u})", f"x̄↓ ({u})", f"s↑ ({u})", f"s↓ ({u})",
            f"B ({u})", f"R↑ ({u})", f"R↓ ({u})", f"R ({u})", f"x̄ ({u})"]
    rows = [[f"{t.target:g}", t.n_up, t.n_down, fmt(t.mean_up), fmt(t.mean_down), fmt(t.s_up), fmt(t.s_down),
             fmt(t.B), fmt(t.R_up), fmt(t.R_down), fmt(t.R), fmt(t.mean)] for t in ev.targets]
    return _table(head, rows, numeric_from=0)


def _change(before: float | None, after: float | None) -> tuple[str, str]:
    """(text, css class) of the change in magnitude from before to after; smaller is better. Signed
    values are compared by their magnitudes, never by a ratio across zero."""
    if before is None or after is None or before == 0:
        return "–", ""
    ratio = abs(after) / abs(before)
    word = "smaller" if ratio <= 1 else "larger"
    sign = "; sign changed" if (before < 0) != (after < 0) and after != 0 else ""
    return f"|×| {ratio:.2f} ({abs(1 - ratio) * 100:.0f} % {word}{sign})", "better" if ratio <= 1 else "worse"


def comparison_table(before: Evaluation, after: Evaluation) -> str:
    """The summary parameters before and after, with the change in magnitude |after| / |before|."""
    unit = unit_label(after.unit)
    rows = []
    for key, meaning in SUMMARY_ROWS:
        if key not in after.summary or (before.summary.get(key) is None and after.summary[key] is None):
            continue
        text, css = _change(before.summary.get(key), after.summary[key])
        rows.append(f"<tr><td>{key}</td><td>{escape(meaning)}</td>"
                    f"<td class=num>{fmt(before.summary.get(key))}</td>"
                    f"<td class=num>{fmt(after.summary[key])}</td><td class=num>{unit}</td>"
                    f"<td class='num {css}'>{escape(text)}</td></tr>")
    head = "".join(f"<th{' class=num' if i > 1 else ''}>{h}</th>" for i, h in
                   enumerate(["Parameter", "Meaning", "Before", "After", "Unit", "Change in magnitude"]))
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def key_figures(ev: Evaluation, budget: Budget) -> str:
    """The main parameters in large type: A, E, B and R (or their one-direction values), each with
    its expanded uncertainty."""
    unit = unit_label(ev.unit)
    keys = ("A", "E", "B", "R") if ev.summary.get("A") is not None or ev.summary.get("E") is not None else \
        ("A_up", "E_up", "R_up", "A_down", "E_down", "R_down")
    cells = []
    for k in keys:
        if k not in ev.summary:
            continue
        u = budget.expanded.get(k[0])
        plus = f"<span class='unit'>± {u:.2f} (U, k = 2)</span>" if u is not None and ev.summary.get(k) is not None else ""
        cells.append(f"<div><span class='key'>{k}</span><span class='value'>{fmt(ev.summary.get(k), 2)}</span>"
                     f"<span class='unit'>{unit}</span> {plus}</div>")
    return f"<div class='figures'>{''.join(cells)}</div>"


def verdict_box(verdict: Verdict, tolerances: dict[str, float], unit: str, rests_on: Sequence[str] = ()) -> str:
    """PASS, FAIL or NOT JUDGED with its reasons, the tolerances on A, E, B and R and the decision
    rule; `rests_on`: what the verdict assumes beyond the measurement (an instrument specification
    assumed, a calibration not recorded), said beside the word."""
    css = {"pass": "pass", "fail": "fail"}.get(verdict.verdict, "none")
    reasons = "".join(f"<li>{escape(r)}</li>" for r in verdict.reasons)
    notes = "".join(f"<li>{escape(n)}</li>" for n in verdict.notes)
    rests = (f"<p class='rests'>{verdict.word} rests on {escape(' and on '.join(rests_on))}: "
             "record the laser's certificate to make it a calibrated verdict.</p>" if rests_on else "")
    return (f"<div class='verdict {css}'><span class='word'>{verdict.word}</span><div>{rests}<ul>{reasons}{notes}</ul>"
            f"{tolerance_table(verdict, tolerances, unit)}"
            f"<p class='rule'>Decision rule: {escape(verdict.rule)}.</p></div></div>")


def sign_off(verdict: str, operator: str) -> str:
    """The block a quality engineer signs: measured by (the operator, when recorded), checked by,
    approved by, each with name, signature and date lines, and the disposition."""
    rows = "".join(f"<tr><th>{role}</th><td class='line'>{escape(name)}</td><td class='line'></td>"
                   f"<td class='line'></td></tr>"
                   for role, name in (("Measured by", operator), ("Checked by", ""), ("Approved by", "")))
    return section("Sign-off", f"<p>Result as reported: <b>{escape(verdict)}</b>. Disposition: "
                   "☐ accepted&nbsp;&nbsp; ☐ accepted with remarks&nbsp;&nbsp; ☐ rejected</p>"
                   "<table class='signoff'><thead><tr><th>Role</th><th>Name</th><th>Signature</th><th>Date</th>"
                   f"</tr></thead><tbody>{rows}</tbody></table><p>Remarks:</p>"
                   "<table class='signoff'><tbody><tr><td class='line'></td></tr><tr><td class='line'></td></tr>"
                   "</tbody></table>")


def tolerance_table(verdict: Verdict, tolerances: dict[str, float], unit: str) -> str:
    """Each parameter's tolerance as configured, and for those set: value, U, the decision rule's
    interval and the result. A parameter without a tolerance is said to be not judged on."""
    u = unit_label(unit)
    checks = {c["parameter"]: c for c in verdict.checks}
    rows = []
    for key, name in NAMES.items():
        tol = tolerances.get(key) or 0.0
        c = checks.get(key)
        if c is not None:
            if c["U"] is None:  # one run: no scatter, no U
                rows.append([c.get("name", name), f"{tol:g}", f"{c['value']:.3f}", "—", "—", c["result"].upper()])
            else:
                rows.append([c.get("name", name), f"{tol:g}", f"{c['value']:.3f}", f"{c['U']:.3f}",
                             f"{c['value'] - c['U']:.3f} … {c['value'] + c['U']:.3f}", c["result"].upper()])
        elif tol:
            rows.append([name, f"{tol:g}", "—", "—", "—", "unavailable"])
        else:
            rows.append([name, "not set", "—", "—", "—", "not judged on"])
    return _table(["Parameter", f"Tolerance ({u})", f"Value ({u})", f"U ({u}), k = 2", f"Value ± U ({u})", "Result"],
                  rows, numeric=(1, 2, 3, 4))


def budget_table(budget: Budget) -> str:
    """Every term of the uncertainty budget, then the expanded uncertainties."""
    unit = unit_label(budget.unit)
    rows = [[t.name, f"{t.u:.3f}", " ".join(t.applies), t.source] for t in budget.terms]
    rows += [[f"U({k}), k = {budget.k:g}", f"{v:.3f}", k, "expanded uncertainty"] for k, v in budget.expanded.items()]
    table = _table(["Term", f"u ({unit})", "For", "Input and source"], rows, numeric=(1,))
    missing = "".join(f"<li>{escape(m)}</li>" for m in budget.missing)
    return table + (f"<p>Not evaluated:</p><ul class='warnings'>{missing}</ul>" if missing else "")


def outliers_table(outliers: Outliers, unit: str) -> str:
    """The readings the outlier test flags (they stay in the result), and the scatter with and
    without them."""
    u = unit_label(unit)
    test = (f"Studentised deleted residual against the scatter pooled over the campaign, "
            f"{100 * outliers.alpha:g} % significance for the whole campaign (Bonferroni)")
    if not outliers.found:
        return f"<p>None found. {escape(test)}.</p>"
    rows = [[str(o.run), "+" if o.direction > 0 else "−", f"{o.target:g}", f"{o.deviation:+.3f}", f"{o.score:.1f}",
             f"{o.critical:.1f}"] for o in outliers.found]
    scatter = (f"Pooled scatter s = {outliers.s_with:.3f} {u} with them, {outliers.s_without:.3f} {u} without. "
               "They are included in every result above.")
    return (_table(["Run", "Direction", "Target", f"Deviation ({u})", "Score", "Critical"], rows, numeric_from=2)
            + f"<p>{escape(scatter)} {escape(test)}.</p>")


def per_run_table(table: PointTable) -> str:
    """Every reading: one row per target and direction, one column per run (Li et al. 2022 tables 7, 8)."""
    u = unit_label(UNITS[table.kind][1])
    runs = sorted({int(r) for r in table.run})
    cells = {(float(t), int(d), int(r)): float(x)
             for t, d, r, x in zip(table.target, table.direction, table.run, table.deviation)}
    rows = []
    for d in sorted({int(x) for x in table.direction}, reverse=True):
        for t in sorted({float(x) for x in table.target}):
            rows.append([f"{t:g}", "+" if d > 0 else "−"] +
                        [f"{cells[(t, d, r)]:.3f}" if (t, d, r) in cells else "–" for r in runs])
    return _table([f"Target ({table.position_unit})", "Direction"] + [f"Run {r} ({u})" for r in runs], rows,
                  numeric_from=2)

"""The report's history section: when the campaign store (campaign/history/) holds other
campaigns of the same machine and axis, the trend plot, the drift, the jumps, the crossing date
and the last campaigns. Nothing when the store is turned off or holds no other campaign; one
sentence when it cannot be reached. The store is named by its short label (its file name, or host
and database), never by a URL. The report never
creates or migrates a store (store.open_reader): an embedded store file that does not exist, or a
database without the store's tables, is no store."""

from __future__ import annotations

import base64
import io
from html import escape
from typing import Any

from campaign.report.html import section
from protocols.units import unit_label

LAST = 10
"""How many of the last campaigns the section lists."""


def _store_rows(machine: str, axis: str) -> tuple[list[dict[str, Any]], str] | None:
    """(the axis's rows, the store's name), or None without a store; RuntimeError with a sentence
    when the store cannot be reached."""
    from campaign.history.location import store_label, store_url
    from campaign.history.store import StoreUnavailable, open_reader

    url = store_url(None)
    if url is None:
        return None
    try:
        store = open_reader(url)
        if store is None:
            return None
        with store:
            return store.campaigns(machine, axis), store.display
    except StoreUnavailable as exc:
        raise RuntimeError(f"The history store could not be used ({exc}); the axis's history is not shown.") from None
    except Exception as exc:  # noqa: BLE001 - the report is made whatever the store says
        raise RuntimeError(f"The history store {store_label(url)} could not be read ({type(exc).__name__}); "
                           "the axis's history is not shown.") from None


def history_section(machine: str, axis: str) -> str:
    """The section's HTML ("" when there is no history to show)."""
    try:
        found = _store_rows(machine, axis)
    except RuntimeError as exc:
        return section("History of this axis", f"<p>{escape(str(exc))}</p>")
    if found is None:
        return ""
    rows, name = found
    from campaign.history.axis import axis_trend

    trend = axis_trend(rows, machine, axis)
    if len(trend.counted) < 2:
        return ""
    from campaign.history.plots import draw_trend
    from campaign.plot import pyplot

    fig = draw_trend(trend)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    pyplot().close(fig)
    image = "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")
    unit = unit_label(trend.unit)
    sentences = [f.sentence(unit) for f in trend.fits.values()]
    sentences += trend.step_sentences() + [j.sentence(unit) for j in trend.jumps]
    if trend.crossing is not None:
        sentences.append(trend.crossing.sentence(unit))
    items = "".join(f"<li>{escape(s)}</li>" for s in sentences)
    head = "".join(f"<th class='num'>{h}</th>" if h in "AEBR" else f"<th>{h}</th>"
                   for h in ("Date", "Campaign", "A", "E", "B", "R", "Verdict"))
    body = ""
    for r in trend.counted[-LAST:]:
        cells = []
        for p in ("A", "E", "B", "R"):
            value, u = r["results"].get((p, "both"), (None, None))
            cells.append("n/a" if value is None else f"{value:.2f}" + ("" if u is None else f" ± {u:.2f}"))
        when = r["measured_utc"].date().isoformat() if r["measured_utc"] else "undated"
        body += (f"<tr><td>{escape(when)}</td><td>{escape(r['label'])}</td>"
                 + "".join(f"<td class='num'>{escape(c)}</td>" for c in cells) + f"<td>{escape(r['verdict'])}</td></tr>")
    left = f" {len(trend.left_out)} other record(s) of this axis are left out of the trend." if trend.left_out else ""
    lead = (f"{len(trend.counted)} campaigns of machine {machine}, axis {axis} in {name}; values ± U (k = 2), "
            f"{unit}.{left}")
    return section("History of this axis",
                   f"<p>{escape(lead)}</p><ul>{items}</ul>"
                   f"<img class='plot' alt='The axis over its campaigns' src='{image}'>"
                   f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")


# --- the plant at a glance (`axiscal history plant --html FILE`) --------------------------------

SPARK_W, SPARK_H = 240, 64
"""The size of each axis's trend plot on the plant page, CSS pixels."""

PLANT_CSS = """
<style>
table.plant td { vertical-align: middle; }
table.plant td:nth-child(4), table.plant td:nth-child(6), table.plant td:nth-child(9) { white-space: nowrap; }
td.state-out { color: #fff; background: #b3261e; font-weight: 600; }
td.state-overdue { background: #f6d4d1; font-weight: 600; }
td.state-due-soon { background: #fbecc7; }
td.state-ok { color: #1f6f3f; }
svg.spark { display: block; }
</style>
"""


def _spark(glance: Any) -> str:
    """A small inline SVG of A over the axis's campaigns: each campaign's A with its U, the fitted
    line's last segment continued to the due date, the tolerance (dashed), the due date (a tick)."""
    series = [(r["measured_utc"], *r["results"].get(("A", "both"), (None, None))) for r in glance.trend.counted]
    series = [(when, a, u or 0.0) for when, a, u in series if a is not None]
    if not series:
        return "<span>no campaign that counts</span>"
    import datetime as dt

    start = series[0][0]
    end = max(series[-1][0], dt.datetime.combine(glance.due, dt.time()))
    span_s = max((end - start).total_seconds(), 86400.0)
    tolerance = glance.trend.tolerance
    high = max([a + u for _, a, u in series] + ([tolerance] if tolerance else []))
    low = min([a - u for _, a, u in series] + [0.0])
    high = high + 0.05 * (high - low or 1.0)

    def x(when: Any) -> float:
        return 6 + (SPARK_W - 12) * (when - start).total_seconds() / span_s

    def y(value: float) -> float:
        return SPARK_H - 4 - (SPARK_H - 8) * (value - low) / ((high - low) or 1.0)

    parts = []
    if tolerance:
        parts.append(f"<line x1='0' x2='{SPARK_W}' y1='{y(tolerance):.1f}' y2='{y(tolerance):.1f}' stroke='#b3261e' "
                     "stroke-dasharray='4 3' stroke-width='1'><title>tolerance</title></line>")
    fit = glance.trend.fits.get("A")
    if fit is not None and fit.rate is not None and fit.coef is not None:
        last = series[-1][0]
        tau0 = (series[0][0] - last).total_seconds() / (365.25 * 86400)
        from_index = len(fit.observations) - 1
        first_of_segment = max([0] + [i for i in fit.step_at if i <= from_index])
        t_seg = fit.observations[first_of_segment].when
        tau_a = (t_seg - last).total_seconds() / (365.25 * 86400) if first_of_segment else tau0
        tau_b = (end - last).total_seconds() / (365.25 * 86400)
        import numpy as np

        ends = fit.fitted(np.array([tau_a, tau_b]), from_index)
        x_a = x(last + dt.timedelta(days=365.25 * tau_a))
        parts.append(f"<line x1='{x_a:.1f}' x2='{x(end):.1f}' y1='{y(float(ends[0])):.1f}' y2='{y(float(ends[1])):.1f}' "
                     "stroke='#52606d' stroke-width='1'><title>fitted drift of A</title></line>")
    for when, a, u in series:
        cx = x(when)
        parts.append(f"<line x1='{cx:.1f}' x2='{cx:.1f}' y1='{y(a + u):.1f}' y2='{y(a - u):.1f}' stroke='#2b6cb0' "
                     "stroke-width='1'/>")
        parts.append(f"<circle cx='{cx:.1f}' cy='{y(a):.1f}' r='2.2' fill='#2b6cb0'><title>{escape(when.date().isoformat())}: "
                     f"A = {a:.2f} ± {u:.2f}</title></circle>")
    due_x = x(dt.datetime.combine(glance.due, dt.time()))
    parts.append(f"<line x1='{due_x:.1f}' x2='{due_x:.1f}' y1='0' y2='{SPARK_H}' stroke='#c27c0e' stroke-width='1.5'>"
                 f"<title>next re-check due {glance.due.isoformat()}</title></line>")
    label = escape(f"A of {glance.trend.machine} {glance.trend.axis} over {len(series)} campaigns")
    return (f"<svg class='spark' role='img' aria-label='{label}' width='{SPARK_W}' height='{SPARK_H}' "
            f"viewBox='0 0 {SPARK_W} {SPARK_H}' xmlns='http://www.w3.org/2000/svg'>{''.join(parts)}</svg>")


def plant_page(glances: list[Any], store: str, today: Any, max_interval_days: int, margin_days: int) -> str:
    """The plant at a glance as a self-contained HTML page: one row per axis, most urgent first,
    each with its small trend plot."""
    from campaign.report.html import page

    head = "".join(f"<th>{h}</th>" for h in ("Machine", "Axis", "State", "Next re-check due", "Last campaign",
                                              "A ± U", "Verdict", "Drift of A per year", "A + U reaches the tolerance",
                                              "A over the campaigns"))
    body = []
    for g in glances:
        unit = unit_label(g.trend.unit)
        a, u = g.a_and_u()
        last = g.last
        fit = g.trend.fits.get("A")
        drift = "n/a" if fit is None or fit.rate is None else f"{fit.rate:+.2f} ± {fit.U_rate:.2f} {unit}"
        if fit is not None and fit.rate is None:
            drift = f"not determined ({fit.reason})"
        c = g.trend.crossing
        if c is None or c.state != "predicted" or c.date is None:
            crossing = "already" if c is not None and c.state == "already" else "not predictable"
        else:
            crossing = c.date.date().isoformat()
        cells = [g.trend.machine, g.trend.axis, g.state, g.due.isoformat(),
                 "none" if last is None else f"{last['measured_utc'].date().isoformat()} ({last['label']})",
                 "n/a" if a is None else f"{a:.2f} ± {u or 0.0:.2f} {unit}",
                 "" if last is None else last["verdict"], drift, crossing]
        row = "".join(f"<td>{escape(str(cell))}</td>" if i != 2 else
                      f"<td class='state-{escape(str(cell).replace(' ', '-'))}'>{escape(str(cell))}</td>"
                      for i, cell in enumerate(cells))
        body.append(f"<tr data-machine='{escape(g.trend.machine)}' data-axis='{escape(g.trend.axis)}' "
                    f"title='{escape(g.why)}'>{row}<td>{_spark(g)}</td></tr>")
    lead = (f"{len(glances)} axes in {store}, most urgent first. A re-check is due {margin_days} days before the "
            f"earliest day A + U may reach the tolerance (95 %), and at most {max_interval_days} days after the last "
            "campaign. Each plot: A ± U of every campaign that counts, the fitted drift continued to the due date, "
            "the tolerance (dashed red), the due date (orange).")
    table = f"<table class='plant'><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    return page("The plant at a glance", PLANT_CSS + f"<p>{escape(lead)}</p>" + table,
                f"as of {today.isoformat()}")

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

"""The plant at a glance (issue 30, item 4): `axiscal history plant` lists every machine and axis
with its last A ± U and verdict, the drift of A, the predicted crossing and the date the next
re-check is due, most urgent first; `--html` draws a small trend plot per axis and renders in
headless Chromium."""

from __future__ import annotations

import datetime as dt
import json
import re

import numpy as np
import pytest

from tests.test_history import db  # noqa: F401 - the store fixture, SQLite and PostgreSQL

TODAY = dt.datetime.now(dt.UTC).replace(tzinfo=None, microsecond=0)


def small_plant(url: str) -> dict[str, object]:
    """Four axes: two drifting histories with a tolerance (one near it), one whose last campaign is
    beyond its tolerance, one with two campaigns only. Returns their histories by machine."""
    from campaign.history.simulated import draw_history, record_drawn
    from campaign.history.store import open_store

    rng = np.random.default_rng(4)
    made = {}
    with open_store(url) as store:
        for machine, tolerance in (("lathe-1", 60.0), ("mill-2", 25.0), ("press-3", 3.0)):
            history = draw_history(rng, TODAY - dt.timedelta(days=20), growth=(3.0, 4.0), span=(800.0, 1000.0))
            record_drawn(store, history, machine, "X", tolerance)
            made[machine] = history
        short = draw_history(rng, TODAY - dt.timedelta(days=400), rechecks=(11, 11))
        short = type(short)(**{**short.__dict__, "dates": short.dates[-2:], "jump_at": 99})
        record_drawn(store, short, "grinder-4", "Z", 20.0)
        made["grinder-4"] = short
    return made


@pytest.mark.machine
def test_plant_lists_every_axis_with_its_due_date(cli, db, tmp_path):  # noqa: F811
    from campaign.history.location import store_url

    small_plant(store_url(db) or "")
    result = cli("history", "plant", "--json")
    assert result.code == 0, result.err
    plant = json.loads(result.out)
    axes = {(a["machine"], a["axis"]): a for a in plant["axes"]}
    assert set(axes) == {("lathe-1", "X"), ("mill-2", "X"), ("press-3", "X"), ("grinder-4", "Z")}
    for a in plant["axes"]:
        last = dt.date.fromisoformat(a["last"]["date"])
        due = dt.date.fromisoformat(a["due"])
        assert due <= last + dt.timedelta(days=365), a  # the plant's longest interval
        assert a["due_because"]
    press = axes[("press-3", "X")]
    assert press["state"] == "out" and plant["axes"][0]["state"] == "out" and press["due"] == press["last"]["date"]
    states = [a["state"] for a in plant["axes"]]
    assert states == sorted(states, key=lambda state: state != "out")  # beyond the tolerance first
    grinder = axes[("grinder-4", "Z")]
    assert grinder["drift_A"]["rate_per_year"] is None and "too few campaigns (2" in grinder["due_because"]
    assert grinder["state"] == "overdue"  # last campaign 400 days ago, the longest interval 365 days
    mill = axes[("mill-2", "X")]
    if mill["crossing"]["state"] == "predicted":  # due a margin before the earliest predicted crossing
        earliest = dt.date.fromisoformat(mill["crossing"]["earliest"])
        assert dt.date.fromisoformat(mill["due"]) == min(earliest - dt.timedelta(days=30),
                                                         dt.date.fromisoformat(mill["last"]["date"]) + dt.timedelta(days=365))
    dues = [a["due"] for a in plant["axes"] if a["state"] != "out"]
    assert dues == sorted(dues)  # then the most urgent first
    narrower = json.loads(cli("history", "plant", "--json", "--max-interval", "90", "--margin", "10").out)
    for a in narrower["axes"]:
        assert dt.date.fromisoformat(a["due"]) <= dt.date.fromisoformat(a["last"]["date"]) + dt.timedelta(days=90)
    for width in (60, 80):
        import os

        os.environ["COLUMNS"] = str(width)
        try:
            shown = cli("history", "plant")
        finally:
            del os.environ["COLUMNS"]
        rows = [line for line in shown.out.splitlines() if re.search(r"\d{4}-\d\d-\d\d", line) and "│" in line]
        assert len(rows) == 4 and all(len(line) <= width for line in shown.out.splitlines()), shown.out


def test_plant_refuses_a_bad_html_name(cli, tmp_path, monkeypatch):
    from tests.conftest import assert_one_line_error

    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "h.sqlite"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert_one_line_error(cli("history", "plant", "--html", tmp_path / "plant.png"), "--html", ".html")
    assert_one_line_error(cli("history", "plant", "--max-interval", "0"), "--max-interval")


@pytest.mark.machine
def test_plant_html_renders_in_headless_chromium(cli, tmp_path, monkeypatch):
    from tests.test_report import chromium

    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "h.sqlite"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    small_plant(f"sqlite:///{tmp_path / 'h.sqlite'}")
    page = tmp_path / "plant.html"
    result = cli("history", "plant", "--html", page)
    assert result.code == 0, result.err
    probe = tmp_path / "probe.html"  # the page as Chromium lays it out: each row's plot drawn, with its points
    probe.write_text(page.read_text().replace(
        "</body>", "<script>document.body.setAttribute('data-plots', Array.from(document.querySelectorAll("
                   "'svg.spark')).map(s => Math.round(s.getBoundingClientRect().width) + 'x' + "
                   "s.querySelectorAll('circle').length).join(','))</script></body>"))
    dom = chromium("--dump-dom", probe.as_uri(), tmp_path=tmp_path)
    assert "The plant at a glance" in dom and dom.count("<tr data-machine=") == 4
    plots = dom.split('data-plots="')[1].split('"')[0].split(",")
    assert len(plots) == 4, plots
    widths_and_points = [tuple(int(v) for v in p.split("x")) for p in plots]
    assert all(w >= 200 for w, _ in widths_and_points), plots
    assert min(n for _, n in widths_and_points) == 2 and max(n for _, n in widths_and_points) >= 11, plots
    assert dom.index("press-3") < dom.index("lathe-1")  # most urgent first

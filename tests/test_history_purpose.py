"""Campaigns by purpose and a readable history (issue 30, items 2 and 5): a follow-up or a
diagnostic is stored with its purpose, listed, never trended; a verification after a compensation
enters the trend as a known step; `history list` fits 80 and 60 columns; the store is named by a
short label; `compare` says first and second."""

from __future__ import annotations

import datetime as dt
import json
import re

import pytest

from campaign.config import config_with
from tests.test_history import db  # noqa: F401 - the store fixture, SQLite and PostgreSQL

END = dt.datetime(2026, 6, 1, 9, 0)


def write(directory, when: dt.datetime, lead_ppm: float, seed: int, machine: str = "m-purpose", **campaign: object):
    """One simulated re-check of the demo axis written as a campaign directory, its [campaign]
    keys changed as given (purpose, follows)."""
    from campaign.history.simulated import demo_config, recheck_config, write_campaign

    config = recheck_config(demo_config(), lead_ppm, 0.0, seed, machine)
    if campaign:
        config = config_with(config, {"campaign": campaign})
    return write_campaign(directory, config, when, {}, seed)


def history_with_purposes(root):
    """Eight re-checks a quarter apart, a follow-up and a diagnostic among them."""
    dirs = [write(root / f"c{i}", END - dt.timedelta(days=91 * (7 - i)), -6.0 - 0.75 * i, 10 + i) for i in range(8)]
    follow = write(root / "follow", END - dt.timedelta(days=91 * 3 - 5), -2.0, 99, purpose="follow-up",
                   follows=str(dirs[4]))
    diag = write(root / "diag", END - dt.timedelta(days=91 * 2 - 5), -30.0, 98, purpose="diagnostic")
    return dirs, follow, diag


@pytest.mark.machine
def test_follow_ups_and_diagnostics_are_listed_never_trended(cli, db, tmp_path):  # noqa: F811
    dirs, _, _ = history_with_purposes(tmp_path)
    assert cli("history", "import", tmp_path).code == 0
    listed = json.loads(cli("history", "list", "--json").out)["campaigns"]
    purposes = {c["label"]: c["purpose"] for c in listed}
    assert purposes["follow"] == "follow-up" and purposes["diag"] == "diagnostic" and purposes["c0"] == "acceptance"
    assert [c["follows"] for c in listed if c["label"] == "follow"] == [str(dirs[4])]
    assert [c["verdict"] for c in listed if c["label"] in ("follow", "diag")] == ["not judged", "not judged"]
    shown = cli("history", "list")
    assert "follow-up" in shown.out and "diagnostic" in shown.out
    trend = json.loads(cli("history", "trend", "m-purpose", "X", "--json").out)
    assert [c["label"] for c in trend["campaigns"]] == [d.name for d in dirs]
    reasons = {r["label"]: r["reason"] for r in trend["left_out"]}
    assert reasons["follow"].startswith(f"a follow-up of {dirs[4]}, not a re-check") and "never trended" in reasons["follow"]
    assert reasons["diag"].startswith("a diagnostic, not a re-check")
    assert trend["drift"]["A"]["significant"], trend["drift"]["A"]


@pytest.mark.machine
def test_a_verification_after_a_compensation_is_a_known_step(cli, db, tmp_path):  # noqa: F811
    """Six re-checks with a growing lead error, then a compensation (verified: the lead error
    nearly gone), then four more re-checks growing again at the same rate: the verification
    counts, the fit steps at it (it is not reported as a jump), and the rate is the one drift."""
    dirs = [write(tmp_path / f"c{i}", END - dt.timedelta(days=60 * (10 - i)), -6.0 - 0.8 * i, 30 + i)
            for i in range(6)]
    verify = write(tmp_path / "verify", END - dt.timedelta(days=60 * 4), -0.5 - 0.8 * 6, 40, purpose="verification",
                   follows=str(dirs[-1]))
    later = [write(tmp_path / f"d{i}", END - dt.timedelta(days=60 * (3 - i)), -0.5 - 0.8 * (7 + i), 50 + i)
             for i in range(4)]
    assert cli("history", "import", tmp_path).code == 0
    trend = json.loads(cli("history", "trend", "m-purpose", "X", "--json").out)
    labels = [c["label"] for c in trend["campaigns"]]
    assert labels == [d.name for d in dirs] + [verify.name] + [d.name for d in later]
    assert [s["label"] for s in trend["known_steps"]] == [verify.name]
    assert not any(j["after"]["label"] == verify.name for j in trend["change_points"]), trend["change_points"]
    step_dates = trend["drift"]["A"]["steps_between"]
    assert [dirs[-1].name[:0] + s[1] for s in step_dates] == [trend["campaigns"][6]["date"]]
    a = trend["drift"]["A"]
    truth = 0.8 * 6 * 600 / 1000  # 0.8 µm/m every 60 days over 600 mm: 2.9 µm a year
    assert a["significant"] and abs(a["rate_per_year"] - truth) <= a["U_rate_per_year"], a
    shown = cli("history", "trend", "m-purpose", "X")
    assert f"compensation verified by {verify.name}" in shown.out


@pytest.mark.parametrize("width", [60, 80])
def test_history_list_fits_the_terminal(cli, tmp_path, monkeypatch, width):
    """Each campaign one line within the width (it took five lines a row at 80 columns and broke
    letter by letter at 60); a long machine name is cut with an ellipsis."""
    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "h.sqlite"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    for i in range(3):
        write(tmp_path / "runs" / f"a-rather-long-campaign-directory-name-{i}", END - dt.timedelta(days=100 * i),
              -6.0, 60 + i, machine="press-line-4-station-2-horizontal-spindle")
    assert cli("history", "import", tmp_path / "runs").code == 0
    monkeypatch.setenv("COLUMNS", str(width))
    shown = cli("history", "list")
    lines = shown.out.rstrip("\n").splitlines()
    assert all(len(line) <= width for line in lines), shown.out
    rows = [line for line in lines if re.search(r"\d{4}-\d\d-\d\d", line)]
    assert len(rows) == 3, shown.out  # one line a campaign
    assert all("…" in row for row in rows) and all("± " in row for row in rows), shown.out
    assert "3 campaign(s) in h.sqlite" in shown.out and "sqlite:" not in shown.out


@pytest.mark.machine
def test_the_store_is_named_by_a_short_label(cli, tmp_path, monkeypatch):
    """After a campaign and in the report: the file name, never sqlite:////..."""
    from campaign.history.location import store_label

    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "store" / "plant.sqlite"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    dirs = [write(tmp_path / f"c{i}", END - dt.timedelta(days=100 * (2 - i)), -6.0 - i, 70 + i) for i in range(3)]
    converted = cli("convert", dirs[0] / "points.csv", "-o", tmp_path / "out.rtl")
    assert "history: added in plant.sqlite" in converted.err and "sqlite:" not in converted.err
    assert cli("history", "import", tmp_path).code == 0
    assert cli("report", dirs[-1], "-o", tmp_path / "r.html").code == 0
    page = (tmp_path / "r.html").read_text()
    assert "History of this axis" in page and "in plant.sqlite;" in page and "sqlite:" not in page
    assert store_label("postgresql+psycopg://bob:secret@db.plant:5432/axiscal") == "db.plant:5432/axiscal"


def test_compare_says_first_and_second(cli, tmp_path, monkeypatch):
    """ISO 230-2's A and B are accuracy and reversal: the two campaigns compared are the first and
    the second."""
    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "h.sqlite"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    for i in range(2):
        write(tmp_path / f"c{i}", END - dt.timedelta(days=100 * (1 - i)), -6.0 - 3 * i, 80 + i)
    assert cli("history", "import", tmp_path).code == 0
    shown = cli("history", "compare", "c0", "c1")
    assert shown.code == 0, shown.err
    assert "first: c0" in shown.out and "second: c1" in shown.out and "second − first" in shown.out
    assert "mean A" not in shown.out and "B − A" not in shown.out

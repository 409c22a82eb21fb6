"""The campaign store and its history (issue 27): the store on SQLite and on a real PostgreSQL
server (tests/pg_server.py), importing, the trend on a simulated history with a known truth, the
change point, the crossing date, compare, the hooks of convert and compensate, an unreachable
store and credentials. The SQLite cases are in the fast tier (but the acceptance test, which
simulates a few hundred campaigns for its truth); the PostgreSQL ones start a server and are in the
machine tier (the same tests, parametrized)."""

from __future__ import annotations

import datetime as dt
import functools
import json
import math
import sqlite3

import numpy as np
import pytest

from campaign.history.location import display_url, scrub, store_url
from campaign.history.trend import Observation, analyse, crossing
from tests.conftest import PAPER, assert_one_line_error
from tests.pg_server import PASSWORD


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.machine)])
def db(request, tmp_path, monkeypatch):
    """A new, empty store named by AXISCAL_DB: a SQLite file, or a database on the session's
    PostgreSQL server (its URL carries the superuser's password)."""
    if request.param == "sqlite":
        url = str(tmp_path / "store" / "history.sqlite")
    else:
        url = request.getfixturevalue("postgres_server").new_database()
    monkeypatch.setenv("AXISCAL_DB", url)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    return url


def no_password(*texts: str) -> None:
    for text in texts:
        assert PASSWORD not in text, text


# --- the simulated history and its truth ------------------------------------------------------

@functools.cache
def expected(lead_ppm: float, backlash_um: float, seeds: int = 30) -> tuple[float, float, float]:
    """(E[A], E[U_A], E[E]) of the demo axis with this lead error and reversal: the mean over many
    simulated campaigns (the fast simulator, new noise each), µm."""
    from campaign.assess import assess
    from campaign.discovery.simulate import simulate_campaign
    from campaign.history.simulated import demo_config, recheck_config
    from campaign.model import sim_model

    config = recheck_config(demo_config(), lead_ppm, backlash_um, 7)
    a, u, e = [], [], []
    for seed in range(seeds):
        result = assess(simulate_campaign(config, sim_model(config.sim), seed=5000 + seed), config)
        a.append(result.evaluation.summary["A"])
        u.append(result.uncertainty.expanded["A"])
        e.append(result.evaluation.summary["E"])
    return float(np.mean(a)), float(np.mean(u)), float(np.mean(e))


def true_drift(truth: dict) -> tuple[float, float]:
    """The true drift of A and E, µm/year, after the jump: their expected values at the first and
    the last lead error of the history, with the reversal after the jump, over the years between."""
    start = truth["lead_ppm_end"] + truth["growth_ppm_per_year"] * truth["years"]
    a0, _, e0 = expected(start, truth["backlash_um_after_jump"])
    a1, _, e1 = expected(truth["lead_ppm_end"], truth["backlash_um_after_jump"])
    return (a1 - a0) / truth["years"], (e1 - e0) / truth["years"]


def true_crossing(truth: dict, last: dt.date, tolerance: float) -> dt.date:
    """The day the expected A + U of the simulated axis reaches the tolerance, its lead error
    going on growing as it did (interpolated between expected values half a year apart)."""
    tau, previous = 0.0, None
    while tau < 10:
        a, u, _ = expected(truth["lead_ppm_end"] - truth["growth_ppm_per_year"] * tau, truth["backlash_um_after_jump"])
        if a + u >= tolerance:
            t0, v0 = previous
            share = (tolerance - v0) / (a + u - v0)
            return last + dt.timedelta(days=365.25 * (t0 + share * (tau - t0)))
        previous, tau = (tau, a + u), tau + 0.5
    raise AssertionError("the simulated axis never reaches its tolerance")


@pytest.mark.machine  # sweeps a few hundred simulated campaigns for the truth: seconds, not the fast tier
def test_simulated_history_trend_finds_the_truth(cli, db, tmp_path):
    """The acceptance: 12 re-checks over 2 years, the lead error growing at a known rate, one
    reversal jump; `history trend --json` gives the drift within its U of the truth, names the
    jump between the right two campaigns, and the crossing interval contains the true date."""
    made = cli("demo", "--history", "12", "--out", tmp_path / "history", "--json")
    assert made.code == 0, made.err
    demo = json.loads(made.out)
    truth = demo["truth"]
    assert truth["campaigns"] == 12 and truth["years"] == 2 and truth["jump_after_campaign"] == 7
    result = cli("history", "trend", demo["machine"], "X", "--json")
    assert result.code == 0, result.err
    trend = json.loads(result.out)
    no_password(result.out, result.err, made.out, made.err)
    assert len(trend["campaigns"]) == 12 and trend["left_out"] == []
    dates = [dt.date.fromisoformat(c["date"]) for c in trend["campaigns"]]
    assert 1.9 < (dates[-1] - dates[0]).days / 365.25 < 2.1

    rate_a, rate_e = true_drift(truth)
    for parameter, true_rate in (("A", rate_a), ("E", rate_e)):
        drift = trend["drift"][parameter]
        assert drift["significant"], drift
        assert abs(drift["rate_per_year"] - true_rate) <= drift["U_rate_per_year"], (parameter, drift, true_rate)
        assert drift["U_rate_per_year"] < abs(true_rate), drift  # a statement, not a shrug

    labels = [c["label"] for c in trend["campaigns"]]
    jumps_b = [j for j in trend["change_points"] if j["parameter"] == "B"]
    assert [(j["before"]["label"], j["after"]["label"]) for j in jumps_b] == [(labels[6], labels[7])]
    jump = jumps_b[0]
    assert abs(jump["jump"] - truth["backlash_um_after_jump"]) <= jump["U"]
    assert jump["sentence"].startswith(f"B rose {jump['jump']:.1f} ± {jump['U']:.1f} µm between {dates[6]} and {dates[7]}")
    assert all((j["before"]["label"], j["after"]["label"]) == (labels[6], labels[7]) for j in trend["change_points"])
    # R holds the reversal too (ISO 230-2's R_i contains |B_i|): its fit steps at B's jump, and the
    # simulated R does not drift (its fit read the jump as a drift, +1.6 ± 0.7 µm/year, before)
    step = [[dates[6].isoformat(), dates[7].isoformat()]]
    assert trend["drift"]["R"]["steps_between"] == step and not trend["drift"]["R"]["significant"], trend["drift"]["R"]

    c = trend["crossing"]
    assert c["state"] == "predicted" and c["tolerance"] == truth["tolerance_um"] == 15.0, c
    true_day = true_crossing(truth, dates[-1], truth["tolerance_um"])
    earliest = dt.date.fromisoformat(c["earliest"])
    latest = dt.date.fromisoformat(c["latest"]) if c["latest"] else dt.date.max
    assert earliest <= true_day <= latest, (c, true_day)
    assert earliest <= dt.date.fromisoformat(c["date"]) <= latest
    assert earliest > dates[-1]  # the axis is still within its tolerance at the last re-check


@pytest.mark.machine
def test_trend_table_plot_and_list(cli, db, tmp_path):
    made = json.loads(cli("demo", "--history", "5", "--out", tmp_path / "h", "--json").out)
    shown = cli("history", "trend", made["machine"], "X", "--plot", tmp_path / "trend.png")
    assert shown.code == 0, shown.err
    assert "drift per year" in shown.out and "A: +" in shown.out
    assert (tmp_path / "trend.png").stat().st_size > 10_000
    listed = json.loads(cli("history", "list", "--machine", made["machine"], "--json").out)["campaigns"]
    assert len(listed) == 5 and all(c["command"] == "demo" for c in listed)
    first_day = listed[0]["measured_utc"][:10]
    since = cli("history", "list", "--machine", made["machine"], "--since",
                (dt.date.fromisoformat(first_day) + dt.timedelta(days=1)).isoformat(), "--json")
    assert len(json.loads(since.out)["campaigns"]) == 4
    until = cli("history", "list", "--until", first_day, "--json")
    assert [c["label"] for c in json.loads(until.out)["campaigns"]] == [listed[0]["label"]]
    assert len(json.loads(cli("history", "list", "--verdict", "pass", "--json").out)["campaigns"]) == 5
    assert json.loads(cli("history", "list", "--verdict", "fail", "--json").out)["campaigns"] == []
    assert cli("history", "list", "--axis", "X").code == 0


def test_import_is_idempotent_and_rebuilds_the_store(cli, db, tmp_path):
    made = json.loads(cli("demo", "--history", "4", "--out", tmp_path / "h", "--json").out)
    again = json.loads(cli("history", "import", tmp_path / "h", "--json").out)
    assert (again["added"], again["updated"], again["unchanged"]) == (0, 0, 4)
    rebuilt = tmp_path / "rebuilt.sqlite"
    first = json.loads(cli("history", "import", tmp_path / "h", "--db", rebuilt, "--json").out)
    second = json.loads(cli("history", "import", tmp_path / "h", "--db", rebuilt, "--json").out)
    assert (first["added"], second["added"], second["unchanged"]) == (4, 0, 4)
    counts = json.loads(cli("history", "store", "--db", rebuilt, "--json").out)
    assert counts["campaigns"] == 4 and counts["points"] == 4 * 110
    trend = json.loads(cli("history", "trend", made["machine"], "X", "--db", rebuilt, "--json").out)
    assert len(trend["campaigns"]) == 4
    rebuilt_trend = json.loads(cli("history", "trend", made["machine"], "X", "--json").out)
    assert trend["drift"] == rebuilt_trend["drift"] and trend["crossing"] == rebuilt_trend["crossing"]


def test_compare_two_campaigns(cli, db, tmp_path):
    json.loads(cli("demo", "--history", "3", "--out", tmp_path / "h", "--json").out)
    dirs = sorted((tmp_path / "h").iterdir())
    result = cli("history", "compare", dirs[0], dirs[-1], "--json", "--plot", tmp_path / "cmp.png")
    assert result.code == 0, result.err
    c = json.loads(result.out)
    assert len(c["targets"]) == 11 and c["targets_not_in_both"] == 0
    at_end = c["targets"][-1]  # 600 mm: the lead error grew by 6 µm/m over 2 years: about -3.6 µm there
    assert at_end["target"] == 600.0 and at_end["difference"] < -at_end["U"] < 0
    assert c["targets"][0]["U"] > 0 and abs(c["targets"][0]["difference"]) < c["targets"][0]["U"]  # 0 mm: no change
    assert (tmp_path / "cmp.png").stat().st_size > 10_000
    table = cli("history", "compare", dirs[0], dirs[-1])
    assert "differs beyond its uncertainty" in table.out and " µm at " in " ".join(table.out.split())
    assert "other_axis" not in c and "two axes" not in table.out
    assert_one_line_error(cli("history", "compare", "nosuch", dirs[0]), "no such campaign")
    # a campaign of another machine: compared, and said to be two axes, not one over time
    assert cli("demo", "--fake", "--out", tmp_path / "other").code == 0
    other = cli("history", "compare", dirs[0], tmp_path / "other")
    assert other.code == 0, other.err
    assert "this compares two axes, not one axis over time" in " ".join(other.out.split())


def test_convert_and_compensate_are_recorded(cli, db, tmp_path):
    from campaign.history.location import store_url as url_of
    from campaign.history.store import open_store

    source = tmp_path / "before.csv"
    source.write_text("# date: 2026-01-05\n" + (PAPER / "horizontal_before.csv").read_text())
    converted = cli("convert", source, "-o", tmp_path / "before.rtl")
    assert converted.code == 0, converted.err
    assert "history: added" in converted.err
    back = cli("convert", tmp_path / "before.rtl", "-o", tmp_path / "again.csv")
    assert back.code == 0 and "history: added" in back.err
    table = cli("compensate", source, "--format", "linuxcnc", "-o", tmp_path / "comp.tbl")
    assert table.code == 0, table.err
    with open_store(url_of()) as store:
        rows = store.campaigns()
        tables = store.comp_tables()
    assert [r["command"] for r in rows] == ["convert", "convert"]
    assert [r["source"] for r in rows] == ["converted", "converted"]  # what they are: converted tables
    assert rows[0]["fingerprint"] == rows[1]["fingerprint"]  # one measurement, carried by two files
    assert len(tables) == 1 and tables[0]["format"] == "linuxcnc"
    assert tables[0]["text"] == (tmp_path / "comp.tbl").read_text()
    assert tables[0]["campaign_id"] == rows[0]["id"] and tables[0]["provenance"]["software"].startswith("axiscal")
    machine, axis = rows[0]["machine"], rows[0]["axis"]
    # converted tables are not campaigns of their own (issue 31 item 5): not listed, never trended
    listed = json.loads(cli("history", "list", "--json").out)
    assert listed["campaigns"] == [] and listed["converted_not_listed"] == 2
    shown = cli("history", "list")
    assert "0 campaign(s)" in shown.out and "2 converted table(s)" in shown.out
    assert len(json.loads(cli("history", "list", "--all", "--json").out)["campaigns"]) == 2
    trend = json.loads(cli("history", "trend", machine, axis, "--json").out)
    assert trend["campaigns"] == [] and all("a converted table" in r["reason"] for r in trend["left_out"])
    # unless asked: imported on purpose, the table is a measurement of its own
    imported = json.loads(cli("history", "import", source, "--json").out)
    assert imported["updated"] == 1, imported
    trend = json.loads(cli("history", "trend", machine, axis, "--json").out)
    assert [c["label"] for c in trend["campaigns"]] == ["before.csv"]
    assert trend["drift"]["A"]["reason"].startswith("too few campaigns (1")


def test_unreachable_store_never_stops_a_campaign(cli, db, tmp_path, monkeypatch, request):
    """The store cannot be reached: the command ends normally and says so in one line, the
    campaign waits in the queue; when the same store can be reached again, the next use of it
    records what waited."""
    from campaign.history.simulated import simulate_history

    _, dirs = simulate_history(tmp_path / "h", campaigns=2)
    if db.startswith("postgresql"):  # a role that does not exist yet: refused until it is made
        server = request.getfixturevalue("postgres_server")
        later = db.replace("axiscal:", "late_user:")

        def reachable() -> None:
            import psycopg

            with psycopg.connect(server.url(), autocommit=True) as conn:
                conn.execute(f"CREATE ROLE late_user LOGIN SUPERUSER PASSWORD '{PASSWORD}'")
    else:  # its folder cannot be made while a file stands in the way
        (tmp_path / "in-the-way").write_text("")
        later = str(tmp_path / "in-the-way" / "history.sqlite")

        def reachable() -> None:
            (tmp_path / "in-the-way").unlink()
    monkeypatch.setenv("AXISCAL_DB", later)
    converted = cli("convert", dirs[0] / "points.csv", "-o", tmp_path / "out.rtl")
    assert converted.code == 0 and (tmp_path / "out.rtl").is_file()
    told = [line for line in converted.err.splitlines() if line.startswith("history:")]
    assert len(told) == 1 and "unreachable" in told[0] and "queued" in told[0], converted.err
    no_password(converted.err, converted.out)
    failed = cli("history", "list")
    assert_one_line_error(failed, "unreachable")
    no_password(failed.err)
    # another store, where nothing was ever recorded: the queue is not for it, and reading makes no store
    assert_one_line_error(cli("history", "store", "--db", db, "--json"), "no store at")
    assert_one_line_error(cli("history", "list", "--db", db, "--json"), "no store at")
    reachable()
    listed = cli("history", "list", "--json")
    assert listed.code == 0, listed.err
    assert [c["label"] for c in json.loads(listed.out)["campaigns"]] == [dirs[0].name]
    assert [c["command"] for c in json.loads(listed.out)["campaigns"]] == ["convert"]
    assert json.loads(cli("history", "store", "--json").out)["waiting"] == 0


def test_credentials_never_shown(cli, db, tmp_path):
    if not db.startswith("postgresql"):
        pytest.skip("a SQLite file has no credentials")
    from campaign.history.simulated import simulate_history

    simulate_history(tmp_path / "h", campaigns=2)
    for args in (("history", "store", "--db", db), ("history", "store", "--db", db, "--json"),
                 ("history", "import", tmp_path / "h", "--db", db)):
        result = cli(*args)
        no_password(result.out, result.err)
        if args[1] == "store":  # where the store is in full: its URL, the password masked
            assert "***@127.0.0.1" in result.out + result.err
        else:  # the store's short label: host and database, no URL at all
            assert result.out.startswith("127.0.0.1:") and "@" not in result.out, result.out
    wrong = db.replace(PASSWORD, PASSWORD + "-wrong")
    refused = cli("history", "list", "--db", wrong)
    assert_one_line_error(refused, "unreachable")
    no_password(refused.err)
    assert "-wrong" not in refused.err


def test_credentials_with_a_slash_or_in_the_query_never_shown(cli, db, tmp_path):
    """A password holding '/' (SQLAlchemy reads 'bob:pa/ss@host' as password 'pa/ss') and a
    password given as a query item (?password=...): both connect, and neither shows in what the
    commands print (both printed it before)."""
    if not db.startswith("postgresql"):
        pytest.skip("a SQLite file has no credentials")
    import uuid

    import psycopg
    from sqlalchemy.engine import make_url

    from campaign.history.simulated import simulate_history

    simulate_history(tmp_path / "h", campaigns=2)
    given = make_url(db)
    role, secret = f"slash_{uuid.uuid4().hex[:8]}", "pa/ss-Slash-27"
    with psycopg.connect(host=given.host, port=given.port, user=given.username, password=given.password,
                         dbname=given.database, autocommit=True) as conn:
        conn.execute(f"CREATE ROLE {role} LOGIN SUPERUSER PASSWORD '{secret}'")
    base = f"postgresql://{{}}@{given.host}:{given.port}/{given.database}"
    for url, hidden in ((base.format(f"{role}:{secret}"), secret),
                        (base.format(given.username) + f"?password={PASSWORD}&connect_timeout=5", PASSWORD)):
        for args in (("history", "import", tmp_path / "h", "--db", url), ("history", "store", "--db", url),
                     ("history", "store", "--db", url, "--json")):
            result = cli(*args)
            assert result.code == 0, result.err
            assert hidden not in result.out + result.err and "ss-Slash" not in result.out + result.err, result.out
            assert f"{given.host}:{given.port}/{given.database}" in result.out + result.err


@pytest.mark.parametrize("url, secret", [("postgresql://bob:pa/ss@127.0.0.1:1/x", "pa/ss"),
                                         ("postgresql://bob@127.0.0.1:1/x?password=hunter2", "hunter2")])
def test_an_unreachable_store_never_shows_its_password(cli, tmp_path, monkeypatch, url, secret):
    """Nothing listens on port 1: the error of a history command and the line after a campaign
    name the store without the password (both printed it before)."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    refused = cli("history", "store", "--db", url)
    assert_one_line_error(refused, "unreachable", "bob")
    assert secret not in refused.err and "ss@" not in refused.err, refused.err
    monkeypatch.setenv("AXISCAL_DB", url)
    converted = cli("convert", PAPER / "horizontal_before.csv", "-o", tmp_path / "out.rtl")
    assert converted.code == 0, converted.err
    told = [line for line in converted.err.splitlines() if line.startswith("history:")]
    assert len(told) == 1 and "queued" in told[0] and "127.0.0.1" in told[0], converted.err
    assert secret not in converted.err + converted.out and "ss@" not in converted.err, converted.err
    assert secret not in (tmp_path / "xdg" / "axiscal" / "pending.jsonl").read_text()


# --- the pieces, without a store ----------------------------------------------------------------

def test_location_masks_credentials(monkeypatch, tmp_path):
    url = "postgresql://plant:s3cr%40t@db.example:5432/axiscal"
    assert display_url(url) == "postgresql://plant:***@db.example:5432/axiscal"
    assert "s3cr" not in scrub(f"connection to {url} failed: password=s3cr@t rejected", url)
    slash = "postgresql://bob:pa/ss@db/x?sslpassword=k3y&password=hunter2&sslmode=require"
    assert display_url(slash) == "postgresql://bob:***@db/x?sslmode=require"
    message = scrub(f"{slash} failed: pa/ss, k3y, hunter2 or pa%2Fss", slash)
    assert not any(s in message for s in ("pa/ss", "k3y", "hunter2", "pa%2Fss")), message
    assert store_url(url).startswith("postgresql+psycopg://plant:s3cr%40t@")
    assert store_url(str(tmp_path / "h.sqlite")) == f"sqlite:///{tmp_path / 'h.sqlite'}"
    monkeypatch.setenv("AXISCAL_DB", "none")
    assert store_url() is None
    monkeypatch.setenv("AXISCAL_DB", "")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    assert store_url() == f"sqlite:///{tmp_path / 'axiscal' / 'history.sqlite'}"


def test_sqlite_store_is_in_wal_mode(cli, tmp_path, monkeypatch):
    path = tmp_path / "h.sqlite"
    assert cli("history", "store", "--db", path, "--upgrade").code == 0
    assert sqlite3.connect(path).execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def series(values, us, start=dt.datetime(2024, 1, 1), days=60):
    return [Observation(start + dt.timedelta(days=days * i), f"c{i}", v, u) for i, (v, u) in enumerate(zip(values, us))]


def test_trend_says_when_it_cannot_predict():
    fits, jumps = analyse({"A": series([5.0, 5.1], [1.0, 1.0])})
    assert fits["A"].rate is None and "too few campaigns (2" in fits["A"].reason
    assert crossing(fits["A"], 10.0).state == "not predictable"
    flat = series([5.0, 5.2, 4.9, 5.1, 5.0, 4.95], [1.0] * 6)
    fits, jumps = analyse({"A": flat})
    assert not fits["A"].significant and jumps == []
    c = crossing(fits["A"], 10.0)
    assert c.state == "not predictable" and "no significant upward drift" in c.reason
    assert "no tolerance" in crossing(fits["A"], None).reason
    assert crossing(fits["A"], 5.5).state == "already"


def test_trend_rate_interval_covers_the_truth_most_of_the_time():
    """Synthetic series (a known rate, one jump, scatter smaller than U as in real budgets): the
    stated 95 % interval of the rate covers the truth in most of 200 histories, and the jump is
    found between the right campaigns nearly always."""
    rng = np.random.default_rng(27)
    covered = found = 0
    for _ in range(200):
        t = np.arange(12) / 6.0  # years
        truth = 1.0 + 0.8 * t + np.where(np.arange(12) >= 7, 2.5, 0.0)
        values = truth + rng.normal(0, 0.3, 12)
        obs = series(values, [1.2] * 12, days=int(365.25 / 6))
        fits, jumps = analyse({"A": obs})
        covered += abs(fits["A"].rate - 0.8) <= fits["A"].U_rate
        found += [(j.before.label, j.after.label) for j in jumps] == [("c6", "c7")]
    assert covered >= 180 and found >= 190, (covered, found)


@pytest.mark.machine
def test_report_shows_the_axis_history(cli, db, tmp_path, monkeypatch):
    made = json.loads(cli("demo", "--history", "3", "--out", tmp_path / "h", "--json").out)
    last = max((tmp_path / "h").iterdir())
    assert cli("report", last, "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    assert "<h2>History of this axis</h2>" in html and f"3 campaigns of machine {made['machine']}, axis X" in html
    assert "alt='The axis over its campaigns' src='data:image/png;base64," in html
    assert html.count("<td>recheck-0") == 3 and "drift not determined (too few campaigns (3" in html
    no_password(html)
    monkeypatch.setenv("AXISCAL_DB", "none")
    assert cli("report", last, "-o", tmp_path / "r2.html").code == 0
    assert "History of this axis" not in (tmp_path / "r2.html").read_text()


def dated_tables(tmp_path, dates: list[str], machine: str = "m1") -> list:
    """Point tables of the paper's axis, one per date (`# date:`), each a little different (so
    each counts: a copy of one measurement would count once)."""
    rows = (PAPER / "horizontal_before.csv").read_text().splitlines()
    tables = []
    for i, day in enumerate(dates):
        header, first, *rest = rows
        run, direction, target, deviation = first.split(",")
        changed = f"{run},{direction},{target},{float(deviation) - 0.01 * i:.2f}"
        path = tmp_path / f"t{i}.csv"
        path.write_text("\n".join([f"# date: {day}", f"# machine: {machine}", "# axis: X", header, changed, *rest]) + "\n")
        tables.append(path)
    return tables


@pytest.mark.machine
def test_campaigns_sharing_one_time_give_no_drift(cli, db, tmp_path):
    """Three campaigns dated alike: the drift is not determined (the campaigns span no time) and
    the crossing not predictable, in the trend and in the report (an internal error before)."""
    tables = dated_tables(tmp_path, ["2025-03-01"] * 3)
    assert cli("history", "import", *tables).code == 0
    result = cli("history", "trend", "m1", "X", "--tolerance", "30", "--json")
    assert result.code == 0, result.err
    trend = json.loads(result.out)
    assert len(trend["campaigns"]) == 3
    for parameter in "AEBR":
        drift = trend["drift"][parameter]
        assert drift["rate_per_year"] is None and drift["reason"].startswith("the campaigns span no time"), drift
    assert trend["crossing"]["state"] == "not predictable" and "span no time" in trend["crossing"]["reason"]
    shown = cli("history", "trend", "m1", "X", "--plot", tmp_path / "t.png")
    assert shown.code == 0 and "A: drift not determined (the campaigns span no time" in shown.out, shown.err
    assert cli("report", tables[0], "-o", tmp_path / "r.html").code == 0
    assert "drift not determined (the campaigns span no time" in (tmp_path / "r.html").read_text()


def test_a_segment_spanning_no_time_gives_no_drift():
    """Two campaigns on one day, a jump, two more on another day: the step and the drift cannot be
    told apart; said so, no singular matrix."""
    day1, day2 = dt.datetime(2025, 1, 1), dt.datetime(2025, 6, 1)
    obs = [Observation(when, f"c{i}", v, 0.5) for i, (when, v) in
           enumerate([(day1, 1.0), (day1, 1.1), (day2, 5.0), (day2, 5.1)])]
    fits, jumps = analyse({"A": obs})
    assert [(j.before.label, j.after.label) for j in jumps] == [("c1", "c2")]
    assert fits["A"].rate is None and "between the jumps set apart span no time" in fits["A"].reason
    assert crossing(fits["A"], 10.0).state == "not predictable"


def started_campaign(directory, machine: str = "m0"):
    """A campaign directory as a campaign killed before its first point leaves it: its config,
    plan, meta and start record, no point."""
    from campaign.config import recorded_sections
    from campaign.history.simulated import demo_config, recheck_config
    from campaign.plan import build_plan, plan_records
    from campaign.record import Recorder

    config = recheck_config(demo_config(), -7.0, 0.0, 1, machine)
    plan, sections = build_plan(config), recorded_sections(config)
    meta = {"machine": machine, "axis": "X", "kind": "linear", "points_planned": len(plan.points),
            "created": "2025-01-01T00:00:00+00:00"}
    recorder = Recorder.create(directory, config.text, sections, plan_records(plan, sections), meta, "linear")
    recorder.start(0.0, 0, len(plan.points))
    recorder.close()
    return directory


def test_compare_with_a_campaign_of_no_point_is_one_error(cli, db, tmp_path):
    """A campaign killed before its first point is recorded (0 points); comparing it is one
    error line, exit 2 (a ValueError from max() before)."""
    from campaign.history.simulated import simulate_history

    empty = started_campaign(tmp_path / "empty", "m0")
    _, dirs = simulate_history(tmp_path / "h", campaigns=1, machine="m0")
    imported = json.loads(cli("history", "import", empty, dirs[0], "--json").out)
    assert imported["added"] == 2 and imported["failed"] == []
    for pair in ((empty, dirs[0]), (dirs[0], empty)):
        assert_one_line_error(cli("history", "compare", *pair), "has no point recorded", "empty")
    trend = json.loads(cli("history", "trend", "m0", "X", "--json").out)
    [reason] = [r["reason"] for r in trend["left_out"]]
    assert reason.startswith("not finished (0 of 110 points; no stop recorded") and "axiscal resume" in reason


def test_readers_never_wait_for_the_writer(cli, tmp_path, monkeypatch):
    """Another process holds SQLite's write lock (a long import, say): opening the store and
    reading it go on at once; a write waits its turn. Before, every transaction took BEGIN
    IMMEDIATE and a reader waited (here, with a 0.3 s busy timeout, it failed)."""
    from campaign.history import store as store_module
    from campaign.history.simulated import simulate_history
    from campaign.history.store import StoreUnavailable, open_store

    path = tmp_path / "h.sqlite"
    monkeypatch.setenv("AXISCAL_DB", str(path))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    _, dirs = simulate_history(tmp_path / "h", campaigns=2)
    assert cli("history", "import", dirs[0]).code == 0
    monkeypatch.setattr(store_module, "BUSY_TIMEOUT_MS", 300)
    writer = sqlite3.connect(path, isolation_level=None)
    writer.execute("BEGIN IMMEDIATE")  # the write lock, held
    try:
        with open_store(f"sqlite:///{path}") as store:
            assert [r["label"] for r in store.campaigns()] == [dirs[0].name]
            with pytest.raises(StoreUnavailable, match="locked"):
                store.put(__import__("campaign.history.entry", fromlist=["path_entry"]).path_entry(dirs[1]))
        listed = cli("history", "list", "--json")
        assert listed.code == 0 and len(json.loads(listed.out)["campaigns"]) == 1, listed.err
    finally:
        writer.execute("ROLLBACK")
        writer.close()


def test_the_queue_is_not_locked_while_recording(tmp_path, monkeypatch):
    """Draining the queue records each waiting item without holding the queue's lock (a campaign
    ending meanwhile in another process queues at once, and its line stays); an item whose
    source is gone leaves the queue and is told (one sentence each)."""
    import fcntl
    import os

    from campaign.history.pending import drain, enqueue, queue_path

    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    url, other = "sqlite:///one.sqlite", "sqlite:///other.sqlite"
    for store, path in ((url, "a"), (other, "b"), (url, "gone")):
        enqueue(store, {"kind": "campaign", "path": path})

    def record(item):
        fd = os.open(queue_path().with_suffix(".lock"), os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # BlockingIOError while the queue is locked
        finally:
            os.close(fd)
        enqueue(url, {"kind": "campaign", "path": f"ended-during-{item['path']}"})
        if item["path"] == "gone":
            raise LookupError("gone: it was waiting to be recorded and is not")

    done, problems = drain(url, record)
    assert (done, problems) == (1, ["dropped from the queue: gone: it was waiting to be recorded and is not"])
    left = [json.loads(line)["path"] for line in queue_path().read_text().splitlines()]
    assert left == ["b", "ended-during-a", "ended-during-gone"]


def test_a_dropped_queue_item_is_told(cli, tmp_path, monkeypatch):
    """A campaign waits in the queue, then its directory moves: the next campaign's end records
    its own and says, in one more line, that the moved one was dropped from the queue."""
    from campaign.history.simulated import simulate_history

    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    _, dirs = simulate_history(tmp_path / "h", campaigns=2)
    (tmp_path / "in-the-way").write_text("")
    monkeypatch.setenv("AXISCAL_DB", str(tmp_path / "in-the-way" / "history.sqlite"))
    assert "queued" in cli("convert", dirs[0] / "points.csv", "-o", tmp_path / "a.rtl").err
    (tmp_path / "in-the-way").unlink()
    dirs[0].rename(tmp_path / "moved")
    converted = cli("convert", dirs[1] / "points.csv", "-o", tmp_path / "b.rtl")
    assert converted.code == 0, converted.err
    told = [line for line in converted.err.splitlines() if line.startswith("history:")]
    assert told[0] == "history: added in history.sqlite" and len(told) == 2, converted.err  # a label, not a URL
    assert told[1].startswith("history: warning: dropped from the queue: ") and dirs[0].name in told[1]


def test_a_stalled_postgresql_store_never_hangs_a_campaign(cli, db, tmp_path, monkeypatch):
    """Another session holds a lock on the campaigns table: with the store's lock timeout (1 s
    here) a campaign's end queues its campaign and `history import` is one error line, instead of
    waiting as long as the lock is held (released after 20 s: before, both waited and then
    recorded). Sessions carry the statement and lock timeouts."""
    if not db.startswith("postgresql"):
        pytest.skip("SQLite's busy timeout is tested above")
    import threading

    import psycopg

    from campaign.history import store as store_module
    from campaign.history.simulated import simulate_history
    from campaign.history.store import open_store

    _, dirs = simulate_history(tmp_path / "h", campaigns=1)
    with open_store(store_url()) as store:  # made and migrated
        with store.engine.connect() as conn:
            shown = {name: conn.exec_driver_sql(f"SHOW {name}").scalar() for name in ("statement_timeout", "lock_timeout")}
        assert shown == {"statement_timeout": "1min", "lock_timeout": "30s"}, shown
    monkeypatch.setattr(store_module, "LOCK_TIMEOUT_S", 1)
    holder = psycopg.connect(db)
    holder.execute("LOCK TABLE campaigns IN ACCESS EXCLUSIVE MODE")
    release = threading.Timer(20.0, holder.rollback)
    release.start()
    try:
        converted = cli("convert", dirs[0] / "points.csv", "-o", tmp_path / "a.rtl")
        told = [line for line in converted.err.splitlines() if line.startswith("history:")]
        assert converted.code == 0 and len(told) == 1 and "queued" in told[0] and "lock timeout" in told[0], told
        assert_one_line_error(cli("history", "import", dirs[0]), "unreachable", "lock timeout")
    finally:
        release.cancel()
        holder.rollback()
        holder.close()


def test_one_verification_linked_by_two_processes_at_once(cli, db, tmp_path):
    """Two imports of the same verification at once: one has written its link and not yet
    committed when the other writes it; the second waits and then updates the row (an upsert).
    Before (delete, then insert), the second failed with a unique-key violation, an internal error."""
    if not db.startswith("postgresql"):
        pytest.skip("SQLite writers take turns at BEGIN IMMEDIATE: they cannot interleave")
    import threading
    import time

    import psycopg

    from campaign.history.entry import path_entry
    from campaign.history.simulated import simulate_history
    from campaign.history.store import open_store

    _, dirs = simulate_history(tmp_path / "h", campaigns=1)
    with open_store(store_url()) as store:
        campaign_id, _ = store.put(path_entry(dirs[0]))
        other = psycopg.connect(db)  # the other import, in the middle of its transaction
        other.execute("INSERT INTO verifications (campaign_id, before_id, before_location, compensation) "
                      "VALUES (%s, NULL, 'first', '{}')", (campaign_id,))
        failed: list[BaseException] = []

        def link() -> None:
            try:
                store.link_verification(campaign_id, None, "second", {"table": "t"})
            except BaseException as exc:  # noqa: BLE001 - reported below
                failed.append(exc)

        thread = threading.Thread(target=link)
        thread.start()
        with psycopg.connect(db, autocommit=True) as watcher:  # until the second waits on the first's row
            for _ in range(600):
                if watcher.execute("SELECT count(*) FROM pg_locks WHERE NOT granted").fetchone()[0]:
                    break
                time.sleep(0.05)
            else:
                raise AssertionError("the second writer never waited for the first")
        other.commit()
        other.close()
        thread.join(timeout=60)
        assert not thread.is_alive() and failed == [], failed
        row = store.verification_of(campaign_id)
        assert row is not None and row["before_location"] == "second" and row["compensation"] == {"table": "t"}


def test_drift_uncertainty_never_shrinks_below_the_campaigns_u():
    """Four campaigns on an exact line, U = 0.5: the rate's U is what their U give (k = 2, not
    scaled by χ²/ν ≈ 0), not ± 0.00 with a one-day crossing interval; campaigns scattering more
    than their U say widen it (Student's t for ν)."""
    from scipy.stats import t as student

    exact = series([5.0 + 0.37 * i * 120 / 365.25 for i in range(4)], [0.5] * 4, days=120)
    fit = analyse({"A": exact})[0]["A"]
    years = np.array([i * 120 / 365.25 for i in range(4)])
    stated = 2 * 0.25 / math.sqrt(np.sum((years - years.mean()) ** 2))
    assert fit.k == 2.0 and fit.U_rate == pytest.approx(stated, rel=1e-9), fit.sentence("µm")
    assert fit.rate == pytest.approx(0.37)
    assert crossing(fit, 10.0).state == "not predictable"  # +0.37 ± 0.68: not significant
    scattered = series([5.0, 6.1, 5.0, 6.1, 5.0, 6.1], [1.0] * 6, days=120)
    fit = analyse({"A": scattered})[0]["A"]
    assert fit.birge > 1 and fit.k == pytest.approx(float(student.ppf(0.975, 4)))


def test_a_jump_steps_only_the_parameters_it_moves():
    """A jump of R alone does not put a step into A's line (which then keeps all its campaigns for
    one drift); a jump of B steps A, E and R, which contain the reversal."""
    days = 60
    steady = [1.0 + 0.5 * i * days / 365.25 for i in range(8)]
    r_jumps = [1.0] * 4 + [4.0] * 4
    fits, jumps = analyse({"A": series(steady, [0.6] * 8), "R": series(r_jumps, [0.6] * 8)})
    assert [(j.parameter, j.after.label) for j in jumps] == [("R", "c4")]
    assert fits["A"].step_at == [] and fits["A"].dof == 6 and fits["R"].step_at == [4]
    fits, jumps = analyse({"A": series(steady, [0.6] * 8), "B": series(r_jumps, [0.6] * 8),
                           "E": series(steady, [0.6] * 8), "R": series([1.0] * 8, [0.6] * 8)})
    assert [(j.parameter, j.after.label) for j in jumps] == [("B", "c4")]
    assert fits["A"].step_at == fits["E"].step_at == fits["B"].step_at == fits["R"].step_at == [4]


def test_simulated_history_records_its_truth_in_each_recheck(tmp_path):
    """Each re-check's meta.json holds the history's truth as the demo reports it: the travel
    measured (600 mm on the demo axis) and the lead error's growth over it (3 µm/m a year, a
    plant's rate: 1.8 µm a year) and the tolerance its re-checks state; the first two were recorded
    as 0.0."""
    from campaign.history.simulated import simulate_history
    from campaign.record import META_FILE

    truth, dirs = simulate_history(tmp_path / "h", campaigns=3)
    assert truth.span_mm == 600.0 and truth.lead_growth_um_per_year == pytest.approx(1.8)
    for number, directory in enumerate(dirs, start=1):
        recorded = json.loads((directory / META_FILE).read_text())["simulated_history"]
        assert recorded == {**truth.as_json(), "recheck": number, "lead_ppm": recorded["lead_ppm"],
                            "backlash_um": 2.5 if number > truth.jump_after else 0.0}
        assert recorded["span_mm"] == 600.0 and recorded["lead_growth_um_per_year"] == pytest.approx(1.8)
        assert recorded["tolerance_um"] == 15.0 and "tolerance = 15.0" in (directory / "config.toml").read_text()


def test_the_report_never_creates_or_migrates_a_store(cli, db, tmp_path):
    """The report of a campaign with a store named that does not exist yet (a SQLite file) or
    holds nothing (a new PostgreSQL database): no history section, and no store made, no table
    created (on PostgreSQL the report migrated the empty database before)."""
    from campaign.history.simulated import simulate_history

    _, dirs = simulate_history(tmp_path / "h", campaigns=1)
    assert cli("report", dirs[0], "-o", tmp_path / "r.html").code == 0
    assert "History of this axis" not in (tmp_path / "r.html").read_text()
    if db.startswith("postgresql"):
        import psycopg

        with psycopg.connect(db) as conn:
            tables = conn.execute("SELECT table_name FROM information_schema.tables "
                                  "WHERE table_schema = 'public'").fetchall()
        assert tables == []
    else:
        assert not (tmp_path / "store").exists()


def test_an_axis_whose_only_campaign_was_killed_says_so(cli, db, tmp_path):
    """The trend of an axis whose one campaign never finished says the campaign does not count and
    why, and the crossing says there is no campaign to judge from, not that no tolerance is
    recorded (the demo config has one: it said 'no tolerance on A is recorded' before)."""
    killed = started_campaign(tmp_path / "killed", "m9")
    assert cli("history", "import", killed).code == 0
    trend = json.loads(cli("history", "trend", "m9", "X", "--json").out)
    assert trend["campaigns"] == [] and len(trend["left_out"]) == 1
    assert trend["crossing"]["state"] == "not predictable"
    assert "no campaign that counts" in trend["crossing"]["reason"], trend["crossing"]

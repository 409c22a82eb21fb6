"""A store that never breaks a campaign (issue 30, item 3): a store at a revision this axiscal does
not know is refused in one sentence and the campaign queued; a shared server store is migrated
only by `history store --upgrade`, an embedded SQLite file migrates itself (and the migration fills
in each campaign's uncertainty between re-checks); recording after the verdict never raises;
commands that only read never make a store. SQLite here, PostgreSQL in the machine tier (the same
tests, parametrized by the `db` fixture)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import sqlalchemy as sa

from tests.conftest import assert_one_line_error
from tests.test_history import db, no_password  # noqa: F401 - the store fixture, SQLite and PostgreSQL


def _url(store: str) -> str:
    from campaign.history.location import store_url

    return store_url(store) or ""


def set_revision(store: str, revision: str) -> None:
    """Write `revision` into the store's alembic_version, as another axiscal would."""
    engine = sa.create_engine(_url(store))
    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE alembic_version SET version_num = :r"), {"r": revision})
    engine.dispose()


def make_at(store: str, revision: str) -> None:
    """A store made by an axiscal whose newest revision was `revision`."""
    from alembic import command

    from campaign.history.store import _alembic, writing

    url = _url(store)
    if url.startswith("sqlite"):
        Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
    engine = sa.create_engine(url)
    config = _alembic()
    with writing(engine) as conn:
        config.attributes["connection"] = conn
        command.upgrade(config, revision)
    engine.dispose()


def revision_of(store: str) -> str:
    engine = sa.create_engine(_url(store))
    with engine.connect() as conn:
        found = conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar_one()
    engine.dispose()
    return str(found)


def test_a_newer_store_queues_the_campaign_in_one_line(cli, db, tmp_path):  # noqa: F811
    """A store at a revision this axiscal does not know (a newer axiscal on the same server): the
    command ends with exit 0 and one line saying so; the campaign waits in the queue, and the
    store is left as it was (exit 1 'internal error: CommandError' and nothing queued before)."""
    from campaign.history.simulated import simulate_history

    _, dirs = simulate_history(tmp_path / "h", campaigns=1)
    assert cli("history", "import", dirs[0]).code == 0
    set_revision(db, "r9999")
    converted = cli("convert", dirs[0] / "points.csv", "-o", tmp_path / "out.rtl")
    assert converted.code == 0, converted.err
    told = [line for line in converted.err.splitlines() if line.startswith("history:")]
    assert len(told) == 1 and "newer than this axiscal" in told[0] and "queued" in told[0], converted.err
    assert "internal error" not in converted.err and "Traceback" not in converted.err
    no_password(converted.err)
    assert revision_of(db) == "r9999"
    refused = cli("history", "list")
    assert_one_line_error(refused, "schema revision r9999", "newer than this axiscal")
    set_revision(db, _head())  # the newer axiscal's change undone: the queue is recorded at the next use
    listed = cli("history", "list", "--json")
    assert listed.code == 0 and json.loads(listed.out)["campaigns"][0]["label"] == dirs[0].name
    assert json.loads(cli("history", "store", "--json").out)["waiting"] == 0


def _head() -> str:
    from campaign.history.store import known_revisions

    return known_revisions()[-1]


def test_record_now_never_raises(tmp_path, monkeypatch):
    """Whatever fails while recording (here: opening the store raises an error of no kind the
    store knows) is queued and said in one line."""
    from campaign.history import recording

    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))

    def broken(url: str, *args: object, **kwargs: object) -> None:
        raise RuntimeError("something unforeseen")

    monkeypatch.setattr(recording, "open_store", broken)
    line = recording.record_now({"kind": "campaign", "path": str(tmp_path), "command": "run"},
                                str(tmp_path / "h.sqlite"))
    assert line.startswith("history: store unreachable") and "queued" in line and "\n" not in line, line


def test_reading_a_missing_store_makes_nothing(cli, tmp_path, monkeypatch):
    """`history list --db` on a mistyped path: exit 2 'no store at ...', and no folder, no file
    made (it said '0 campaign(s)' and made both before)."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    missing = tmp_path / "mistyped" / "dir" / "h.sqlite"
    for action in (("list",), ("trend", "m", "X"), ("compare", "1", "2"), ("store",), ("plant",)):
        result = cli("history", *action, "--db", missing)
        assert_one_line_error(result, f"no store at {missing}")
    assert not (tmp_path / "mistyped").exists()


def test_a_file_that_is_no_database_is_said_so(cli, tmp_path, monkeypatch):
    """`--db` naming a config file (a slip of the shell's completion): exit 2 with one sentence, for
    reading and writing actions alike (it was an internal error, exit 1, with SQLAlchemy's link)."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    not_a_store = tmp_path / "x.toml"
    not_a_store.write_text("[campaign]\nmachine = 'm'\n" * 200)
    for action in (("list",), ("store",), ("trend", "m", "X")):
        assert_one_line_error(cli("history", *action, "--db", not_a_store), str(not_a_store), "not a database")
    assert not_a_store.read_text().startswith("[campaign]")


@pytest.mark.machine
def test_an_empty_server_database_is_no_store_to_read(cli, postgres_server, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    url = postgres_server.new_database()
    result = cli("history", "list", "--db", url)
    assert_one_line_error(result, "no store at", "holds no axiscal store")
    no_password(result.err)
    engine = sa.create_engine(_url(url))
    with engine.connect() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM information_schema.tables "
                                    "WHERE table_schema = 'public'")).scalar_one() == 0
    engine.dispose()


def test_an_older_store_migrates_itself_on_sqlite_only_by_command_on_a_server(cli, db, tmp_path):  # noqa: F811
    """A store at the first revision: an embedded SQLite file migrates itself when a command
    records into it; a PostgreSQL store is not migrated by a campaign's end (the campaign is
    queued, one line naming the command), only by `history store --upgrade`. The migration fills
    in the uncertainty between re-checks of the campaigns recorded before."""
    from campaign.history.simulated import simulate_history
    from campaign.history.store import open_store

    _, dirs = simulate_history(tmp_path / "h", campaigns=2)
    make_at(db, "r0001")
    converted = cli("convert", dirs[0] / "points.csv", "-o", tmp_path / "out.rtl")
    assert converted.code == 0, converted.err
    told = [line for line in converted.err.splitlines() if line.startswith("history:")]
    if db.startswith("postgresql"):
        assert revision_of(db) == "r0001"
        assert len(told) == 1 and "history store --upgrade" in told[0] and "queued" in told[0], told
        assert_one_line_error(cli("history", "list"), "schema revision r0001", "history store --upgrade")
        upgraded = cli("history", "store", "--upgrade", "--json")
        assert upgraded.code == 0, upgraded.err
        assert json.loads(upgraded.out)["upgraded_from"] == "r0001"
        no_password(upgraded.out, upgraded.err)
    else:
        assert told == ["history: added in history.sqlite"], told
    assert revision_of(db) == _head()
    with open_store(_url(db)) as store:
        rows = store.campaigns()
    assert [r["label"] for r in rows] == [dirs[0].name] and rows[0]["purpose"] == "acceptance"
    assert set(rows[0]["recheck"]) == {"A", "E", "B", "R"}


def test_the_migration_fills_in_what_earlier_campaigns_lack(tmp_path):
    """Campaigns recorded at the first revision get their purpose (a verification when measured
    with a compensation table) and their uncertainty between re-checks, from their points, the
    same as recording them now gives."""
    from campaign.history.entry import directory_entry
    from campaign.history.simulated import simulate_history
    from campaign.history.store import open_store

    _, dirs = simulate_history(tmp_path / "h", campaigns=1)
    store_path = str(tmp_path / "old.sqlite")
    make_at(store_path, "r0001")
    entry = directory_entry(dirs[0])
    old_columns = {k: v for k, v in entry.values.items() if k not in ("purpose", "follows")}
    engine = sa.create_engine(_url(store_path))
    from campaign.history import schema

    with engine.begin() as conn:  # the columns of the first revision only
        cid = conn.execute(schema.campaigns.insert().values(**{**old_columns, "with_compensation": True})
                           .returning(schema.campaigns.c.id)).scalar_one()
        conn.execute(schema.results.insert(), [{"campaign_id": cid, "parameter": p, "direction": d, "value": v,
                                                "expanded_u": u} for p, d, v, u in entry.results])
        conn.execute(schema.points.insert(), [
            {"campaign_id": cid, "seq": i, "run": r, "direction": d, "target": t, "deviation": e, "time_s": s}
            for i, (r, d, t, e, s) in enumerate(entry.points)])
    engine.dispose()
    with open_store(_url(store_path)) as store:
        row = store.campaigns()[0]
    assert row["purpose"] == "verification"
    assert row["recheck"] == pytest.approx(entry.recheck, rel=1e-9)


SMALL_RUN = """
[campaign]
machine = "sim-run"
tolerance = 10.0
{purpose}

[axis]
name = "X"
soft_limit_min = -10.0
soft_limit_max = 110.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 100.0
count = 4
overrun = 2.0
cycles = 2
dwell_s = 1.0
velocity = 20.0

[axis_driver]
type = "sim"

[instrument]
type = "sim"

[capture]
average_s = 0.5
retries = 0

[sim]
seed = {seed}

[sim.effects.linear_scale]
ppm = -12.4

[sim.effects.noise]
sigma_um = 0.3
reading_sigma_um = 0.05
"""


@pytest.mark.machine
def test_run_with_a_newer_store_and_a_follow_up(cli, tmp_path, monkeypatch):
    """Done-when of issue 30 with `axiscal run` on the simulated machine: the store at a newer
    revision, the campaign completes with exit 0 and waits in the queue; a follow-up (the purpose
    `discover --follow-up` writes) prints no PASS/FAIL and is absent from `history trend`."""
    store = str(tmp_path / "store.sqlite")
    monkeypatch.setenv("AXISCAL_DB", store)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    config = tmp_path / "c.toml"
    config.write_text(SMALL_RUN.format(purpose="", seed=1))
    first = cli("run", config, "--out", tmp_path / "first")
    assert first.code == 0, first.err
    set_revision(store, "r9999")
    config.write_text(SMALL_RUN.format(purpose="", seed=2))  # new noise: another measurement
    second = cli("run", config, "--out", tmp_path / "second")
    assert second.code == 0, second.err
    told = [line for line in second.err.splitlines() if line.startswith("history:")]
    assert len(told) == 1 and "newer than this axiscal" in told[0] and "queued" in told[0], second.err
    assert json.loads(cli("history", "store", "--db", tmp_path / "other.sqlite", "--upgrade", "--json").out)
    set_revision(store, _head())
    follow = tmp_path / "follow.toml"
    follow.write_text(SMALL_RUN.format(purpose=f'purpose = "follow-up"\nfollows = "{tmp_path / "first"}"', seed=3))
    third = cli("run", follow, "--out", tmp_path / "third")
    assert third.code == 0, third.err
    assert "PASS" not in third.out and "FAIL" not in third.out and "not an acceptance test" in third.out, third.out
    trend = json.loads(cli("history", "trend", "sim-run", "X", "--json").out)
    assert [c["label"] for c in trend["campaigns"]] == ["first", "second"], (third.err[-600:], [r["reason"][:90] for r in trend["left_out"]])  # the queued one recorded first
    assert [r["label"] for r in trend["left_out"]] == ["third"] and "a follow-up of" in trend["left_out"][0]["reason"]


def test_the_store_names_the_newest_revision_without_alembic():
    from campaign.history.store import HEAD, known_revisions

    assert HEAD == known_revisions()[-1]

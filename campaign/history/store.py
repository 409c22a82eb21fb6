"""The campaign store: one database of every campaign of every axis (SQLAlchemy Core).

The same code runs on the embedded SQLite file (WAL mode: readers never wait for the writer, a
read is a deferred transaction; writers take turns through `BEGIN IMMEDIATE`, taken only by write
transactions, and a busy timeout) and on a plant's shared PostgreSQL server (by URL; a connect
timeout, a statement timeout and a lock timeout, so that a stalled server cannot hang a campaign's
end: it is queued instead). A store is brought to the newest schema revision by its migrations
(Alembic, `migrations/`): a new store is made at the newest revision by the first command that
records into it; an embedded SQLite file at an older revision migrates itself when opened, a
server store only by an explicit `axiscal history store --upgrade` (its other clients may be an
older axiscal). A store at a revision this axiscal does not know (a newer one) is refused in one
sentence, never touched. Two processes opening a new store at once migrate it once (the migration
holds the write lock: SQLite's, or a PostgreSQL advisory lock). A command that only reads never
makes a store: where there is none it is told `NoStore` ("no store at ...").

Two processes recording at once lose nothing: each campaign is written in one transaction, known
by its unique key; when both record the same campaign, the second finds it there (a unique-key
conflict is retried once) and changes nothing.

Errors reaching the store (a server that does not answer, a file that cannot be opened) are
`StoreUnavailable`, whose message names the store without its credentials.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Self

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine

from campaign.history import schema
from campaign.history.entry import Entry, now_utc
from campaign.history.location import display_url, scrub, store_label, store_place

MIGRATIONS = Path(__file__).parent / "migrations"
ADVISORY_LOCK = 230_2027
"""PostgreSQL advisory lock held while a store is migrated (an arbitrary number of ours)."""
BUSY_TIMEOUT_MS = 60_000
"""SQLite: how long a writer waits for another's transaction to end, ms."""
CONNECT_TIMEOUT_S = 5
"""PostgreSQL: how long to wait for the server to answer, s."""
STATEMENT_TIMEOUT_S = 60
"""PostgreSQL: the longest a statement may run (the server cancels it), s."""
LOCK_TIMEOUT_S = 30
"""PostgreSQL: the longest a statement waits for a lock another session holds, s."""
WRITE = "axiscal_write"
"""The execution option that marks a write transaction (SQLite takes its write lock at BEGIN)."""


class StoreUnavailable(Exception):
    """The store cannot be reached or written; the message names it without its credentials."""


class NoStore(StoreUnavailable):
    """There is no store where one was named (a file that does not exist, a database without the
    store's tables), and the command only reads: nothing is made."""


def _sqlite_engine(url: str, create: bool = True) -> Engine:
    database = sa.engine.make_url(url).database
    if create and database and database != ":memory:":
        try:
            Path(database).parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreUnavailable(f"{display_url(url)}: cannot create its folder ({exc.strerror})") from None
    engine = sa.create_engine(url, connect_args={"timeout": BUSY_TIMEOUT_MS / 1000})

    @sa.event.listens_for(engine, "connect")
    def on_connect(dbapi_connection: Any, record: Any) -> None:
        dbapi_connection.isolation_level = None  # transactions are begun below, not by the driver
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute(f"PRAGMA busy_timeout={BUSY_TIMEOUT_MS}")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    @sa.event.listens_for(engine, "begin")
    def on_begin(conn: Connection) -> None:
        if conn.get_execution_options().get(WRITE):
            conn.exec_driver_sql("BEGIN IMMEDIATE")  # one writer at a time, waiting its turn
        else:
            conn.exec_driver_sql("BEGIN")  # a reader: a snapshot, never waiting for the writer

    return engine


def _engine(url: str, create: bool = True) -> Engine:
    if url.startswith("sqlite"):
        return _sqlite_engine(url, create)
    given = sa.engine.make_url(url).query  # what the URL sets itself stays as it is
    args: dict[str, Any] = {"connect_timeout": CONNECT_TIMEOUT_S}
    if "options" not in given:
        args["options"] = (f"-c statement_timeout={STATEMENT_TIMEOUT_S * 1000} "
                           f"-c lock_timeout={LOCK_TIMEOUT_S * 1000}")
    return sa.create_engine(url, pool_pre_ping=True, connect_args={k: v for k, v in args.items() if k not in given})


@contextmanager
def writing(engine: Engine) -> Iterator[Connection]:
    """A write transaction (SQLite: BEGIN IMMEDIATE); committed at the end, rolled back on error."""
    with engine.connect() as conn:
        conn.execution_options(**{WRITE: True})
        with conn.begin():
            yield conn


def _alembic() -> Any:
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    return config


HEAD = "r0002"
"""The newest schema revision (migrations/versions/; a test checks it is Alembic's head): a store
there is opened without loading Alembic, which only migrating needs."""


def _revisions(engine: Engine) -> tuple[str | None, str]:
    """(the store's revision, None when it holds no store yet; the newest revision)."""
    with engine.connect() as conn:
        try:
            current = conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar()
        except (sa.exc.OperationalError, sa.exc.ProgrammingError):
            if not _has_no_version_table(conn):
                raise
            current = None
        conn.rollback()
    return (None if current is None else str(current)), HEAD


def _has_no_version_table(conn: Connection) -> bool:
    """After a failed read of alembic_version: whether the table is simply not there (a new or
    foreign database), rather than the store failing."""
    conn.rollback()
    return "alembic_version" not in sa.inspect(conn).get_table_names()


def known_revisions() -> list[str]:
    """The schema revisions this axiscal knows, oldest first."""
    from alembic.script import ScriptDirectory

    return [r.revision for r in reversed(list(ScriptDirectory.from_config(_alembic()).walk_revisions()))]


def _migrate(engine: Engine) -> None:
    """Bring the store to the newest revision (nothing to do when it is there)."""
    from alembic import command

    current, head = _revisions(engine)
    if current == head:
        return
    config = _alembic()
    with writing(engine) as conn:
        if engine.dialect.name == "postgresql":
            conn.execute(sa.text("SELECT pg_advisory_xact_lock(:key)"), {"key": ADVISORY_LOCK})
        config.attributes["connection"] = conn
        command.upgrade(config, "head")


SUMMARY_COLUMNS = ("id", "key", "source", "command", "machine", "axis", "axis_kind", "unit", "position_unit",
                   "measured_utc", "status", "points", "points_planned", "with_compensation", "location", "label",
                   "verdict", "tolerances", "fingerprint", "purpose", "follows")
"""The campaigns' columns a trend and the plant read (Store.campaigns(summary=True))."""


class Store:
    """An open store. `url`: its SQLAlchemy URL (never shown as is: `display`)."""

    def __init__(self, url: str, migrate: bool = True, create: bool = True):
        """Open the store; `migrate`: bring it to the newest revision (False: read it as it is;
        `revision` says what it is, None when it holds no store); `create`: make a SQLite file's
        folder when it is missing (False: never make anything)."""
        self.url = url
        self.display = store_label(url)
        """The store's short name (file name, or host and database), for every line and report."""
        self.place = store_place(url)
        """Where it is in full, without credentials (errors, `history store`)."""
        self.engine = _engine(url, create)
        with self._reaching():
            if migrate:
                _migrate(self.engine)
            self.revision, self.head = _revisions(self.engine)

    @contextmanager
    def _reaching(self) -> Iterator[None]:
        """Database and OS errors as StoreUnavailable, credentials masked."""
        try:
            yield
        except sa.exc.IntegrityError:
            raise  # a key two writers both add: put's own retry takes it
        except (sa.exc.DatabaseError, sa.exc.InterfaceError) as exc:  # operational, programming, not a database
            reason = str(getattr(exc, "orig", None) or exc).strip().splitlines()
            raise StoreUnavailable(scrub(f"{self.place}: {reason[0] if reason else type(exc).__name__}",
                                         self.url)) from None
        except OSError as exc:
            raise StoreUnavailable(scrub(f"{self.place}: {exc.strerror or exc}", self.url)) from None

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # writing

    def put(self, entry: Entry) -> tuple[int, str]:
        """Record one campaign or table: (its id, "added", "updated" or "unchanged")."""
        for attempt in (1, 2):
            try:
                with self._reaching(), writing(self.engine) as conn:
                    return self._put(conn, entry)
            except sa.exc.IntegrityError:
                if attempt == 2:  # the same campaign, recorded by another process a moment ago: twice
                    raise
        raise AssertionError("unreachable")

    def _put(self, conn: Connection, entry: Entry) -> tuple[int, str]:
        c = schema.campaigns
        row = conn.execute(sa.select(c.c.id, c.c.state, c.c.command, c.c.source).where(c.c.key == entry.key)).first()
        values = dict(entry.values)
        if row is not None:
            asked = row.source == "converted" and values["source"] == "table" and values["command"] == "import"
            if row.state == values["state"] and not asked:
                return row.id, "unchanged"  # (a converted table imported on purpose becomes a measurement)
            if values["command"] == "import":  # the command that measured it stays named
                values["command"] = row.command
            conn.execute(c.update().where(c.c.id == row.id).values(**values))
            conn.execute(schema.results.delete().where(schema.results.c.campaign_id == row.id))
            conn.execute(schema.points.delete().where(schema.points.c.campaign_id == row.id))
            campaign_id, what = row.id, "updated"
        else:
            campaign_id = conn.execute(c.insert().values(**values).returning(c.c.id)).scalar_one()
            what = "added"
        if entry.results:
            conn.execute(schema.results.insert(), [
                {"campaign_id": campaign_id, "parameter": p, "direction": d, "value": v, "expanded_u": u,
                 "u_recheck": entry.recheck.get(p) if d == "both" else None}
                for p, d, v, u in entry.results])
        if entry.points:
            conn.execute(schema.points.insert(), [
                {"campaign_id": campaign_id, "seq": i, "run": r, "direction": d, "target": t, "deviation": e,
                 "time_s": s} for i, (r, d, t, e, s) in enumerate(entry.points)])
        return campaign_id, what

    def link_verification(self, after_id: int, before_id: int | None, before_location: str | None,
                          compensation: dict[str, Any]) -> None:
        """Record that campaign `after_id` verified a compensation against `before_id` (an upsert:
        two processes recording the same verification at once both succeed)."""
        v = schema.verifications
        from sqlalchemy.dialects import postgresql, sqlite

        row = {"before_id": before_id, "before_location": before_location, "compensation": compensation}
        dialect = postgresql if self.engine.dialect.name == "postgresql" else sqlite
        statement = dialect.insert(v).values(campaign_id=after_id, **row)
        with self._reaching(), writing(self.engine) as conn:
            conn.execute(statement.on_conflict_do_update(index_elements=[v.c.campaign_id], set_=row))

    def put_comp_table(self, key: str, values: dict[str, Any]) -> str:
        """Record a compensation table written: "added" or "unchanged"."""
        t = schema.comp_tables
        for attempt in (1, 2):
            try:
                with self._reaching(), writing(self.engine) as conn:
                    if conn.execute(sa.select(t.c.id).where(t.c.key == key)).first() is not None:
                        return "unchanged"
                    conn.execute(t.insert().values(key=key, **values))
                    return "added"
            except sa.exc.IntegrityError:
                if attempt == 2:
                    raise
        raise AssertionError("unreachable")

    # reading

    def known(self, key: str) -> tuple[int, str] | None:
        """(id, state) of the campaign recorded under `key`, or None."""
        c = schema.campaigns
        with self._reaching(), self.engine.connect() as conn:
            row = conn.execute(sa.select(c.c.id, c.c.state).where(c.c.key == key)).first()
        return None if row is None else (row.id, row.state)

    def campaign_id(self, key: str) -> int | None:
        c = schema.campaigns
        with self._reaching(), self.engine.connect() as conn:
            return conn.execute(sa.select(c.c.id).where(c.c.key == key)).scalar()

    def campaigns(self, machine: str | None = None, axis: str | None = None, since: dt.datetime | None = None,
                  until: dt.datetime | None = None, verdict: str | None = None,
                  summary: bool = False) -> list[dict[str, Any]]:
        """The campaigns recorded, oldest first (undated last), each with its `results`:
        {(parameter, direction): (value, U)}, and `recheck`: {parameter: standard uncertainty
        between re-checks}. `summary`: only what a trend needs (SUMMARY_COLUMNS, the bidirectional
        results; no budget, plan, checks: a plant's thousands of campaigns read in a second)."""
        c = schema.campaigns
        query = sa.select(*(c.c[name] for name in SUMMARY_COLUMNS)) if summary else sa.select(c)
        if machine:
            query = query.where(c.c.machine == machine)
        if axis:
            query = query.where(c.c.axis == axis)
        if since:
            query = query.where(c.c.measured_utc >= since)
        if until:
            query = query.where(c.c.measured_utc < until)
        if verdict:
            query = query.where(c.c.verdict == verdict)
        query = query.order_by(c.c.measured_utc.is_(None), c.c.measured_utc, c.c.id)
        r = schema.results
        with self._reaching(), self.engine.connect() as conn:
            rows = [dict(row._mapping) for row in conn.execute(query)]
            by_id = {row["id"]: row for row in rows}
            for row in rows:
                row["results"], row["recheck"] = {}, {}
            ids = list(by_id)
            for start in range(0, len(ids), 500):
                chunk = ids[start:start + 500]
                wanted = sa.select(r).where(r.c.campaign_id.in_(chunk))
                if summary:
                    wanted = wanted.where(r.c.direction == "both")
                for res in conn.execute(wanted):
                    by_id[res.campaign_id]["results"][(res.parameter, res.direction)] = (res.value, res.expanded_u)
                    if res.u_recheck is not None:
                        by_id[res.campaign_id]["recheck"][res.parameter] = res.u_recheck
        return rows

    def points(self, campaign_id: int) -> list[tuple[int, int, float, float, float | None]]:
        """The point table of a campaign, in its recorded order."""
        p = schema.points
        query = sa.select(p.c.run, p.c.direction, p.c.target, p.c.deviation, p.c.time_s).where(
            p.c.campaign_id == campaign_id).order_by(p.c.seq)
        with self._reaching(), self.engine.connect() as conn:
            return [(row.run, row.direction, row.target, row.deviation, row.time_s) for row in conn.execute(query)]

    def find(self, reference: str) -> dict[str, Any]:
        """A campaign by its id number, its key (or a prefix of 8 or more), its directory's path or
        its label. LookupError naming what matched when none or several do."""
        c = schema.campaigns
        text = reference.strip()
        tests = []
        if text.isdigit():
            tests.append(c.c.id == int(text))
        if len(text) >= 8:
            tests.append(c.c.key.startswith(text))
        tests += [c.c.location == str(Path(text).resolve()), c.c.label == Path(text).name]
        with self._reaching(), self.engine.connect() as conn:
            for test in tests:
                rows = [dict(r._mapping) for r in conn.execute(sa.select(c).where(test))]
                if len(rows) == 1:
                    return rows[0]
                if len(rows) > 1:
                    raise LookupError(f"'{reference}' names {len(rows)} campaigns (ids "
                                      f"{', '.join(str(r['id']) for r in rows[:6])}): give the id")
        raise LookupError(f"'{reference}': no such campaign in the store (axiscal history list shows them)")

    def verification_of(self, campaign_id: int) -> dict[str, Any] | None:
        v = schema.verifications
        with self._reaching(), self.engine.connect() as conn:
            row = conn.execute(sa.select(v).where(v.c.campaign_id == campaign_id)).first()
        return None if row is None else dict(row._mapping)

    def comp_tables(self, machine: str | None = None, axis: str | None = None) -> list[dict[str, Any]]:
        t = schema.comp_tables
        query = sa.select(t).order_by(t.c.written_utc, t.c.id)
        if machine:
            query = query.where(t.c.machine == machine)
        if axis:
            query = query.where(t.c.axis == axis)
        with self._reaching(), self.engine.connect() as conn:
            return [dict(r._mapping) for r in conn.execute(query)]

    def counts(self) -> dict[str, int]:
        """Rows per table (for a summary)."""
        with self._reaching(), self.engine.connect() as conn:
            return {name: int(conn.execute(sa.select(sa.func.count()).select_from(table)).scalar_one())
                    for name, table in (("campaigns", schema.campaigns), ("points", schema.points),
                                        ("comp_tables", schema.comp_tables))}


def open_store(url: str, create: bool = True, upgrade: bool = False) -> Store:
    """Open the store at `url` to record into it or read it (see the module's docstring):
    `create`: make a new store where there is none (False: NoStore, nothing made); `upgrade`:
    bring a store at an older revision to the newest whatever its back end (only an embedded
    SQLite file migrates itself otherwise). StoreUnavailable, in one sentence, when it cannot be
    reached or is at a revision this axiscal cannot use."""
    place = store_place(url)
    if not create and url.startswith("sqlite"):
        database = sa.engine.make_url(url).database
        if database and database != ":memory:" and not Path(database).is_file():
            raise NoStore(f"no store at {place}")
    try:
        store = Store(url, migrate=False, create=create)
    except sa.exc.ArgumentError as exc:
        raise StoreUnavailable(scrub(f"{place}: {exc}", url)) from None
    try:
        _bring_to_head(store, create, upgrade)
    except BaseException:
        store.close()
        raise
    return store


def _bring_to_head(store: Store, create: bool, upgrade: bool) -> None:
    """Migrate `store` as open_store says, or refuse it in one sentence."""
    if store.revision == store.head:
        return
    if store.revision is None:
        if not create:
            raise NoStore(f"no store at {store.place} (the database holds no axiscal store)")
    else:
        known = known_revisions()
        if store.revision not in known:
            raise StoreUnavailable(f"{store.place} is at schema revision {store.revision}, newer than this axiscal "
                                   f"knows (up to {store.head}): a newer axiscal wrote it; upgrade this one to use it")
        if not (upgrade or store.url.startswith("sqlite")):
            raise StoreUnavailable(f"{store.place} is at schema revision {store.revision}, this axiscal uses "
                                   f"{store.head}: a shared server store is migrated only on purpose, by "
                                   "`axiscal history store --upgrade` (older axiscal clients then queue their campaigns)")
    with store._reaching():
        _migrate(store.engine)
        store.revision, store.head = _revisions(store.engine)


def open_reader(url: str) -> Store | None:
    """Open the store at `url` to read it only: never created, never migrated. None when there is
    no store there; StoreUnavailable when it cannot be reached, or is at another revision than this
    axiscal's."""
    if url.startswith("sqlite"):
        database = sa.engine.make_url(url).database
        if not database or database == ":memory:" or not Path(database).is_file():
            return None
    try:
        store = Store(url, migrate=False, create=False)
    except sa.exc.ArgumentError as exc:
        raise StoreUnavailable(scrub(f"{display_url(url)}: {exc}", url)) from None
    if store.revision is None:
        store.close()
        return None
    if store.revision != store.head:
        store.close()
        raise StoreUnavailable(f"{store.display} is at schema revision {store.revision}, this axiscal reads "
                               f"{store.head}")
    return store


__all__ = ["NoStore", "Store", "StoreUnavailable", "now_utc", "open_reader", "open_store"]

"""`axiscal history import|list|trend|compare|store`: the campaign store (docs/history.md).

Also the hook the measuring commands call at their end (`record_after`): it records the campaign
into the store and tells the user in one line on stderr; a store that cannot be reached never
stops a campaign (the campaign is queued and recorded at the next use of the store).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from campaign.commands import SUMMARY, positive_number
from campaign.errors import InputError

if TYPE_CHECKING:
    from campaign.history.store import Store

VERDICTS = ("pass", "fail", "not judged")


def record_after(path: str | Path, command: str, fmt: str = "points") -> None:
    """Record the campaign directory (or measurement file of format `fmt`) `path` measured or read
    by `command` into the store; one line on stderr says what happened. Never raises."""
    from campaign.history.recording import record_now
    from campaign.record import META_FILE

    where = Path(path)
    if not (where.is_file() or (where / META_FILE).is_file()):
        return  # nothing was recorded: no campaign to remember
    line = record_now({"kind": "campaign", "path": str(where.resolve()), "command": command, "format": fmt})
    if line:
        print(line, file=sys.stderr)


def record_comp_after(text: str, output: str | Path, fmt: str, points: str | Path, provenance: dict[str, str],
                      machine: str, axis: str) -> None:
    """Record a compensation table just written (and the campaign it came from). Never raises."""
    from campaign.history.recording import comp_item, record_now

    line = record_now(comp_item(text, output, fmt, Path(points).resolve(), provenance, machine, axis))
    if line:
        print(line, file=sys.stderr)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("history", help=SUMMARY["history"],
                       description="The campaign store: every campaign of every axis, its trend and when it "
                                   "will leave its tolerance (docs/history.md). The store: --db, else "
                                   "$AXISCAL_DB, else ~/.local/share/axiscal/history.sqlite.")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True, parser_class=type(p))
    db = argparse.ArgumentParser(add_help=False)
    db.add_argument("--db", metavar="URL|PATH",
                    help="the store: a database URL (postgresql://USER@HOST/DB, sqlite:///PATH) or a SQLite file "
                         "(default: $AXISCAL_DB, else ~/.local/share/axiscal/history.sqlite)")
    db.add_argument("--json", action="store_true", help="print one JSON object")

    a = actions.add_parser("import", parents=[db], help="record campaign directories (and the ones below them)",
                           description="Record each campaign directory (or point table) into the store; a folder "
                                       "that is not a campaign is searched for campaign directories. Importing "
                                       "twice adds nothing.")
    a.add_argument("paths", nargs="+", metavar="DIR")
    a.set_defaults(func=run_import)

    ls = actions.add_parser("list", parents=[db], help="the campaigns recorded",
                            description="The campaigns in the store, oldest first.")
    ls.add_argument("--machine")
    ls.add_argument("--axis")
    ls.add_argument("--since", type=day, metavar="YYYY-MM-DD", help="measured on or after this day (UTC)")
    ls.add_argument("--until", type=day, metavar="YYYY-MM-DD", help="measured on or before this day (UTC)")
    ls.add_argument("--verdict", choices=VERDICTS)
    ls.add_argument("--all", action="store_true",
                    help="list the converted tables too (files read by axiscal convert: copies, not campaigns)")
    ls.set_defaults(func=run_list)

    t = actions.add_parser("trend", parents=[db], help="an axis's A, E, B, R over time, drift, jumps, crossing",
                           description="A, E, B and R of one axis over its campaigns with their U, the drift per "
                                       "year of each (weighted fit), the jumps between campaigns, and when A + U "
                                       "is predicted to reach the tolerance.")
    t.add_argument("machine")
    t.add_argument("axis")
    t.add_argument("--tolerance", type=positive_number, metavar="T",
                   help="tolerance on A, µm (arcsec on a rotary axis); default: the latest campaign's")
    t.add_argument("--plot", metavar="OUT", help="write the trend plot (.png or .svg)")
    t.set_defaults(func=run_trend)

    c = actions.add_parser("compare", parents=[db], help="two campaigns' mean deviation curves and their difference",
                           description="Overlay the mean deviation per target of two campaigns (id, key, directory "
                                       "or label, as `history list` shows) and their difference with its U.")
    c.add_argument("first", metavar="FIRST")
    c.add_argument("second", metavar="SECOND")
    c.add_argument("--plot", metavar="OUT", help="write the comparison plot (.png or .svg)")
    c.set_defaults(func=run_compare)

    g = actions.add_parser("plant", parents=[db], help="every axis at a glance: last A, drift, crossing, next re-check due",
                           description="One row per machine and axis, most urgent first: the last campaign's A ± U "
                                       "and verdict, the drift of A per year, when A + U is predicted to reach the "
                                       "tolerance, and when the next re-check is due (the earliest predicted "
                                       "crossing at 95 % less --margin, at most --max-interval after the last "
                                       "campaign).")
    g.add_argument("--machine", help="only this machine's axes")
    g.add_argument("--html", metavar="FILE", help="also write the plant as an HTML page, a small trend plot per axis")
    g.add_argument("--max-interval", type=positive_int, default=None, metavar="DAYS",
                   help="the longest interval between two re-checks of an axis, days (default 365)")
    g.add_argument("--margin", type=non_negative_int, default=None, metavar="DAYS",
                   help="how long before the earliest predicted crossing a re-check is due, days (default 30)")
    g.set_defaults(func=run_plant)

    s = actions.add_parser("store", parents=[db], help="where the store is, what it holds, what waits",
                           description="Name the store (without its credentials), count what it holds and what "
                                       "waits in the queue for it; --upgrade migrates a shared server store to this "
                                       "axiscal's schema (an embedded SQLite file migrates itself).")
    s.add_argument("--upgrade", action="store_true",
                   help="bring the store to this axiscal's schema revision (older axiscal clients of a shared store "
                        "then queue their campaigns until they are upgraded too)")
    s.set_defaults(func=run_store)


def positive_int(text: str) -> int:
    """argparse type: a whole number above 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{value} is not above 0")
    return value


def non_negative_int(text: str) -> int:
    """argparse type: a whole number, 0 or more."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} is below 0")
    return value


def day(text: str) -> dt.datetime:
    """argparse type: a day YYYY-MM-DD (UTC midnight)."""
    try:
        return dt.datetime.strptime(text, "%Y-%m-%d")
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a day YYYY-MM-DD") from None


def open_for(args: argparse.Namespace, create: bool = False, upgrade: bool = False) -> Store:
    """The store the command names, with what waited in its queue recorded first. A command that
    only reads (`create` False) never makes a store: none there is exit 2 "no store at ...",
    unless campaigns wait in the queue for it (they were meant to go there). A SQLite store at an
    older revision migrates itself; a server store only with `upgrade` (`history store --upgrade`)."""
    from campaign.history.location import store_url
    from campaign.history.pending import waiting
    from campaign.history.recording import drain_queue
    from campaign.history.store import NoStore, StoreUnavailable, open_store

    url = store_url(args.db)
    if url is None:
        raise InputError("--db/AXISCAL_DB: the store is turned off (none): name a store")
    try:
        store = open_store(url, create=create or waiting(url) > 0, upgrade=upgrade)
    except NoStore as exc:
        raise InputError(f"{exc}; nothing is recorded there yet (axiscal history import DIR makes it)") from None
    except StoreUnavailable as exc:
        raise InputError(f"history store unreachable: {exc}") from None
    try:
        drained, problems = drain_queue(store)
    except StoreUnavailable as exc:
        store.close()
        raise InputError(f"history store unreachable: {exc}") from None
    if drained and not args.json:
        print(f"history: {drained} campaign(s) waiting in the queue recorded first", file=sys.stderr)
    for problem in problems:
        print(f"history: warning: {problem}", file=sys.stderr)
    return store


def campaign_dirs(paths: list[str]) -> list[Path]:
    """Each path that is a campaign directory or a point table, and the campaign directories
    below each folder that is neither, sorted."""
    from campaign.record import META_FILE

    found: list[Path] = []
    for text in paths:
        path = Path(text)
        if not path.exists():
            raise InputError(f"{path}: no such directory or file")
        if path.is_file() or (path / META_FILE).is_file():
            found.append(path)
            continue
        below = sorted(meta.parent for meta in path.rglob(META_FILE))
        if not below:
            raise InputError(f"{path}: no campaign directory in it (none holds {META_FILE})")
        found += below
    return found


def run_import(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from campaign.history.recording import record_campaign
    from campaign.history.store import StoreUnavailable
    from campaign.views import make_console, print_json

    paths = campaign_dirs(args.paths)
    counts = {"added": 0, "updated": 0, "unchanged": 0}
    failed: list[dict[str, str]] = []
    store = open_for(args, create=True)
    console = make_console(stderr=True)
    try:
        with Progress(TextColumn("importing"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      console=console, transient=True, disable=args.json or len(paths) < 20) as progress:
            task = progress.add_task("import", total=len(paths))
            for path in paths:
                try:
                    counts[record_campaign(store, path)[1]] += 1
                except StoreUnavailable as exc:
                    raise InputError(f"history store unreachable: {exc}") from None
                except InputError as exc:
                    failed.append({"path": str(path), "error": str(exc)})
                progress.advance(task)
    finally:
        store.close()
    result = {"store": store.display, **counts, "failed": failed}
    if args.json:
        print_json(result)
    else:
        print(f"{store.display}: {counts['added']} added, {counts['updated']} updated, {counts['unchanged']} "
              f"unchanged, {len(failed)} not campaigns")
        for f in failed:
            print(f"  not recorded: {f['error']}")
    return 0 if not failed else 2


def _fmt(value: float | None, u: float | None = None) -> str:
    if value is None:
        return "n/a"
    return f"{value:.2f}" + ("" if u is None else f" ± {u:.2f}")


def run_list(args: argparse.Namespace) -> int:
    from rich.table import Table

    from campaign.views import make_console, print_json

    with open_for(args) as store:
        until = args.until + dt.timedelta(days=1) if args.until else None
        everything = store.campaigns(args.machine, args.axis, args.since, until, args.verdict)
    rows = everything if args.all else [r for r in everything if r["source"] != "converted"]
    hidden = len(everything) - len(rows)
    if args.json:
        print_json({"store": store.display, "campaigns": [_listed(r) for r in rows], "converted_not_listed": hidden})
        return 0
    console = make_console()
    cells = []
    for r in rows:
        a, u = r["results"].get(("A", "both"), (None, None))
        cells.append({"id": str(r["id"]), "date": _date(r["measured_utc"]), "day": _date(r["measured_utc"])[:10],
                      "machine": r["machine"], "axis": r["axis"], "purpose": _purpose_shown(r), "command": r["command"],
                      "status": r["status"], "points": str(r["points"]), "A ± U": _fmt(a, u), "verdict": r["verdict"],
                      "where": _shown_path(r["location"])})
    widths = list_widths(console.width, cells)
    table = Table(title=f"{len(rows)} campaign(s) in {store.display}", title_justify="left")
    for head, width in widths.items():
        # one line a campaign: a long name or path is cut with an ellipsis, never broken letter by letter
        table.add_column(head, justify="right" if head in ("id", "points", "A ± U") else "left", no_wrap=True,
                         overflow="ellipsis", width=width)
    for row in cells:
        table.add_row(*(row[head] for head in widths))
    console.print(table)
    if hidden:
        console.print(f"{hidden} converted table(s) (axiscal convert) not listed: --all lists them", markup=False)
    return 0


LIST_COLUMNS = ("id", "date", "day", "machine", "axis", "purpose", "command", "status", "points", "A ± U", "verdict",
                "where")
"""`history list`'s columns, in their order (date or day: one of them)."""
FLEXIBLE = {"machine": 7, "where": 16}
"""Columns that take what is left (each cut with an ellipsis), with the width each needs to be shown."""
DROPPED_FIRST = ("command", "points", "status", "where", "date", "purpose")
"""Which columns give way first when the terminal is narrow (date gives way to day)."""


def list_widths(width: int, cells: list[dict[str, str]]) -> dict[str, int]:
    """The columns `history list` shows in `width` terminal columns, with their widths (see
    fit_columns; date gives way to day). --json gives all."""
    columns = [h for h in LIST_COLUMNS if h != "day"]
    return fit_columns(width, cells, columns, FLEXIBLE, DROPPED_FIRST, {"date": "day"},
                       ("id", "day", "machine", "axis", "A ± U", "verdict"))


def fit_columns(width: int, cells: list[dict[str, str]], columns: list[str], flexible: dict[str, int],
                dropped_first: tuple[str, ...], instead: dict[str, str], narrowest: tuple[str, ...]) -> dict[str, int]:
    """Which columns of a table fit in `width` terminal columns, with their widths: every column
    as wide as its widest cell but the `flexible` ones ({column: the width it needs to be shown}),
    which share what is left (their cells cut with an ellipsis); columns are dropped in the order
    `dropped_first` (or replaced by a shorter one: `instead`) until the table fits; at the last,
    the `narrowest` columns, the first flexible one taking what is left."""
    def need(head: str) -> int:
        return max([len(head)] + [len(c[head]) for c in cells])

    shown = list(columns)
    for drop in (None, *dropped_first):
        if drop in instead:
            shown[shown.index(drop)] = instead[drop]
        elif drop is not None and drop in shown:
            shown.remove(drop)
        fixed = {h: need(h) for h in shown if h not in flexible}
        left = width - sum(fixed.values()) - 3 * len(shown) - 1
        stretch = [h for h in shown if h in flexible]
        if left >= sum(min(flexible[h], need(h)) for h in stretch):
            out = dict(fixed)
            wanted = {h: need(h) for h in stretch}
            total = sum(wanted.values()) or 1
            for h in stretch:
                out[h] = max(min(flexible[h], wanted[h]), min(wanted[h], left * wanted[h] // total))
            while stretch and sum(out[h] for h in stretch) > left:  # a share rounded up past what is left
                out[max(stretch, key=lambda h: out[h])] -= 1
            return {h: out[h] for h in shown}
    narrow = {h: need(h) for h in narrowest}
    first = next(h for h in narrowest if h in flexible)
    narrow[first] = 0
    narrow[first] = max(4, width - sum(narrow.values()) - 3 * len(narrow) - 1)
    return narrow


def _purpose_shown(r: dict[str, Any]) -> str:
    return "converted" if r["source"] == "converted" else str(r.get("purpose") or "acceptance")


def _shown_path(location: str) -> str:
    """A campaign's place as the list shows it: relative to the working directory when inside it
    (the JSON keeps the absolute path)."""
    import os

    try:
        relative = os.path.relpath(location)
    except ValueError:
        return location
    return location if relative.startswith("..") else relative


def _date(when: dt.datetime | None) -> str:
    return "undated" if when is None else when.strftime("%Y-%m-%d %H:%M")


def _listed(r: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in r.items() if k not in ("results", "uncertainty", "checks", "state", "recheck")}
    out["measured_utc"] = None if r["measured_utc"] is None else r["measured_utc"].isoformat()
    out["recorded_utc"] = r["recorded_utc"].isoformat()
    out["results"] = {f"{p}" + ("" if d == "both" else f"_{d}"): {"value": v, "U": u}
                      for (p, d), (v, u) in r["results"].items()}
    return out


def trend_of(store: Store, machine: str, axis: str, tolerance: float | None) -> Any:
    from campaign.history.axis import axis_trend

    rows = store.campaigns(machine, axis)
    if not rows:
        known = sorted({(r["machine"], r["axis"]) for r in store.campaigns()})
        hint = "; ".join(f"{m} {x}" for m, x in known[:8]) or "none yet (axiscal history import DIR)"
        raise InputError(f"history trend: no campaign of machine '{machine}', axis '{axis}' in {store.display} "
                         f"(recorded: {hint})")
    return axis_trend(rows, machine, axis, tolerance)


def run_trend(args: argparse.Namespace) -> int:
    from campaign.plot import check_plot_path
    from campaign.views import print_json

    if args.plot:
        check_plot_path(args.plot)
    with open_for(args) as store:
        trend = trend_of(store, args.machine, args.axis, args.tolerance)
    if args.plot:
        from campaign.history.plots import draw_trend, save

        save(draw_trend(trend), args.plot)
    if args.json:
        print_json({"store": store.display, **trend.as_json()})
        return 0
    print_trend(trend)
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


def print_trend(trend: Any) -> None:
    """The trend as a terminal table and sentences."""
    from rich.table import Table

    from campaign.views import make_console
    from protocols.units import unit_label

    console = make_console()
    unit = unit_label(trend.unit)
    table = Table(title=f"Machine {trend.machine}, axis {trend.axis}: {len(trend.counted)} campaigns ({unit}, ± U, k = 2)")
    for head in ("date", "campaign", "A", "E", "B", "R", "verdict"):
        table.add_column(head, justify="right" if head in "AEBR" else "left", overflow="fold")
    for r in trend.counted:
        cells = [_fmt(*r["results"].get((p, "both"), (None, None))) for p in ("A", "E", "B", "R")]
        step = " (verification: a known step)" if r in trend.known_steps else ""
        table.add_row(_date(r["measured_utc"])[:10], r["label"] + step, *cells, r["verdict"])
    console.print(table)
    for r, why in trend.left_out:
        console.print(f"left out: {r['label']}: {why}", markup=False)
    console.print("drift per year (weighted fit, 95 %):", markup=False)
    for fit in trend.fits.values():
        console.print(f"  {fit.sentence(unit)}", markup=False)
    for sentence in trend.step_sentences():
        console.print(sentence, markup=False)
    for jump in trend.jumps:
        console.print(f"jump: {jump.sentence(unit)}", markup=False)
    if not trend.jumps:
        console.print("no jump between consecutive campaigns beyond their combined uncertainty", markup=False)
    if trend.crossing is not None:
        console.print(trend.crossing.sentence(unit), markup=False)


def run_compare(args: argparse.Namespace) -> int:
    from rich.table import Table

    from campaign.history.compare import compare
    from campaign.plot import check_plot_path
    from campaign.views import make_console, print_json
    from protocols.units import unit_label

    if args.plot:
        check_plot_path(args.plot)
    with open_for(args) as store:
        try:
            first, second = store.find(args.first), store.find(args.second)
        except LookupError as exc:
            raise InputError(f"history compare: {exc.args[0]}") from None
        if first["axis_kind"] != second["axis_kind"]:
            raise InputError(f"history compare: a {first['axis_kind']} and a {second['axis_kind']} axis")
        points = [store.points(row["id"]) for row in (first, second)]
        for row, recorded in zip((first, second), points):
            if not recorded:
                raise InputError(f"history compare: campaign {row['id']} ({row['label']}) has no point recorded "
                                 f"(status {row['status']}): nothing to compare")
        result = compare(first, points[0], second, points[1])
    if args.plot:
        from campaign.history.plots import draw_compare, save

        save(draw_compare(result), args.plot)
    if args.json:
        print_json(result.as_json())
        return 0
    unit = unit_label(result.unit)
    table = Table(title=f"first: {first['label']} (id {first['id']}), second: {second['label']} (id {second['id']}); "
                        f"mean deviation, {unit}, U with k = 2")
    for head in (f"target ({result.position_unit})", "first", "second", "second − first", "U", "beyond U"):
        table.add_column(head, justify="right")
    for r in result.rows:
        beyond = "" if r["U"] is None else ("yes" if abs(r["difference"]) > r["U"] else "no")
        table.add_row(f"{r['target']:g}", f"{r['first']:.2f}", f"{r['second']:.2f}", f"{r['difference']:+.2f}",
                      _fmt(r["U"]), beyond)
    console = make_console()
    console.print(table)
    console.print(f"{result.sentence()}.", markup=False)
    if (other := result.other_axis()) is not None:
        console.print(f"note: {other}", markup=False)
    if result.only_one:
        console.print(f"{result.only_one} target(s) measured in one campaign only are not compared", markup=False)
    if args.plot:
        console.print(f"plot written to {args.plot}", markup=False)
    return 0


def run_plant(args: argparse.Namespace) -> int:
    from rich.table import Table

    from campaign.history.plant import MARGIN_DAYS, MAX_INTERVAL_DAYS, plant
    from campaign.views import make_console, print_json
    from protocols.units import unit_label

    max_interval = args.max_interval or MAX_INTERVAL_DAYS
    margin = MARGIN_DAYS if args.margin is None else args.margin
    if args.html:
        _check_html_path(args.html)
    today = dt.datetime.now(dt.UTC).date()
    with open_for(args) as store:
        rows = store.campaigns(args.machine, summary=True)
    glances = plant(rows, today, max_interval, margin)
    if args.html:
        from campaign.report.history import plant_page

        Path(args.html).write_text(plant_page(glances, store.display, today, max_interval, margin), encoding="utf-8")
    if args.json:
        print_json({"store": store.display, "today": today.isoformat(), "max_interval_days": max_interval,
                    "margin_days": margin, "axes": [g.as_json() for g in glances],
                    **({"html": str(args.html)} if args.html else {})})
        return 0
    console = make_console()
    cells = []
    for g in glances:
        a, u = g.a_and_u()
        fit = g.trend.fits.get("A")
        c = g.trend.crossing
        drift = "n/a" if fit is None or fit.rate is None else f"{fit.rate:+.2f} ± {fit.U_rate:.2f}"
        crossing = ("already" if c is not None and c.state == "already" else
                    c.date.date().isoformat() if c is not None and c.state == "predicted" and c.date else "—")
        cells.append({"machine": g.trend.machine, "axis": g.trend.axis, "due": g.due.isoformat(), "state": g.state,
                      "A ± U": _fmt(a, u), "drift/year": drift, "crossing": crossing})
    widths = fit_columns(console.width, cells, list(PLANT_COLUMNS), {"machine": 7}, ("crossing", "state", "drift/year"),
                         {}, ("machine", "axis", "due", "A ± U"))
    table = Table(title=f"{len(glances)} axes in {store.display}, most urgent first ({today.isoformat()})",
                  title_justify="left")
    for head, width in widths.items():
        table.add_column(head, justify="right" if head in ("A ± U", "drift/year") else "left", no_wrap=True,
                         overflow="ellipsis", width=width)
    for row in cells:
        table.add_row(*(row[head] for head in widths))
    console.print(table)
    units = sorted({unit_label(g.trend.unit) for g in glances})
    console.print(f"A ± U and drift in {', '.join(units) or 'µm'} (per year); due: {margin} days before the earliest "
                  f"predicted crossing (95 %), at most {max_interval} days after the last campaign. "
                  "--json says why for each axis.", markup=False)
    if args.html:
        console.print(f"page written to {args.html}", markup=False)
    return 0


PLANT_COLUMNS = ("machine", "axis", "due", "state", "A ± U", "drift/year", "crossing")
"""`history plant`'s columns in the terminal (--json and --html give all)."""


def _check_html_path(path: str) -> None:
    """--html: a writable file ending in .html, checked before the store is read."""
    target = Path(path)
    if target.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"--html: {path}: the page's name must end in .html")
    if not target.parent.is_dir():
        raise InputError(f"--html: {target.parent}: no such folder")


def run_store(args: argparse.Namespace) -> int:
    from campaign.history.location import store_url
    from campaign.history.pending import queue_path, waiting
    from campaign.views import print_json

    url = store_url(args.db) or ""
    before = _revision_of(url) if args.upgrade else None
    with open_for(args, create=args.upgrade, upgrade=args.upgrade) as store:
        counts = store.counts()
        revision = store.revision
    result = {"store": store.display, "place": store.place, "revision": revision, **counts, "waiting": waiting(url),
              "queue": str(queue_path())}
    if args.upgrade:
        result["upgraded_from"] = before
    if args.json:
        print_json(result)
    else:
        if args.upgrade:
            print(f"{store.display}: schema revision {revision}" + (
                f" (was {before})" if before and before != revision else " (already)" if before else " (made)"))
        print(f"{store.display} ({store.place}): {counts['campaigns']} campaigns ({counts['points']} points), "
              f"{counts['comp_tables']} compensation tables; {result['waiting']} waiting in {result['queue']}")
    return 0


def _revision_of(url: str) -> str | None:
    """The store's schema revision as it is, before an upgrade (None: no store, or unreachable)."""
    from campaign.history.store import Store, StoreUnavailable

    if url.startswith("sqlite") and not Path(url.removeprefix("sqlite:///")).is_file():
        return None
    try:
        with Store(url, migrate=False, create=False) as store:
            return store.revision
    except (StoreUnavailable, Exception):  # noqa: BLE001 - said by open_for right after
        return None


def demo_history(args: argparse.Namespace) -> int:
    """`axiscal demo --history N`: N simulated re-checks of the demo axis over two years (its lead
    error growing, its reversal jumping once), recorded into the store, then the trend."""
    from campaign.history.location import store_url
    from campaign.history.recording import record_campaign
    from campaign.history.simulated import SIMULATOR, simulate_history
    from campaign.history.store import StoreUnavailable, open_store
    from campaign.plot import check_plot_path
    from campaign.views import make_console, print_json

    for given, what in ((args.inject, "--inject"), (args.verify, "--verify"), (args.capture == "stable", "--capture stable"),
                        (args.controller != "sim", "--controller linuxcnc"), (args.cycles, "--cycles")):
        if given:
            raise InputError(f"--history: {what} does not go with a simulated history (its re-checks are the demo's "
                             "campaign, simulated by the fast simulator)")
    if args.plot:
        check_plot_path(args.plot)
    stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    out = Path(args.out) if args.out else Path("runs") / f"history-{stamp}"
    if out.exists() and any(out.iterdir()):
        raise InputError(f"--out: {out} is not empty; a simulated history goes into a new directory")
    url = store_url(None)
    if url is None:
        raise InputError("--history: the store is turned off (AXISCAL_DB=none): name a store to record the history in")
    try:
        store = open_store(url)
    except StoreUnavailable as exc:
        raise InputError(f"history store unreachable: {exc}") from None
    machine = f"sim-history-{stamp}"
    console = make_console(stderr=args.json)
    with store:
        truth, dirs = simulate_history(out, campaigns=args.history, machine=machine)
        for directory in dirs:
            record_campaign(store, directory, "demo")
        trend = trend_of(store, machine, "X", None)
    if args.plot:
        from campaign.history.plots import draw_trend, save

        save(draw_trend(trend), args.plot)
    if args.json:
        print_json({"dir": str(out), "store": store.display, "machine": machine, "axis": "X", "simulator": SIMULATOR,
                    "truth": truth.as_json(), "trend": trend.as_json()})
        return 0
    console.print(f"{len(dirs)} re-checks of the demo axis over {truth.years:g} years, simulated by the {SIMULATOR}, "
                  f"written to {out} and recorded in {store.display}. The truth: the lead error grows by "
                  f"{truth.growth_ppm_per_year:g} µm/m a year (to {truth.lead_ppm_end:g} µm/m at the last re-check); "
                  f"the reversal jumps to {truth.backlash_um:g} µm after re-check {truth.jump_after}.", markup=False)
    print_trend(trend)
    console.print(f"Again with: axiscal history trend {machine} X --plot trend.png", markup=False)
    if args.plot:
        console.print(f"plot written to {args.plot}", markup=False)
    return 0

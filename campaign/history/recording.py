"""Recording into the store: a campaign directory, a point table, a compensation table; and the
end-of-command hook that never stops a campaign (`record_now`).

What is recorded is an *item*, a small JSON-able dict, so that it can wait in the queue
(campaign/history/pending.py) when the store is unreachable:

    {"kind": "campaign", "path": DIR or FILE, "command": run|guide|demo|verify|resume|convert|import,
     "format": the file's format (campaign.convert: points, rtl, ecmc; points by default)}
    {"kind": "comp", "key": ..., "points": the point table it came from, "values": the comp_tables row}
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from campaign.assess import campaign_dir_of
from campaign.history.entry import directory_key, directory_state, path_entry, utc
from campaign.history.location import chosen, scrub, store_label, store_place, store_url
from campaign.history.store import Store, StoreUnavailable, open_store


def record_campaign(store: Store, path: str | Path, command: str = "import", fmt: str = "points") -> tuple[int, str]:
    """Record the campaign directory or measurement file `path` (of format `fmt`: campaign.convert;
    a verification with its baseline and the link between them): (its id, added / updated /
    unchanged). InputError for what is not a campaign or a measurement."""
    directory = campaign_dir_of(path)
    if directory is not None and not (directory / "verification.md").exists():  # unchanged: nothing to read
        known = store.known(directory_key(directory.resolve()))
        if known is not None and known[1] == directory_state(directory.resolve()):
            return known[0], "unchanged"
    entry = path_entry(path, command, fmt)
    campaign_id, what = store.put(entry)
    if entry.compensation is not None or entry.baseline is not None:
        before_id = None
        if entry.baseline is not None and entry.baseline.exists():
            before_id, _ = store.put(path_entry(entry.baseline, "import"))
        store.link_verification(campaign_id, before_id, None if entry.baseline is None else str(entry.baseline),
                                entry.compensation or {})
    return campaign_id, what


def comp_item(text: str, location: str | Path, fmt: str, points: str | Path, provenance: dict[str, str],
              machine: str, axis: str) -> dict[str, Any]:
    """The item of a compensation table written to `location` from the point table `points`."""
    where = str(Path(location).resolve())
    key = hashlib.sha256(f"{where}\n{text}".encode()).hexdigest()
    return {"kind": "comp", "key": key, "points": str(points),
            "values": {"format": fmt, "location": where, "text": text, "provenance": provenance,
                       "machine": machine or "unknown", "axis": axis or "unknown",
                       "written_utc": provenance.get("written", "")}}


def record_item(store: Store, item: dict[str, Any]) -> str:
    """Record one item: added / updated / unchanged. LookupError when what it names is gone."""
    if item.get("kind") == "comp":
        values = dict(item["values"])
        values["written_utc"] = utc(values.get("written_utc")) or utc("1970-01-01")
        campaign_id = None
        points = Path(str(item.get("points", "")))
        if points.exists():
            campaign_id, _ = record_campaign(store, points, "compensate")
        return store.put_comp_table(str(item["key"]), {"campaign_id": campaign_id, **values})
    path = Path(str(item["path"]))
    if not path.exists():
        raise LookupError(f"{path}: gone; it was waiting to be recorded and is not")
    return record_campaign(store, path, str(item.get("command", "import")), str(item.get("format", "points")))[1]


def drain_queue(store: Store) -> tuple[int, list[str]]:
    """Record what waits in the queue for this store (see campaign/history/pending.py)."""
    from campaign.history.pending import drain

    return drain(store.url, lambda item: record_item(store, item), fatal=(StoreUnavailable,))


def record_now(item: dict[str, Any], option: str | None = None) -> str:
    """The hook at the end of a command: record `item` into the store (first what waits in the
    queue for it). Never raises: returns the one line to tell the user ("" when the store is
    turned off; then one warning line per queued item that was dropped or failed), its
    credentials masked whatever the message says. An unreachable store queues the item."""
    try:
        url = store_url(option)
    except Exception as exc:  # noqa: BLE001 - a bad --db/AXISCAL_DB never stops a campaign
        return scrub(f"history: not recorded ({exc})", chosen(option) or "")
    if url is None:
        return ""
    try:
        told = _record_or_queue(url, item)
    except Exception as exc:  # noqa: BLE001 - whatever fails after the verdict is queued, said in one line
        told = _queue(url, item, f"{type(exc).__name__}: {exc}")
    return "\n".join(scrub(line, url) for line in told.splitlines())


def _record_or_queue(url: str, item: dict[str, Any]) -> str:
    try:
        store = open_store(url)
    except StoreUnavailable as exc:
        return _queue(url, item, str(exc))
    except Exception as exc:  # noqa: BLE001 - a store that cannot be opened (whatever the reason) waits
        return _queue(url, item, f"{store_place(url)}: {type(exc).__name__}: {' '.join(str(exc).split())}")
    try:
        drained, problems = drain_queue(store)
        what = record_item(store, item)
        more = f"; {drained} waiting from before also recorded" if drained else ""
        return "\n".join([f"history: {what} in {store.display}{more}",
                          *(f"history: warning: {problem}" for problem in problems)])
    except StoreUnavailable as exc:
        return _queue(url, item, str(exc))
    except Exception as exc:  # noqa: BLE001 - the campaign is recorded in its directory whatever happens here
        return f"history: not recorded in {store_label(url)} ({exc}); the directory keeps it: axiscal history import"
    finally:
        store.close()


def _queue(url: str, item: dict[str, Any], reason: str) -> str:
    from campaign.history.pending import enqueue

    later = f"axiscal history import {item['path']}" if "path" in item else "axiscal history import"
    what = "store not usable" if "schema revision" in reason else "store unreachable"
    try:
        queue = enqueue(url, item)
    except Exception as exc:  # noqa: BLE001 - never raises: said instead
        return f"history: {what} ({reason}) and not queued ({getattr(exc, 'strerror', None) or exc}): record it later with {later}"
    return (f"history: {what} ({reason}); queued in {queue}, recorded at the next use of the store "
            f"(or: {later})")

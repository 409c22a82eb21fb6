"""A bluesky run's documents turned into a campaign directory (campaign/commands/bluesky_plan.py):
documents that are not such a run are an InputError whose one line says what is wrong and in which
document (a KeyError or ValueError traceback before), and nothing is half-written."""

import pytest

from campaign.commands.bluesky_plan import CONFIG_KEY, STREAM, campaign_from_documents
from campaign.config import parse_config
from campaign.errors import InputError
from campaign.plan import build_plan
from tests.fakes import SMALL


def run_documents() -> list[tuple[str, dict]]:
    """A whole run of SMALL's plan: start, then a descriptor and an event per point."""
    plan = build_plan(parse_config(SMALL, "small.toml"))
    docs: list[tuple[str, dict]] = [("start", {"uid": "run", "time": 0.0, CONFIG_KEY: SMALL})]
    for point in plan.points:
        docs.append(("descriptor", {"uid": f"d{point.index}", "name": f"{STREAM}{point.index}"}))
        docs.append(("event", {"descriptor": f"d{point.index}", "seq_num": 1, "time": 1.0 + point.index,
                               "data": {"laser": point.target}}))
    return docs


def broken(docs: list, position: int, change) -> list:
    """`docs` with the document at `position` (from 1) changed by `change(document)`."""
    name, doc = docs[position - 1]
    docs[position - 1] = change(name, dict(doc))
    return docs


def without(key):
    return lambda name, doc: (name, {k: v for k, v in doc.items() if k != key})


def with_value(key, value):
    return lambda name, doc: (name, {**doc, key: value})


CASES = {
    "start without time": (1, without("time"), "document 1 (start): no 'time'"),
    "start time a string": (1, with_value("time", "noon"), "document 1 (start): 'time' is 'noon', not a finite"),
    "config not text": (1, with_value(CONFIG_KEY, 5), "document 1 (start): 'axiscal_config' is int"),
    "descriptor without uid": (2, without("uid"), "document 2 (descriptor): no 'uid'"),
    "event without descriptor": (3, without("descriptor"), "document 3 (event): no 'descriptor'"),
    "event without data": (3, without("data"), "document 3 (event): no 'data'"),
    "event data not a mapping": (3, with_value("data", [1.0]), ("document 3 (event), event 1 of axiscal_point_0: "
                                                               "has no 'laser' reading")),
    "event without time": (3, without("time"), "document 3 (event): no 'time'"),
    "reading not a number": (3, with_value("data", {"laser": "x"}), "document 3 (event): 'laser' is 'x'"),
    "reading NaN": (3, with_value("data", {"laser": float("nan")}), "document 3 (event): 'laser' is nan"),
    "stream names no point": (2, with_value("name", f"{STREAM}first"), ("document 3 (event): stream "
                                                                       "'axiscal_point_first' names no point")),
    "not a pair": (4, lambda name, doc: ("descriptor",), "document 4: not a (name, document) pair"),
    "document not a mapping": (4, lambda name, doc: (name, [doc]), "document 4: not a (name, document) pair"),
}


@pytest.mark.parametrize("case", CASES)
def test_malformed_documents_are_one_line_input_errors_naming_the_document(tmp_path, case):
    position, change, expected = CASES[case]
    with pytest.raises(InputError) as refused:
        campaign_from_documents(broken(run_documents(), position, change), tmp_path / "run")
    message = str(refused.value)
    assert message.startswith(expected) and "\n" not in message, message
    assert not (tmp_path / "run").exists()  # refused before anything is written


def test_the_whole_run_still_becomes_a_campaign(tmp_path):
    directory = campaign_from_documents(run_documents(), tmp_path / "run")
    assert (directory / "points.csv").is_file()

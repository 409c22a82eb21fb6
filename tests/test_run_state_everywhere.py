"""Every campaign directory axiscal writes ends its events.jsonl in `stopped` (issue 32), also those
not measured by the executor: the simulated history's re-checks."""

from tests.conftest import events


def test_a_simulated_recheck_ends_stopped(tmp_path):
    from campaign.history.simulated import simulate_history

    _, dirs = simulate_history(tmp_path / "h", campaigns=2)
    for d in dirs:
        states = events(d, "state")
        assert states, f"{d}: no state event"
        assert states[-1]["data"] == {"state": "stopped", "previous": "idle", "reason": "completed"}
        assert events(d)[-1]["kind"] == "stop"


def test_a_campaign_from_bluesky_documents_ends_stopped(tmp_path):
    """The campaign directory written from a bluesky run's documents (campaign/commands/bluesky_plan.py)
    holds its run's end: idle -> stopped, completed when every point is in the documents."""
    from campaign.commands.bluesky_plan import CONFIG_KEY, STREAM, campaign_from_documents
    from campaign.config import parse_config
    from campaign.plan import build_plan
    from tests.fakes import SMALL

    text = SMALL
    plan = build_plan(parse_config(text, "small.toml"))
    docs: list[tuple[str, dict]] = [("start", {"uid": "run", "time": 0.0, CONFIG_KEY: text})]
    for point in plan.points:
        docs.append(("descriptor", {"uid": f"d{point.index}", "name": f"{STREAM}{point.index}"}))
        docs.append(("event", {"descriptor": f"d{point.index}", "seq_num": 1, "time": 1.0 + point.index,
                               "data": {"laser": point.target}}))
    directory = campaign_from_documents(docs, tmp_path / "run")
    states = events(directory, "state")
    assert states and states[-1]["data"] == {"state": "stopped", "previous": "idle", "reason": "completed"}
    assert events(directory)[-1]["kind"] == "stop"


def test_an_event_record_with_a_time_that_is_no_time_is_refused_where_it_is_read():
    """A hand-edited events.jsonl: t_s NaN, Infinity (json reads both) or true is no campaign time."""
    from campaign.record import check_record

    good = {"t_s": 1.5, "kind": "unpause", "message": "m", "point": None, "data": {}}
    assert check_record(good) is None
    for bad in (float("nan"), float("inf"), True):
        assert check_record({**good, "t_s": bad}) == "t_s missing or of the wrong type", bad

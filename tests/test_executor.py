"""The executor and the session on the in-process fake axis and laser (fast tier): the recorded
table, the event stream, the run records, and what happens on retry, skip, abort, pause, beam
loss, disk full, Ctrl-C, a failing display, and resume (with an unchanged, an edited and an old
directory)."""

import itertools
import json
from dataclasses import replace

import pytest

from campaign.config import config_with, parse_config
from campaign.errors import InputError, SafetyError
from campaign.measure.executor import Control, Observer
from campaign.measure.session import resume_campaign, start_campaign
from campaign.plan import build_plan
from campaign.pointtable import read_points
from campaign.record.directory import open_campaign
from tests.conftest import events
from tests.fakes import SMALL, AxisFault, FakeMachine, linear_error_um


def config(extra: str = ""):
    return parse_config(SMALL + extra, "small.toml")


def rows(directory):
    table = read_points(directory / "points.csv", partial=True)
    return [(int(p), int(r), int(d), float(t), float(x)) for p, r, d, t, x in
            zip(table.extra["point"], table.run, table.direction, table.target, table.deviation)]


def expected_rows(cfg):
    return [(p.index, p.run, p.direction, p.target, round(linear_error_um(p.target, p.direction), 4))
            for p in build_plan(cfg).points]


def test_a_campaign_records_every_point_and_one_event_stream(tmp_path):
    cfg = config()
    machine = FakeMachine()
    outcome = start_campaign(cfg, tmp_path / "c", opener=machine)
    assert (outcome.status, outcome.points, outcome.planned) == ("completed", 12, 12)
    assert rows(tmp_path / "c") == expected_rows(cfg)
    kinds = [e["kind"] for e in events(tmp_path / "c") if e["kind"] != "state"]
    assert kinds == ["start"] + ["point"] * 12 + ["stop"]
    states = [e["data"]["state"] for e in events(tmp_path / "c", "state")]
    assert states == ["moving", "settling", "capturing"] * 12 + ["moving", "idle", "stopped"]  # the closing move
    assert events(tmp_path / "c")[-2]["data"] == {"state": "stopped", "previous": "idle", "reason": "completed"}
    point = events(tmp_path / "c", "point")[4]
    assert point["point"] == 4 and point["data"]["deviation"] == round(linear_error_um(50.0, -1), 4)
    assert set(point) >= {"t_s", "kind", "message", "point", "utc", "data"}
    campaign = open_campaign(tmp_path / "c")
    assert campaign.status == "completed" and [r["record"] for r in campaign.runs] == ["start", "stop"]
    assert campaign.recorded_plan() == build_plan(cfg)
    assert campaign.meta["format_version"] == 2 and campaign.meta["software"].startswith("axiscal ")
    log = [ln for ln in (tmp_path / "c" / "events.log").read_text().splitlines() if " state: " not in ln]
    assert len(log) == 14 and "point 1: run 1 +, target 0 mm" in log[1]


def test_every_move_is_checked_before_it_is_sent(tmp_path):
    machine = FakeMachine()
    cfg = config()
    cfg = config_with(cfg, {"axis": {"max_velocity": 20.0}})  # below the plan's 25 mm/s
    with pytest.raises(SafetyError, match="velocity"):
        start_campaign(cfg, tmp_path / "c", opener=machine)
    assert machine.openings == []  # refused before any hardware was opened


def test_an_axis_fault_is_retried_and_the_table_is_complete(tmp_path):
    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
    outcome = start_campaign(config(), tmp_path / "c", opener=machine)
    assert outcome.status == "completed"
    assert rows(tmp_path / "c") == expected_rows(config())  # no point lost or doubled
    fault = events(tmp_path / "c", "fault")
    assert [(f["point"], f["data"]) for f in fault] == [(2, {"error": "AxisError", "error_id": 0x4550})]
    assert events(tmp_path / "c", "halt", ok=True, why="fault")
    assert [e["point"] for e in events(tmp_path / "c", "retry")] == [2]
    axis = machine.openings[0].axis
    assert axis.halts == 1 and axis.resets == 1


def operator_answers(*decisions: str) -> Control:
    """A control channel on which the operator has answered the coming faults."""
    control = Control(asks_operator=True)
    for decision in decisions:
        control.answer(decision)
    return control


def test_a_skipped_point_is_missing_and_the_rest_measured(tmp_path):
    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
    control = operator_answers("skip")
    outcome = start_campaign(config(), tmp_path / "c", opener=machine, control=control)
    assert outcome.status == "completed" and outcome.points == 11
    assert [(f["point"], f["data"]["error"]) for f in events(tmp_path / "c", "fault")] == [(2, "AxisError")]
    assert [r[0] for r in rows(tmp_path / "c")] == [i for i in range(12) if i != 2]
    assert [e["point"] for e in events(tmp_path / "c", "skip")] == [2]


def test_abort_by_policy_stops_halted_and_resumable(tmp_path):
    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=6)))
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    outcome = start_campaign(cfg, tmp_path / "c", opener=machine)  # move 6: to 100 mm from above
    assert outcome.status == "interrupted" and outcome.points == 3
    assert open_campaign(tmp_path / "c").status == "interrupted"
    assert events(tmp_path / "c", "halt", ok=True)
    assert events(tmp_path / "c", "stop")[0]["data"] == {"status": "interrupted", "points": 3}
    again = resume_campaign(tmp_path / "c", opener=FakeMachine())
    assert again.status == "completed" and rows(tmp_path / "c") == expected_rows(config())
    runs = open_campaign(tmp_path / "c").runs
    assert [(r["record"], r.get("status")) for r in runs] == [("start", None), ("stop", "interrupted"),
                                                              ("start", None), ("stop", "completed")]
    assert runs[2]["first_point"] == 3


def test_resume_reapproaches_the_point_in_its_own_direction(tmp_path):
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    # the 6th command is the move to the first target approached from above (100 mm, point 3)
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    first = len(rows(tmp_path / "c"))
    point = build_plan(cfg).points[first]
    machine = FakeMachine()
    resume_campaign(tmp_path / "c", opener=machine)
    moves = machine.openings[0].axis.moves
    assert moves[0][0] == point.target - point.direction * 2.0  # from the overrun side
    assert moves[1][0] == point.target


def test_pause_holds_between_points(tmp_path):
    class PausesOnce(Observer):
        def __init__(self):
            self.control = None

        def emit(self, event):
            if event.kind == "point" and event.point == 3:
                self.control.request_pause()
            if event.kind == "pause":
                self.control.request_resume()  # the operator presses r at once

    from campaign.measure.executor import Control

    observer, control = PausesOnce(), Control()
    observer.control = control
    outcome = start_campaign(config(), tmp_path / "c", opener=FakeMachine(), observer=observer, control=control)
    assert outcome.status == "completed"
    pause, unpause = events(tmp_path / "c", "pause"), events(tmp_path / "c", "unpause")
    assert [e["point"] for e in pause] == [3] and len(unpause) == 1


def test_beam_loss_retries_the_capture_and_never_averages_a_bad_reading(tmp_path):
    def cut_the_beam(parts):
        parts.laser.beam_off.append((0.85, 1.05))  # during the first point's capture window (0.7 to 1.2 s)

    outcome = start_campaign(config(), tmp_path / "c", opener=FakeMachine(setup=cut_the_beam))
    assert outcome.status == "completed"
    assert rows(tmp_path / "c") == expected_rows(config())
    assert events(tmp_path / "c", "capture_retry")
    assert events(tmp_path / "c", "beam", ok=False) and events(tmp_path / "c", "beam", ok=True)


def test_a_full_disk_stops_the_campaign_and_resume_completes_it(tmp_path):
    outcome = start_campaign(config(), tmp_path / "c", opener=FakeMachine(disk_full_at_s=12.0))
    assert outcome.status == "interrupted" and "recording failed" in outcome.message
    assert 0 < outcome.points < 12
    again = resume_campaign(tmp_path / "c", opener=FakeMachine())
    assert again.status == "completed" and rows(tmp_path / "c") == expected_rows(config())


def test_ctrl_c_halts_and_marks_the_directory_interrupted(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        start_campaign(config(), tmp_path / "c", opener=FakeMachine(), on_open=ctrl_c_after_three_points)
    assert open_campaign(tmp_path / "c").status == "interrupted"
    assert events(tmp_path / "c", "interrupt", by="Ctrl-C")
    assert events(tmp_path / "c", "halt", ok=True, why="interrupted")
    assert len(rows(tmp_path / "c")) == 3


def test_a_failing_display_never_stops_the_campaign(tmp_path):
    class Broken(Observer):
        def emit(self, event):
            raise RuntimeError("the terminal went away")

        def reading(self, t_s, reading, target):
            raise RuntimeError("the terminal went away")

    outcome = start_campaign(config(), tmp_path / "c", opener=FakeMachine(), observer=Broken())
    assert outcome.status == "completed" and outcome.points == 12
    assert len(events(tmp_path / "c", "display")) == 1


def test_resume_after_an_edited_config_refuses_and_names_the_key(tmp_path):
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    path = tmp_path / "c" / "config.toml"
    path.write_text(path.read_text().replace("targets = [0.0, 50.0, 100.0]", "targets = [3.0, 53.0, 103.0]"))
    before = (tmp_path / "c" / "points.csv").read_bytes()
    with pytest.raises(InputError, match=r"config.toml: plan.targets is \[3.0, 53.0, 103.0\] now, "
                                         r"\[0.0, 50.0, 100.0\] when recorded"):
        resume_campaign(tmp_path / "c", opener=FakeMachine())
    assert (tmp_path / "c" / "points.csv").read_bytes() == before  # nothing touched


def test_resume_accepts_a_changed_connection_or_operator(tmp_path):
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    path = tmp_path / "c" / "config.toml"
    path.write_text(path.read_text() + '[axis_driver]\nip = "10.0.0.7"\n')
    path.write_text(path.read_text().replace('machine = "fake"', 'machine = "fake"\noperator = "night shift"'))
    assert resume_campaign(tmp_path / "c", opener=FakeMachine()).status == "completed"


def test_resume_uses_the_recorded_plan_not_todays_plan_builder(tmp_path, monkeypatch):
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    import campaign.plan

    def different_builder(config):  # a later axiscal that plans differently
        raise AssertionError("resume must not rebuild a recorded plan")

    monkeypatch.setattr(campaign.plan, "build_plan", different_builder)
    assert resume_campaign(tmp_path / "c", opener=FakeMachine()).status == "completed"
    assert rows(tmp_path / "c") == expected_rows(config())


def old_directory(tmp_path, targets_recorded):
    """A directory as axiscal 0.1 left it: meta.json with a status, no plan.jsonl or runs.jsonl."""
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    d = tmp_path / "c"
    meta = json.loads((d / "meta.json").read_text())
    for key in ("format_version", "config"):
        meta.pop(key)
    meta.update(status="interrupted", targets=targets_recorded)
    (d / "meta.json").write_text(json.dumps(meta))
    for name in ("plan.jsonl", "runs.jsonl", "events.jsonl"):
        (d / name).unlink()
    return d


def test_an_old_directory_resumes_with_the_rebuilt_plan(tmp_path):
    d = old_directory(tmp_path, [0.0, 50.0, 100.0])
    assert open_campaign(d).status == "interrupted" and open_campaign(d).format_version == 1
    assert resume_campaign(d, opener=FakeMachine()).status == "completed"
    assert rows(d) == expected_rows(config())


def test_an_old_directory_whose_config_changed_is_refused(tmp_path):
    d = old_directory(tmp_path, [0.0, 40.0, 100.0])
    with pytest.raises(InputError, match=r"config.toml: target 2 is 50 now, 40 when recorded"):
        resume_campaign(d, opener=FakeMachine())


def test_resume_measures_a_skipped_point_and_the_table_reads_in_plan_order(tmp_path):
    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
    first = start_campaign(config(), tmp_path / "c", opener=machine, control=operator_answers("skip"))
    assert first.status == "completed" and first.points == 11  # completed, one point short
    second = FakeMachine()
    again = resume_campaign(tmp_path / "c", opener=second)
    assert (again.status, again.points, again.planned) == ("completed", 12, 12)
    file_order = [int(ln.split(",")[5]) for ln in (tmp_path / "c" / "points.csv").read_text().splitlines()
                  if ln[:1].isdigit()]
    assert file_order == [i for i in range(12) if i != 2] + [2]  # appended, never rewritten
    assert rows(tmp_path / "c") == expected_rows(config())  # read in plan order, no duplicate
    point = build_plan(config()).points[2]
    moves = second.openings[0].axis.moves
    assert moves[:2] == [(point.target - point.direction * 2.0, 25.0), (point.target, 25.0)]
    assert len(moves) == 2  # the re-approach and the point: the rest was measured before
    resume = events(tmp_path / "c", "resume")[0]
    assert resume["data"] == {"first_point": 2, "points": 1, "skipped": [2]}
    with pytest.raises(InputError, match="already completed"):
        resume_campaign(tmp_path / "c", opener=FakeMachine())


def test_skip_policy_without_an_operator(tmp_path):
    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "skip"}})
    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
    outcome = start_campaign(cfg, tmp_path / "c", opener=machine)
    assert outcome.status == "completed" and outcome.points == 11
    assert [e["point"] for e in events(tmp_path / "c", "skip")] == [2]


def test_a_resumed_campaign_publishes_each_run_from_idle_to_stopped(tmp_path):
    """Each run of the executor in one directory starts idle and ends stopped: an aborted run, then
    its resume that completes it; the directory's last state is stopped: completed."""
    cfg = config_with(config(), {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    assert resume_campaign(tmp_path / "c", opener=FakeMachine()).status == "completed"
    first, second = runs_of_states(tmp_path / "c")
    assert first[-1][1:] == ("stopped", "interrupted: axis error 17744 (0x4550) during the move to 100")
    assert second[-1] == ("idle", "stopped", "completed")


def test_an_event_payload_is_checked_where_it_is_written_and_where_it_is_read(tmp_path):
    from campaign.record import Event

    with pytest.raises(ValueError, match="point event: data missing deviation"):
        Event(1.0, "point", "a point", 0, {"run": 1, "direction": 1, "target": 0.0})
    with pytest.raises(ValueError, match="data.ok = 'yes' is not bool"):
        Event(1.0, "beam", "beam lost", 0, {"ok": "yes", "signal_pct": None})
    with pytest.raises(ValueError, match="unknown event kind"):
        Event(1.0, "teleport", "beamed up")
    start_campaign(config(), tmp_path / "c", opener=FakeMachine())
    path = tmp_path / "c" / "events.jsonl"
    lines = path.read_text().splitlines()
    record = json.loads(lines[5])
    record["data"]["state"] = "dancing"
    lines[5] = json.dumps(record)
    path.write_text("\n".join(lines) + "\n")
    from campaign.record import read_events

    with pytest.raises(InputError, match=r"events.jsonl:6: not an axiscal event: state event: data.state = 'dancing'"):
        read_events(tmp_path / "c")


@pytest.mark.parametrize("shift_mm, ok", [(0.0, True), (0.5, False)])
def test_the_resume_checklist_sees_a_re_zeroed_laser(tmp_path, shift_mm, ok):
    from campaign.guide.checklist import datum_item
    from campaign.measure.session import prepare_resume
    from campaign.record.directory import last_reading_offset

    cfg = config()
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    r = prepare_resume(tmp_path / "c")
    recorded = last_reading_offset(r.path, r.plan)
    assert recorded == pytest.approx(linear_error_um(100.0, 1) / 1000, abs=1e-6)  # the last point: 100 mm, +
    hw, _ = r.open(FakeMachine(setup=lambda p: setattr(p.laser, "offset", shift_mm)))
    try:
        item = datum_item(hw, r.config, recorded)
    finally:
        hw.close()
        r.close()
    assert item.ok is ok, item.value


def published_states(directory) -> list[tuple[str, str, str]]:
    """(previous, state, reason) of every `state` event in events.jsonl, checked against the one
    state machine: each event starts where the one before it ended, along a listed transition."""
    from campaign.record import TRANSITIONS, RunState

    states = [(e["data"]["previous"], e["data"]["state"], e["data"]["reason"]) for e in events(directory, "state")]
    assert states and states[0][0] == "idle"
    for (_, before, _), (after_from, _, _) in itertools.pairwise(states):
        assert after_from == before
    assert all(RunState(b) in TRANSITIONS[RunState(a)] for a, b, _ in states)
    return states


def runs_of_states(directory) -> list[list[tuple[str, str, str]]]:
    """The `state` events of a directory split into its runs (a resume is a new run): each run
    starts idle, follows the state machine and ends stopped with a reason."""
    from campaign.record import TRANSITIONS, RunState

    runs: list[list[tuple[str, str, str]]] = [[]]
    for e in events(directory, "state"):
        runs[-1].append((e["data"]["previous"], e["data"]["state"], e["data"]["reason"]))
        if e["data"]["state"] == "stopped":
            runs.append([])
    assert runs.pop() == [], "the last run did not end stopped"
    for run in runs:
        assert run[0][0] == "idle" and run[-1][1] == "stopped" and run[-1][2]
        assert all(RunState(b) in TRANSITIONS[RunState(a)] for a, b, _ in run)
        assert all(after[0] == before[1] for before, after in itertools.pairwise(run))
    return runs


def refuse_reset(parts):
    """An axis fault at the 4th move whose error the drive then refuses to clear."""
    from protocols.hardware import AxisError

    def reset():
        raise AxisError("reset refused (fake)", 0x4551)

    parts.axis.faults.append(AxisFault(move=4))
    parts.axis.reset = reset


def ctrl_c_after_three_points(hardware, parts, executor):
    def at(t):
        if executor.rec.points_written == 3:
            raise KeyboardInterrupt

    parts.clock.listeners.append(at)


@pytest.mark.parametrize("case", ["completed", "abort", "recovery_failed", "ctrl_c", "disk_full", "refused_motion"])
def test_every_run_publishes_its_states_and_ends_stopped_with_the_reason(tmp_path, case):
    """Every transition is a `state` event in events.jsonl and every exit ends in `stopped`, with
    the reason, also a run whose recovery after a fault failed (it ended in `faulted` before)."""
    cfg, kwargs, expected = config(), {}, "completed"
    machine = FakeMachine()
    if case == "abort":
        machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
        kwargs["control"], expected = operator_answers("abort"), "interrupted: axis error 17744"
    elif case == "recovery_failed":
        machine = FakeMachine(setup=refuse_reset)
        expected = "interrupted: axis not ready after the fault: reset refused"
    elif case == "ctrl_c":
        kwargs["on_open"], expected = ctrl_c_after_three_points, "interrupted (Ctrl-C)"
    elif case == "disk_full":
        kwargs["on_open"], expected = lambda hw, parts, ex: ex.rec.inject_disk_full(), "interrupted: recording failed: "
    elif case == "refused_motion":  # a plan step beyond the limits, as a corrupted recorded plan would have
        kwargs["on_open"] = lambda hw, parts, ex: setattr(ex, "axis", replace(ex.axis, soft_limit_max=101.0))
        expected = "interrupted: motion to 102 mm is outside the soft limits"
    try:
        start_campaign(cfg, tmp_path / "c", opener=machine, **kwargs)
    except KeyboardInterrupt:
        assert case == "ctrl_c"
    except SafetyError:
        assert case == "refused_motion"
    states = published_states(tmp_path / "c")
    previous, last, reason = states[-1]
    assert last == "stopped" and reason.startswith(expected), states[-3:]
    if case == "recovery_failed":
        assert previous == "faulted"
    assert [e["kind"] for e in events(tmp_path / "c")][-1] == "stop"


def test_the_operator_answers_through_the_control_channel_and_nothing_else_decides(tmp_path):
    """A display is a passive sink: an observer cannot answer a fault; the control's answer does."""
    class Display(Observer):
        def fault(self, exc, point):  # the old way a display decided: never called now
            raise AssertionError("a display decided a fault")

    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
    outcome = start_campaign(config(), tmp_path / "c", opener=machine, observer=Display(),
                             control=operator_answers("retry"))
    assert outcome.status == "completed" and rows(tmp_path / "c") == expected_rows(config())
    assert [e["point"] for e in events(tmp_path / "c", "retry")] == [2]
    assert events(tmp_path / "c", "display") == []


def failing_opener(spec, **kwargs):
    """An opener whose controller does not answer (as an unreachable PLC)."""
    from protocols.hardware import AxisError

    raise AxisError("no answer from the controller (test)", 0)


def test_a_campaign_whose_machine_never_opens_ends_stopped(tmp_path):
    """The directory is made before the machine opens: when the opener fails, its events.jsonl still
    ends in `stopped` with the reason (it held no event at all before), and resume completes it."""
    from protocols.hardware import AxisError

    with pytest.raises(AxisError):
        start_campaign(config(), tmp_path / "c", opener=failing_opener)
    (run,) = runs_of_states(tmp_path / "c")
    assert run == [("idle", "stopped", ("interrupted: the machine did not open: AxisError: "
                                        "no answer from the controller (test)"))]
    assert resume_campaign(tmp_path / "c", opener=FakeMachine()).status == "completed"
    assert runs_of_states(tmp_path / "c")[-1][-1] == ("idle", "stopped", "completed")


def test_a_resume_whose_machine_never_opens_ends_stopped(tmp_path):
    from protocols.hardware import AxisError

    cfg = config_with(config(), {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    with pytest.raises(AxisError):
        resume_campaign(tmp_path / "c", opener=failing_opener)
    runs = runs_of_states(tmp_path / "c")
    assert len(runs) == 2 and runs[-1][-1][1:] == ("stopped", ("interrupted: the machine did not open: "
                                                               "AxisError: no answer from the controller (test)"))


def test_a_resume_with_nothing_left_ends_stopped(tmp_path):
    """A run killed after its last point, before its stop: the resume measures nothing and its last
    state is `stopped` (it was the killed run's `capturing` or `moving`)."""
    start_campaign(config(), tmp_path / "c", opener=FakeMachine())
    for name in ("events.jsonl", "runs.jsonl"):  # as if killed before the closing move's events and stop
        path = tmp_path / "c" / name
        lines = path.read_text().splitlines(keepends=True)
        keep = [ln for ln in lines if '"stop"' not in ln and '"state": "stopped"' not in ln and '"state": "idle"' not in ln]
        path.write_text("".join(keep))
    assert resume_campaign(tmp_path / "c", opener=FakeMachine()).status == "completed"
    assert events(tmp_path / "c", "state")[-1]["data"]["state"] == "stopped"
    assert events(tmp_path / "c")[-1]["kind"] == "stop"

"""The guide's dashboard shows the run state the executor publishes (its `state` events), never
one it derives; the operator's pending request is shown beside it."""

import io

from rich.console import Console

from campaign.config import parse_config
from campaign.guide.dashboard import Dashboard
from campaign.measure import Control, start_campaign
from campaign.plan import build_plan
from campaign.record import Event, RunState, StateData
from tests.fakes import SMALL, AxisFault, FakeMachine


def dashboard(control: Control | None = None) -> tuple[Dashboard, io.StringIO]:
    config = parse_config(SMALL, "small.toml")
    out = io.StringIO()
    console = Console(file=out, width=120, force_terminal=False)
    return Dashboard(console, config, build_plan(config), control or Control(), None), out


def state(previous: RunState, now: RunState, reason: str = "") -> Event:
    return Event(1.0, "state", f"{previous} -> {now}", None, StateData(state=now, previous=previous, reason=reason))


def test_the_dashboard_renders_the_published_state_and_the_pending_request():
    control = Control()
    dash, _ = dashboard(control)
    assert "STARTING" in dash.state_text()
    dash.emit(state(RunState.IDLE, RunState.MOVING, "to point 1"))
    assert dash.state is RunState.MOVING and "MOVING" in dash.state_text()
    dash.on_key("p")  # a pause is a request until the executor publishes `paused`
    assert control.pause_requested() and "MOVING · pause requested" in dash.state_text()
    dash.emit(state(RunState.MOVING, RunState.CAPTURING))
    assert "CAPTURING · pause requested" in dash.state_text()
    dash.emit(state(RunState.CAPTURING, RunState.PAUSED, "the operator asked for a pause"))
    assert "PAUSED" in dash.state_text() and "pause requested" not in dash.state_text()
    dash.emit(state(RunState.PAUSED, RunState.STOPPED, "interrupted (a pressed)"))
    assert dash.state_text() == "[bold red]STOPPED: interrupted (a pressed)[/]"


def test_a_campaign_on_the_dashboard_ends_in_the_state_the_executor_published(tmp_path):
    """The whole stream of a run with a fault the policy retries: the dashboard follows the
    executor's states (faulted, then moving again) and ends in stopped: completed."""
    config = parse_config(SMALL, "small.toml")
    dash, out = dashboard()
    seen: list[RunState] = []
    original = dash._state

    def spy(event):
        original(event)
        seen.append(dash.state)

    dash._state = spy
    machine = FakeMachine(setup=lambda parts: parts.axis.faults.append(AxisFault(move=4)))
    outcome = start_campaign(config, tmp_path / "c", opener=machine, observer=dash)
    assert outcome.status == "completed"
    assert RunState.FAULTED in seen and seen[seen.index(RunState.FAULTED) + 1] is RunState.MOVING
    assert seen[-1] is RunState.STOPPED and dash.state_reason == "completed"
    assert "state: stopped (completed)" in out.getvalue()  # a script's one line for the end

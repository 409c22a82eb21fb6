"""`axiscal guide`: the checklist, the confirmation, the keys in a real pseudo-terminal, faults and
the verdict, all on the simulated machine (real pyads client, loopback ADS server, pty serial)."""

import io
import json
import os
import re
import signal
import subprocess
import sys
import time

import pexpect
import pytest

from campaign.cli import build_parser
from campaign.commands import guide
from campaign.errors import InputError
from campaign.guide.dashboard import signed_sparkline, sparkline
from campaign.guide.keys import CtrlC, Keys
from campaign.measure.executor import Control
from campaign.record import RunState
from tests.conftest import ROOT, assert_one_line_error, events, status

SMALL = """
[campaign]
machine = "sim-test"
operator = "tester"
tolerance = {tolerance}

[axis]
name = "X"
soft_limit_min = -10.0
soft_limit_max = 110.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 100.0
count = 6
overrun = 2.0
cycles = 5
dwell_s = 1.0
velocity = 20.0

[axis_driver]
type = "sim"

[instrument]
type = "sim"

[capture]
average_s = 0.5
retries = 0

[sim.effects.linear_scale]
ppm = -12.4

[sim.effects.noise]
sigma_um = 0.3
reading_sigma_um = 0.05
"""
"""60 points over 100 mm, about 2 min of machine time; A is about 3 µm."""


@pytest.fixture
def small_config(tmp_path):
    def write(tolerance=10.0):
        path = tmp_path / f"small-{tolerance:g}.toml"
        path.write_text(SMALL.format(tolerance=tolerance))
        return path

    return write


def guide_args(*argv):
    words = ["guide", *map(str, argv)]
    return build_parser(words).parse_args(words)


def count_points(out):
    """Complete point rows in out/points.csv so far (a row being written is not counted)."""
    path = out / "points.csv"
    rows = path.read_text().split("\n")[:-1] if path.exists() else []
    return sum(row[:1].isdigit() for row in rows)


def spy_on_moves(moves):
    """An on_hardware hook that records every move the guide commands."""
    def hook(hw, sim):
        start_move = hw.axis.start_move
        hw.axis.start_move = lambda pos, vel: (moves.append(pos), start_move(pos, vel))[1]
    return hook


# -- scripts -----------------------------------------------------------------------------------

@pytest.mark.machine
@pytest.mark.parametrize("tolerance, verdict", [(10.0, "PASS"), (0.3, "FAIL")])
def test_a_script_runs_the_whole_session(tmp_path, small_config, tolerance, verdict):
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "campaign", "guide", small_config(tolerance), "--out", out,
                           "--yes"], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120,
                          cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "Setup checklist" in proc.stdout and "FAIL " not in proc.stdout.split("Axis summary")[0]
    assert f"{verdict}: accuracy A = " in proc.stdout
    assert f"axiscal report {out} -o {out}/report.html" in proc.stdout
    assert f"axiscal compensate {out}/points.csv --format" in proc.stdout
    assert status(out) == "completed"
    assert count_points(out) == 60


@pytest.mark.machine
def test_a_script_must_confirm_with_yes(tmp_path, small_config, cli):
    result = cli("guide", small_config(), "--out", tmp_path / "never")
    assert_one_line_error(result, "confirmation needed", "--yes")
    assert not (tmp_path / "never" / "meta.json").exists()


@pytest.mark.machine
def test_a_failed_check_stops_before_any_motion(tmp_path, small_config):
    moves = []

    def not_homed(hw, sim):
        spy_on_moves(moves)(hw, sim)
        sim.plc.homed = False

    with pytest.raises(InputError, match="setup check failed: controller: .*homed NO"):
        guide.run(guide_args(small_config(), "--out", tmp_path / "r", "--yes"), on_hardware=not_homed)
    assert moves == [] and not (tmp_path / "r").exists()


def test_a_plan_outside_the_soft_limits_fails_before_opening_hardware(tmp_path, small_config, cli):
    path = small_config()
    path.write_text(path.read_text().replace("overrun = 2.0", "overrun = 20.0"))
    result = cli("guide", path, "--out", tmp_path / "r", "--yes")
    assert_one_line_error(result, "soft limits", "outside")


@pytest.mark.machine
def test_the_alignment_check_fails_on_a_beam_break(tmp_path, small_config):
    moves = []

    def break_the_beam(hw, sim):
        spy_on_moves(moves)(hw, sim)
        sim.instrument.beam_break(sim.clock.now() + 2.0, sim.clock.now() + 4.0)  # during the first move

    with pytest.raises(InputError, match="laser alignment: .*beam LOST"):
        guide.run(guide_args(small_config(), "--out", tmp_path / "r", "--yes"), on_hardware=break_the_beam)
    assert moves == [102.0, -2.0]  # to both ends of the plan, then stopped before the campaign
    assert not (tmp_path / "r" / "meta.json").exists()


@pytest.mark.machine
def test_on_fault_skip_skips_the_points_without_beam(tmp_path, small_config, capsys):
    out = tmp_path / "r"

    def break_the_beam_mid_campaign(hw, sim):
        sim.instrument.beam_break(40.0, 46.0)  # machine time s; the campaign starts at about 15 s

    code = guide.run(guide_args(small_config(), "--out", out, "--yes", "--on-fault", "skip", "--json"),
                     on_hardware=break_the_beam_mid_campaign)
    result = json.loads(capsys.readouterr().out)
    assert code == 0 and result["status"] == "completed"
    assert 0 < result["points"] < result["planned"] == 60
    assert result["verdict"] == "not judged" and any("planned points are missing" in r for r in result["reasons"])
    assert len(events(out, "skip")) == 60 - result["points"]
    assert events(out, "fault", error="BeamLost")


@pytest.mark.machine
def test_the_fault_prompt_takes_one_key_from_the_terminal():
    """The keys typed once the prompt waits: an unknown one ignored, the next taken. (Typed before
    the prompt waited, they went to on_key, as keys before a prompt do, and the test waited forever
    when its reader thread was quicker than `ask`: a hang of the whole suite. Now it types once the
    prompt waits, and an abort after 10 s makes a lost key a failure, not a hang.)"""
    import threading

    master, slave = os.openpty()
    before: list[str] = []
    control = Control()
    give_up = threading.Timer(10.0, control.request_abort)
    try:
        with Keys(before.append, fd=slave) as keys:

            def type_when_asked() -> None:
                deadline = time.monotonic() + 10.0
                while keys._answers is None and time.monotonic() < deadline:
                    time.sleep(0.005)
                os.write(master, b"xs")  # an unknown key is ignored

            threading.Thread(target=type_when_asked, daemon=True).start()
            give_up.start()
            assert keys.ask({"r": "retry", "s": "skip", "a": "abort"}, control) == "skip"
            assert before == []
    finally:
        give_up.cancel()
        os.close(master)
        os.close(slave)


def test_sparkline_scales_between_the_lowest_and_highest_value():
    assert sparkline([0.0, None, 5.0, 10.0], 0.0, 10.0) == "▁·▅█"
    assert sparkline([1.0, 2.0], 0.0, 10.0, width=2) == "▂▂▂▂"


def test_the_signed_chart_has_zero_in_the_middle():
    assert signed_sparkline([0.0, -1.0, -2.0, 2.0, None], 2.0) == "▄▃▁▇·"


def small_dashboard():
    from rich.console import Console

    from campaign.config import parse_config
    from campaign.guide import Dashboard
    from campaign.plan import build_plan
    from tests.fakes import SMALL

    config = parse_config(SMALL, "small.toml")
    plan = build_plan(config)
    console = Console(file=io.StringIO(), width=120, force_terminal=False, color_system=None)
    return Dashboard(console, config, plan, Control(), None), console, plan


def test_the_dashboard_chart_is_signed_and_more_negative_is_lower():
    """Deviations all below 0: the 0 line is the middle block and the bars go down as the deviation
    grows more negative (the old chart drew 0 as a full bar and shrank the bars instead)."""
    dashboard, console, plan = small_dashboard()
    ups = [p for p in plan.points if p.direction > 0 and p.run == 1]
    for point, deviation in zip(ups, (-1.0, -2.0, -3.0)):
        dashboard.point_done(point, deviation, 1.0)
    console.print(dashboard._chart())
    rows = {line.split()[0] + line.split()[1] if line.split()[0] in "↑↓" else line.split()[0]: line
            for line in console.file.getvalue().splitlines() if line.strip()}
    width = 48 // 3  # characters per target
    up = rows["↑+"].split()[-1]
    assert up == "▃" * width + "▂" * width + "▁" * width, up  # -1, -2, -3 on ±3: below 0, lower as they grow
    assert rows["0"].split()[1] == "▄" * 3 * width and "±3.00 µm" in rows["0"]


def test_the_key_line_follows_the_state():
    """The key line renders the published run state and the operator's pending request."""
    dashboard, console, _ = small_dashboard()
    for state, request, offered, not_offered in (
            (RunState.MOVING, None, "p pause", "r resume"), (RunState.PAUSED, None, "r resume", "p pause"),
            (RunState.CAPTURING, "pause requested", "r cancel the pause", "p pause"),
            (RunState.MOVING, "aborting", "aborting", "p pause"), (RunState.STOPPED, None, None, "p pause")):
        dashboard.state, dashboard.request = state, request
        console.file.truncate(0)
        console.file.seek(0)
        console.print(dashboard)
        screen = console.file.getvalue()
        assert (offered is None or offered in screen) and not_offered not in screen, (state, request, screen)


# -- a technician at a real terminal -----------------------------------------------------------

def spawn_guide(config, out, speed="10"):
    env = dict(os.environ, TERM="xterm")
    env.pop("NO_COLOR", None)
    child = pexpect.spawn(sys.executable, ["-m", "campaign", "guide", str(config), "--out", str(out),
                                           "--speed", speed], cwd=str(ROOT), env=env, dimensions=(40, 120),
                          encoding="utf-8", timeout=30)
    child.logfile_read = io.StringIO()
    return child


def keep_reading_until(child, condition, timeout=30.0) -> bool:
    """Read the screen (so the program never blocks on a full pty) until condition() holds."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        try:
            child.read_nonblocking(1 << 16, timeout=0.1)
        except pexpect.TIMEOUT:
            pass
    return condition()


def confirm_and_wait_for_points(child, out, n):
    child.expect("Start the motion")
    child.sendline("y")
    child.expect("MOVING")
    assert keep_reading_until(child, lambda: count_points(out) >= n)


@pytest.mark.machine
def test_keys_pause_resume_and_abort_in_a_terminal(tmp_path, small_config):
    out = tmp_path / "run"
    child = spawn_guide(small_config(), out)
    try:
        confirm_and_wait_for_points(child, out, 2)
        child.send("p")
        child.expect("PAUSED")
        paused_at = count_points(out)
        keep_reading_until(child, lambda: False, timeout=2.0)  # 2 s real = 20 s of machine time
        assert count_points(out) == paused_at
        child.send("r")
        assert keep_reading_until(child, lambda: count_points(out) > paused_at + 1)
        child.send("a")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    assert child.exitstatus == 3, screen[-2000:]
    assert "Traceback" not in screen
    assert f"axiscal resume {out}" in screen and "aborted by the operator (a pressed)" in screen
    assert status(out) == "interrupted"
    assert events(out, "pause") and events(out, "unpause")
    assert events(out, "halt", ok=True, why="interrupted")
    assert count_points(out) < 60


@pytest.mark.machine
def test_ctrl_c_aborts_like_a(tmp_path, small_config):
    out = tmp_path / "run"
    child = spawn_guide(small_config(), out)
    try:
        confirm_and_wait_for_points(child, out, 1)
        child.sendintr()
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    assert child.exitstatus == 3 and "Traceback" not in screen
    assert "aborted by the operator (Ctrl-C)" in screen
    assert status(out) == "interrupted"
    assert events(out, "halt", ok=True, why="interrupted")


def test_a_second_ctrl_c_says_the_stop_is_under_way_and_a_third_quits():
    """The first Ctrl-C asks the campaign to stop (the executor halts the axis at its next tick).
    The second neither talks to the controller from the signal handler (the old one called halt()
    there: in the middle of the main thread's own exchange with the controller, a hang) nor raises
    in the middle of the stop record; it says the stop is under way. A third quits at once."""
    calls = []

    class FakeDashboard:
        def abort(self, why):
            calls.append(f"abort: {why}")

        def say(self, message):
            calls.append(message)

    before = signal.getsignal(signal.SIGINT)
    with CtrlC(FakeDashboard()):
        os.kill(os.getpid(), signal.SIGINT)
        assert calls == ["abort: Ctrl-C"]  # the first only asks the campaign to stop
        os.kill(os.getpid(), signal.SIGINT)
        assert len(calls) == 2 and "already stopping" in calls[1] and "a third Ctrl-C quits" in calls[1]
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    assert len(calls) == 2
    assert signal.getsignal(signal.SIGINT) is before  # restored

    # with `then`, a Ctrl-C as the campaign ends meets that handler (the guide's: said, ignored while the
    # summary is written), not the one before: no gap in which it would end the program
    held = []
    try:
        with CtrlC(FakeDashboard(), then=lambda signum, frame: held.append(signum)):
            pass
        os.kill(os.getpid(), signal.SIGINT)
        assert held == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, before)


@pytest.mark.machine
def test_a_fault_asks_the_operator_in_a_terminal(tmp_path, small_config):
    config = small_config()
    config.write_text(config.read_text() + "\n[sim.faults]\nbeam_break = { at_s = 40.0, duration_s = 1.0 }\n")
    out = tmp_path / "run"
    child = spawn_guide(config, out)
    try:
        child.expect("Start the motion")
        child.sendline("y")
        child.expect("Press r to retry the point, s to skip it")
        skipped_at = count_points(out)
        child.send("s")
        assert keep_reading_until(child, lambda: count_points(out) > skipped_at + 1)
        child.send("a")  # aborts, or answers a second fault prompt with abort
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    assert child.exitstatus == 3 and "Traceback" not in screen
    assert "beam lost" in screen
    assert [e["point"] for e in events(out, "skip")][:1] == [skipped_at]


def spawn(*argv, speed="10"):
    env = dict(os.environ, TERM="xterm")
    env.pop("NO_COLOR", None)
    child = pexpect.spawn(sys.executable, ["-m", "campaign", *map(str, argv), "--speed", speed], cwd=str(ROOT),
                          env=env, dimensions=(40, 120), encoding="utf-8", timeout=30)
    child.logfile_read = io.StringIO()
    return child


@pytest.mark.machine
def test_a_during_run_1_ends_with_the_summary_so_far_and_the_resume_hint(tmp_path, small_config):
    out = tmp_path / "run"
    child = spawn_guide(small_config(), out)
    try:
        confirm_and_wait_for_points(child, out, 2)  # run 1 has 12 points: target 0 has one direction only
        child.send("a")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    assert child.exitstatus == 3, screen[-2000:]
    assert "Traceback" not in screen and "error:" not in screen
    assert "Axis summary" in screen and "NOT JUDGED" in screen and f"axiscal resume {out}" in screen


@pytest.mark.machine
def test_resume_on_a_terminal_is_guided_and_finishes_the_campaign(tmp_path, small_config):
    out = tmp_path / "run"
    child = spawn_guide(small_config(), out)
    try:
        confirm_and_wait_for_points(child, out, 3)
        child.send("a")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    stopped_at = count_points(out)
    child = spawn("resume", out, speed="20")
    try:
        child.expect("Setup checklist")
        child.expect("laser datum")
        child.expect("re-approach")
        child.expect("Start the motion")
        assert count_points(out) == stopped_at  # nothing moved or recorded before the confirmation
        child.sendline("y")
        child.expect("MOVING")
        child.expect(pexpect.EOF, timeout=120)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    assert child.exitstatus == 0, screen[-2000:]
    assert count_points(out) == 60 and status(out) == "completed"
    assert "PASS" in screen and "Traceback" not in screen
    assert [e["data"]["first_point"] for e in events(out, "resume")] == [stopped_at]


@pytest.mark.machine
def test_a_copied_example_config_runs_the_guide(tmp_path):
    """The shipped example, copied elsewhere, still finds its simulated machine's model (the old one
    named it ../models/..., which broke as soon as the file was copied)."""
    copied = tmp_path / "elsewhere" / "vertical.toml"
    copied.parent.mkdir()
    copied.write_text((ROOT / "data" / "configs" / "vertical-sim.toml").read_text()
                      .replace("cycles = 5", "cycles = 1").replace("count = 11", "count = 3"))
    proc = subprocess.run([sys.executable, "-m", "campaign", "guide", copied, "--out", tmp_path / "run", "--yes"],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=180, cwd=tmp_path,
                          check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr
    assert status(tmp_path / "run") == "completed"


@pytest.mark.machine
def test_a_fixed_config_passes_the_recheck_without_a_restart(tmp_path, small_config):
    """A missing model file is said as such (not as a controller failure); fixing the config and
    pressing Enter checks the config as it is now (the old guide kept the first reading)."""
    config = small_config()
    good = config.read_text()
    config.write_text(good.replace("[sim.effects.linear_scale]", '[sim]\nmodel = "gone.toml"\n[sim.effects.linear_scale]'))
    out = tmp_path / "run"
    child = spawn_guide(config, out)
    try:
        child.expect("Fix it, then press Enter")
        screen = child.logfile_read.getvalue()
        # the cell wraps where the tmp path's length puts it (within the path or between words): read
        # it with the table's borders and every space and line break taken out
        cells = re.sub(r"[\s│]+", "", screen)
        assert "errormodel" in cells and "gone.toml" in cells and "ismissing" in cells, screen[-3000:]
        config.write_text(good)
        child.sendline("")
        child.expect("Start the motion")
        child.sendline("n")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    after_fix = screen.split("Fix it, then press Enter")[-1]
    assert "gone.toml" not in after_fix and "FAIL" not in after_fix, after_fix[-3000:]
    assert "│ config " in screen.split("Fix it")[0] or "config " in screen.split("Fix it")[0]
    assert "cannot open the hardware" not in screen  # not said to be the controller


@pytest.mark.machine
def test_a_second_ctrl_c_still_prints_the_summary_and_the_resume_line(tmp_path, small_config):
    out = tmp_path / "run"
    child = spawn_guide(small_config(), out)
    try:
        confirm_and_wait_for_points(child, out, 2)
        child.sendintr()
        time.sleep(0.05)
        child.sendintr()
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    screen = child.logfile_read.getvalue()
    assert child.exitstatus == 3, screen[-2000:]
    assert "Traceback" not in screen and "error: interrupted" not in screen
    assert "Campaign interrupted" in screen and f"axiscal resume {out}" in screen, screen[-2000:]
    assert status(out) == "interrupted"


def test_a_copied_example_finds_its_shipped_model_and_a_missing_one_is_said_as_such(tmp_path):
    """The shipped examples name their model by name, found wherever the config is copied (the old
    '../models/…' broke on the copy); a missing model file is named as the simulated machine's
    error model, and a follow-up config keeps the name (no path made relative to it)."""
    from campaign.config import load_config
    from campaign.discovery.followup import _moved_paths
    from campaign.model import sim_model

    for name in ("horizontal-sim.toml", "vertical-sim.toml"):
        copied = tmp_path / name
        copied.write_text((ROOT / "data" / "configs" / name).read_text())
        config = load_config(copied)
        assert sim_model(config.sim).effects, name
        assert "sim" not in _moved_paths(config, tmp_path / "elsewhere")
    broken = tmp_path / "broken.toml"
    broken.write_text((ROOT / "data" / "configs" / "vertical-sim.toml").read_text()
                      .replace('model = "seed000-vertical"', 'model = "../models/gone.toml"'))
    with pytest.raises(InputError, match=r"\[sim\] model: the simulated machine's error model .*gone.toml is missing"):
        sim_model(load_config(broken).sim)
    unknown = tmp_path / "unknown.toml"
    unknown.write_text(broken.read_text().replace('"../models/gone.toml"', '"seed999"'))
    with pytest.raises(InputError, match="no shipped error model of that name .*seed000-horizontal"):
        sim_model(load_config(unknown).sim)

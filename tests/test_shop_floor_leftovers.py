"""The shop-floor leftovers of issue 31, one test each: what a technician or an engineer reads
(rounded values with units, "1 run", a key suggested, the limit key named, a controller error id
said as one, the planner's cycles said without a contradiction, the papers named in data/)."""

import json
import re

import pytest

from campaign.config import parse_config
from campaign.errors import SafetyError
from campaign.plan import build_plan, check_plan
from tests.conftest import ROOT, assert_one_line_error
from tests.fakes import SMALL, FakeMachine


def test_a_dry_run_prints_rounded_values_with_units(cli, tmp_path, monkeypatch):
    """The old dry run printed `estimated_duration_s 1207.2999999999981` and `travel 6061.863280000002`."""
    monkeypatch.setattr("campaign.commands.run.hardware_opener", lambda: FakeMachine())
    config = tmp_path / "small.toml"
    config.write_text(SMALL)
    result = cli("run", config, "--dry-run")
    assert result.code == 0, result.err
    assert not re.search(r"\d\.\d{5,}", result.out), result.out
    assert "estimated duration" in result.out and " min" in result.out and re.search(r"travel \d+\.\d mm", result.out)
    data = json.loads(cli("run", config, "--dry-run", "--json").out)
    assert data["estimated_duration_s"] == round(data["estimated_duration_s"], 1)


def test_one_run_is_said_in_the_singular(cli, tmp_path):
    from campaign.measure import start_campaign

    start_campaign(parse_config(SMALL.replace("cycles = 2", "cycles = 1"), "small.toml"), tmp_path / "c",
                   opener=FakeMachine())
    text = cli("analyze", tmp_path / "c" / "points.csv").out
    assert "1 run)" in text and "1 runs" not in text
    assert cli("report", tmp_path / "c", "-o", tmp_path / "r.html").code == 0
    assert "1 runs" not in (tmp_path / "r.html").read_text()


@pytest.mark.parametrize("typed, meant", [("dwel_s", "dwell_s"), ("dwell", "dwell_s"), ("velocty", "velocity")])
def test_a_mistyped_key_gets_a_suggestion(cli, tmp_path, typed, meant):
    path = tmp_path / "c.toml"
    path.write_text(SMALL.replace(f"\n{meant} =", f"\n{typed} =", 1))
    assert_one_line_error(cli("plan", path), f"unknown key 'plan.{typed}'", f"did you mean '{meant}'?")


def test_a_far_unknown_key_gets_no_suggestion(cli, tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(SMALL.replace("[capture]", "[capture]\nzzz = 1"))
    result = cli("plan", path)
    assert_one_line_error(result, "unknown key 'capture.zzz'")
    assert "did you mean" not in result.err


def test_the_soft_limit_error_names_its_key_and_the_plan_key():
    overrun = parse_config(SMALL.replace("overrun = 2.0", "overrun = 20.0"), "c.toml")
    with pytest.raises(SafetyError, match=r"below axis\.soft_limit_min = -5 mm .*plan\.overrun"):
        check_plan(build_plan(overrun), overrun.axis)
    target = parse_config(SMALL.replace("[0.0, 50.0, 100.0]", "[0.0, 50.0, 106.0]"), "c.toml")
    with pytest.raises(SafetyError, match=r"motion to 106 mm .*above axis\.soft_limit_max = 105 mm .*plan\.targets"):
        check_plan(build_plan(target), target.axis)


def test_a_controller_error_is_said_as_its_error_id_in_decimal_and_hex():
    from campaign.guide.checklist import controller_item
    from protocols.hardware import AxisStatus

    class Axis:
        def status(self):
            return AxisStatus(busy=False, done=False, error=True, error_id=16992, actual_position=1.0,
                              enabled=True, homed=True)

    hw = type("Hardware", (), {"axis": Axis()})()
    item = controller_item(hw, "mm")
    assert "controller error id 16992 (0x4260)" in item.value and not item.ok


def test_the_correction_planner_does_not_say_it_beats_its_minimum(cli):
    """The old line: "settles after 199 cycles (continuous-time minimum 0.2 s = 200.0 cycles)"."""
    out = cli("correction", "--step", "10", "--max-rate", "100", "--max-accel", "1000", "--cycle-ms", "1").out
    first = out.splitlines()[0]
    assert "settles after 199 cycles = 0.199 s" in first and "continuous-time profile takes 0.2 s" in first
    assert "minimum" not in first


def test_the_comments_in_data_name_the_papers_not_the_seed_files():
    found = [f"{path.relative_to(ROOT)}: {line.strip()}" for path in (ROOT / "data").rglob("*")
             if path.is_file() and path.suffix in (".csv", ".toml", ".md", ".json")
             for line in path.read_text(encoding="utf-8").splitlines() if re.search(r"seed 0\d\d", line, re.IGNORECASE)]
    assert found == []


@pytest.mark.parametrize("fmt, needs", [
    ("pmac", ("--counts-per-unit", "--mode uni")),
    ("fanuc", ("--counts-per-unit", "--reference")),
    ("twincat_cnc", ("--axis-number",)),
])
def test_every_option_a_format_needs_is_said_at_once(cli, tmp_path, fmt, needs):
    """The old compensate revealed them one error at a time."""
    from tests.conftest import PAPER

    result = cli("compensate", PAPER / "vertical_before.csv", "--format", fmt, "-o", tmp_path / "t")
    assert_one_line_error(result, f"--format {fmt} needs", *needs)
    assert not (tmp_path / "t").exists()


def test_the_checklist_keeps_its_rows_when_the_hardware_does_not_open(tmp_path):
    """The old checklist showed the controller row only: the interferometer and environment rows
    are said as not checked, and a file the config names is a config failure, not the controller."""
    from campaign.commands.guide import Setup, open_hardware
    from campaign.errors import InputError
    from protocols.hardware import AxisError

    config = parse_config(SMALL, "small.toml")

    def failing(exc):
        def opener():
            raise exc
        return Setup(config, build_plan(config), [], opener)

    _, _, rows = open_hardware(failing(AxisError("no route", 0)), None)
    names = {r.name: r for r in rows}
    assert names["controller"].ok is False and names["interferometer signal"].ok is None
    assert {"air temperature", "air pressure", "humidity", "material temperature"} <= set(names)
    _, _, rows = open_hardware(failing(InputError("model.toml is missing")), None)
    names = {r.name: r for r in rows}
    assert names["config"].ok is False and names["controller"].ok is None


@pytest.mark.parametrize("width", [60, 80, 120])
def test_progress_lines_never_cut_a_number(width):
    """At 80 columns the old progress line read `1… 0:0…`: now the counts and the time left stay
    whole, and only the live text is cut, at its end."""
    import io

    from rich.console import Console

    from campaign.measure.progress import RichProgress
    from protocols.hardware import Reading

    shown = RichProgress("mm")
    shown.console = Console(file=io.StringIO(), width=width, force_terminal=True, color_system=None)
    shown.progress.live.console = shown.console
    plan = build_plan(parse_config(SMALL.replace("cycles = 2", "cycles = 40"), "small.toml"))
    shown.started(plan, list(range(len(plan.points))))
    shown.reading(100.0, Reading(1.0, 123.45678, True, 90.0, 20.0, 1013.2, 50.0, 20.0), 123.456)
    shown.progress.refresh()
    shown.progress.stop()
    screen = re.sub(r"\x1b\[[0-9;?]*[a-zA-Z]", "", shown.console.file.getvalue()).replace("\r", "\n")
    assert "0/240" in screen and "0/6" in screen and "-:--:--" in screen, screen
    assert not re.search(r"[\d:]…", screen), screen
    assert all(len(line) <= width for line in screen.splitlines())


def test_the_live_line_ends_on_the_last_reading():
    """The live reading is shown at most every 0.5 s of campaign time; the campaign's end shows the last
    one (a new user's trial saw -3.8389 mm left on the line while the axis had gone on to -4.9987)."""
    import io
    import re

    from rich.console import Console

    from campaign.config import parse_config
    from campaign.measure.progress import RichProgress
    from campaign.plan import build_plan
    from protocols.hardware import Reading
    from tests.fakes import SMALL

    with RichProgress("mm") as shown:
        shown.console = Console(file=io.StringIO(), width=120, force_terminal=True, color_system=None)
        shown.progress.live.console = shown.console
        plan = build_plan(parse_config(SMALL, "small.toml"))
        shown.started(plan, list(range(len(plan.points))))
        shown.reading(10.0, Reading(10.0, -3.8389, True, 90.0, 20.0, 1013.2, 50.0, 20.0), None)
        shown.reading(10.2, Reading(10.2, -4.9987, True, 90.0, 20.0, 1013.2, 50.0, 20.0), None)
    screen = re.sub(r"\x1b\[[0-9;?]*[a-zA-Z]", "", shown.console.file.getvalue())
    assert "-4.9987" in screen.splitlines()[-1] or "-4.9987" in screen.split("\r")[-1], screen[-400:]

"""The capture-method registry (issue 33 item 5): one place decides the capture method. A method
registered here, in this file alone, is seen by the command line's choices, the config's
validation, the plan, the executor and replay; the shipped ones by the report and the program
writer through the same registry."""

import itertools
from dataclasses import replace
from statistics import median

import pytest

from campaign import capture_methods
from campaign.capture_methods import METHODS, BeamLost, Captured, CaptureMethod, Window, mean_env, register
from campaign.config import parse_config
from campaign.errors import InputError
from campaign.measure import start_campaign
from campaign.plan import Capture, build_plan
from campaign.pointtable import read_points
from campaign.record import load_raw
from tests.fakes import SMALL, FakeMachine


def _median_capture(spec, w: Window, scale, ticks, start_s, point) -> Captured:
    readings = []
    for wait_s, new in ticks:
        readings.extend(new)
        if wait_s >= start_s + w.window_s - 1e-9:
            if not readings or not all(r.signal_ok for r in readings):
                raise BeamLost("beam not OK")
            return Captured(median(r.position for r in readings), len(readings), wait_s, mean_env(readings))
    raise BeamLost("no more readings")


MEDIAN = CaptureMethod(
    "median", "the median of the last average_s of a fixed dwell", live=True, sweeps=False, iso_230_2=True,
    fixed_dwell=True, window=METHODS["dwell"].window, capture=_median_capture,
    describe=lambda spec, pos, dev: f"median of the last {spec.average_s:g} s",
    step_label=lambda w: ("capture (median)", f"{w.window_s:g}"))


@pytest.fixture
def with_median():
    register(MEDIAN)
    yield MEDIAN
    METHODS.pop("median")


def test_before_it_is_registered_nothing_knows_the_method(cli, tmp_path):
    with pytest.raises(InputError, match="capture.method.*'median' is not one of dwell, stable, scan, stream"):
        parse_config(SMALL + 'method = "median"\n', "small.toml")
    assert cli("demo", "--fake", "--capture", "median").code == 2  # argparse: not a choice


@pytest.mark.machine  # a campaign on the fake machine and two replays: about 1 s
def test_a_registered_method_reaches_the_choices_the_config_the_executor_and_replay(cli, tmp_path, with_median):
    noisy = '[sim.effects.noise]\nsigma_um = 0.3\nreading_sigma_um = 0.5\n'
    config = parse_config(SMALL + 'method = "median"\n' + noisy, "small.toml")
    assert config.capture.method == "median"
    plan = build_plan(config)
    captures = [s for s in plan.steps if isinstance(s, Capture)]
    assert len(captures) == 12 and all(s.spec.method == "median" for s in captures)
    assert captures[0].window_s == 0.5  # the window the registered method gives

    start_campaign(config, tmp_path / "c", opener=FakeMachine(error_um=None))  # the model's noise
    table, raw = read_points(tmp_path / "c" / "points.csv"), load_raw(tmp_path / "c")
    readings = table.extra["reading"]
    differs = 0
    for visit in plan.visits():
        window = raw[(raw.point == visit.point.index) & (raw.step == visit.capture_step)].reading
        assert readings[visit.point.index] == pytest.approx(median(window), abs=1e-8)  # as recorded
        differs += abs(median(window) - window.mean()) > 1e-7
    assert differs > 0  # the median, not the dwell's mean

    # the command line's choices read the registry when the parser is built
    result = cli("replay", tmp_path / "c", "--capture", "median", "--json")
    assert result.code == 0 and '"identical": true' in result.out
    assert cli("replay", tmp_path / "c", "--capture", "dwell", "--json").code == 0


def test_the_shipped_methods_and_what_each_consumer_reads():
    assert capture_methods.names() == ("dwell", "stable", "scan", "stream")
    assert capture_methods.names(live=True, sweeps=False) == ("dwell", "stable")  # replay --capture
    assert [m for m in METHODS.values() if not m.iso_230_2] == [METHODS["scan"]]
    assert not METHODS["stream"].live and METHODS["scan"].sweeps
    dwell = parse_config(SMALL, "small.toml").capture
    assert METHODS["dwell"].describe(dwell, "mm", "µm") == "fixed dwell, mean of the last 0.5 s"
    stable = replace(dwell, method="stable")
    assert METHODS["stable"].window(stable, 4.0) == Window(0.0, stable.stable_window_s, stable.stable_timeout_s)
    assert METHODS["dwell"].window(dwell, 4.0) == Window(3.5, 0.5, 0.5)


def test_a_method_not_run_live_is_refused_by_the_config_naming_file_and_key():
    with pytest.raises(InputError, match="small.toml: key 'capture.method': \"stream\".*import-stream"):
        parse_config(SMALL + 'method = "stream"\n', "small.toml")


def test_the_program_writer_refuses_a_scan(cli):
    from tests.conftest import ROOT, assert_one_line_error

    assert_one_line_error(cli("program", ROOT / "data/configs/scan-demo.toml", "--dialect", "linuxcnc", "-o",
                              "/nonexistent/p.ngc"), "a scan is aligned with the controller's time-stamped")


def test_a_scan_on_an_axis_that_cannot_stream_its_position_is_refused_before_anything_moves(tmp_path):
    from campaign.errors import InputError as Refused

    scan = SMALL.replace("[campaign]\n", '[campaign]\npurpose = "diagnostic"\n') + 'method = "scan"\nscan_velocity = 10.0\n'
    machine = FakeMachine()
    with pytest.raises(Refused, match="cannot stream its actual position"):
        start_campaign(parse_config(scan, "scan.toml"), tmp_path / "c", opener=machine)
    assert machine.openings[0].axis.position == parse_config(scan, "scan.toml").driver.start_position  # never moved


def test_the_controllers_said_to_stream_their_position_are_those_whose_axis_streams_it():
    """campaign.specs.STREAMING_CONTROLLERS (what discovery's follow-up reads) against the drivers' axes
    (drivers/factory.py opens AdsAxis for ads and for the simulated PLC)."""
    from typing import get_args

    from campaign.specs import STREAMING_CONTROLLERS, ControllerSpec, ControllerType
    from drivers.ads_axis import AdsAxis
    from drivers.epics.axis import EpicsAxis
    from drivers.linuxcnc.axis import LinuxCncAxis
    from protocols.hardware import StreamingAxis

    axis_of = {"ads": AdsAxis, "sim": AdsAxis, "linuxcnc": LinuxCncAxis, "epics": EpicsAxis}
    assert set(axis_of) == set(get_args(ControllerType))
    for name, axis in axis_of.items():
        streams = callable(getattr(axis, "stream_positions", None))
        assert streams == (name in STREAMING_CONTROLLERS) == ControllerSpec(type=name).streams_position, name  # type: ignore[arg-type]
        assert streams == all(callable(getattr(axis, m, None)) for m in dir(StreamingAxis) if not m.startswith("_"))


def test_a_scan_config_is_checked_before_anything_runs():
    scan = SMALL + 'method = "scan"\n'
    with pytest.raises(InputError, match="campaign.purpose.*not an ISO 230-2 test"):
        parse_config(scan + "scan_velocity = 10.0\n", "scan.toml")
    diagnostic = scan.replace("[campaign]\n", '[campaign]\npurpose = "diagnostic"\n')
    with pytest.raises(InputError, match="capture.scan_velocity.*required"):
        parse_config(diagnostic, "scan.toml")
    with pytest.raises(InputError, match="capture.scan_velocity.*above axis.max_velocity"):
        parse_config(diagnostic + "scan_velocity = 60.0\n", "scan.toml")
    rate = parse_config(diagnostic + "scan_velocity = 10.0\n", "scan.toml").instrument.rate_hz
    with pytest.raises(InputError, match="scan.toml: key 'capture.scan_window'.*shorter than the spacing of the samples"):
        build_plan(parse_config(diagnostic + f"scan_velocity = 10.0\nscan_window = {0.8 * 10.0 / rate}\n", "scan.toml"))
    build_plan(parse_config(diagnostic + f"scan_velocity = 10.0\nscan_window = {1.2 * 10.0 / rate}\n", "scan.toml"))
    plan = build_plan(parse_config(diagnostic + "scan_velocity = 10.0\n", "scan.toml"))
    spacing = min(b - a for a, b in zip(plan.targets, plan.targets[1:]))
    with pytest.raises(InputError, match="scan.toml: key 'capture.scan_window'.*wider than the targets' spacing"):
        build_plan(parse_config(diagnostic + f"scan_velocity = 10.0\nscan_window = {spacing * 1.2 + 1}\n", "scan.toml"))
    plan = build_plan(parse_config(diagnostic + "scan_velocity = 10.0\n", "scan.toml"))
    assert plan.sweeps and [(p.run, p.direction, p.target) for p in plan.points] == [
        (1, 1, 102.0), (1, -1, -2.0), (2, 1, 102.0), (2, -1, -2.0)]  # the targets ± the overrun, up and down


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_a_scan_window_is_checked_against_the_offset_targets_the_plan_uses(cli, tmp_path, seed):
    """The targets carry offsets (random or golden, up to a fraction of the spacing): the window must fit
    between the plan's targets, not the nominal ones; `axiscal plan` says so in one error line."""
    from tests.conftest import assert_one_line_error

    scan = (SMALL.replace("[campaign]\n", '[campaign]\npurpose = "diagnostic"\n')
            .replace("[plan]\n", f"[plan]\noffsets = \"random\"\noffset_fraction = 0.3\nseed = {seed}\n")
            .replace("soft_limit_min = -5.0", "soft_limit_min = -25.0").replace("soft_limit_max = 105.0", "soft_limit_max = 125.0")
            .replace("targets = [0.0, 50.0, 100.0]", "length = 100.0\ncount = 11")
            + 'method = "scan"\nscan_velocity = 10.0\n')
    nominal = build_plan(parse_config(scan.replace('offsets = "random"', 'offsets = "none"'), "scan.toml")).targets
    targets = build_plan(parse_config(scan, "scan.toml")).targets
    gap, nominal_gap = (min(b - a for a, b in itertools.pairwise(t)) for t in (targets, nominal))
    assert gap < nominal_gap
    window = (gap + nominal_gap) / 2  # fits the nominal targets, not the plan's
    (tmp_path / "scan.toml").write_text(scan + f"scan_window = {window}\n")
    assert_one_line_error(cli("plan", str(tmp_path / "scan.toml")), "key 'capture.scan_window'",
                          "wider than the targets' spacing", f"({gap:g} mm")
    (tmp_path / "ok.toml").write_text(scan + f"scan_window = {gap * 0.99}\n")
    assert cli("plan", str(tmp_path / "ok.toml")).code == 0


def test_register_refuses_a_name_registered_already_and_a_non_iso_method_without_its_reason():
    with pytest.raises(ValueError, match="'dwell' is registered already"):
        register(replace(METHODS["dwell"], summary="another dwell"))
    assert METHODS["dwell"].summary == "average the end of a fixed dwell"
    with pytest.raises(ValueError, match="not_iso_why"):
        register(replace(MEDIAN, name="glide", iso_230_2=False))
    assert "glide" not in METHODS


def test_the_verdict_and_the_report_read_a_method_from_its_registry_object(tmp_path):
    from campaign.assess import assess
    from campaign.report.document import _scan_facts
    from tests.conftest import ROOT

    text = (ROOT / "data/paper-2022-beckhoff-press/horizontal_before.csv").read_text()
    (tmp_path / "t.csv").write_text("# capture: glide\n# purpose: diagnostic\n# scan: 4 moves\n" + text)
    glide = register(replace(METHODS["scan"], name="glide", not_iso_why="the axis glides past its targets"))
    try:
        a = assess(read_points(tmp_path / "t.csv"))
        assert any("glide method, not an ISO 230-2 test: the axis glides past its targets" in r
                   for r in a.verdict.reasons), a.verdict.reasons
        assert _scan_facts(a.table.meta) == [("Scan", "4 moves")]  # a sweeping method's table, whatever its name
    finally:
        METHODS.pop(glide.name)

"""The compensation calculator, the controller grid, the prediction and the Compensator.

Signs: error = measured - target (µm); correction = what the control adds to the command (µm).
"""

from __future__ import annotations

import numpy as np
import pytest

from campaign.compensation.corrections import choose_mode, corrections, inverse_corrections
from campaign.compensation.grid import grid, resample
from campaign.compensation.predict import predict
from campaign.errors import InputError
from campaign.pointtable import parse_points, read_points
from protocols.compensator import Compensator, table_lookup
from protocols.plc_contract import CompTable
from tests.conftest import PAPER, assert_one_line_error


def points(rows: list[tuple[int, str, float, float]]) -> str:
    return "run,direction,target_mm,deviation_um\n" + "".join(f"{r},{d},{t},{e}\n" for r, d, t, e in rows)


def test_inverse_interpolation_hand_worked():
    # targets 0 and 100 mm, errors +10 and +30 µm: actual 0.010 and 100.030 mm.
    # target 100 lies inside: command = (100 - 0.010) * 100 / 100.020 = 99.970006 -> -29.994001 µm.
    # target 0 lies below the first actual: same slope, command = -0.010 * 100 / 100.020
    # = -0.0099980 mm -> -9.998000 µm. The simple method gives -10 and -30.
    c = inverse_corrections(np.array([0.0, 100.0]), np.array([10.0, 30.0]), 1e-3)
    assert c == pytest.approx([-9.998000, -29.994001], abs=1e-6)


def test_inverse_interpolation_rejects_folded_positions():
    with pytest.raises(InputError, match="do not increase"):
        inverse_corrections(np.array([0.0, 0.01]), np.array([20.0, 0.0]), 1e-3)


def test_correction_is_minus_error_for_a_constant_error():
    text = points([(r, d, t, 5.0 + 0.1 * r) for r in (1, 2, 3) for d in "+-" for t in (0, 50, 100)])
    corr = corrections(parse_points(text), "bi")
    # a constant error (5.2 µm mean) is a pure shift: inverse and simple agree, correction -5.2
    assert corr.forward == pytest.approx([-5.2] * 3)
    assert corr.reverse == pytest.approx([-5.2] * 3)
    assert corr.max_inverse_minus_simple == pytest.approx(0.0, abs=1e-9)


def test_uni_mode_splits_the_backlash():
    # + direction error 1 µm, - direction error -3 µm everywhere: mean -1, B = 1 - (-3) = 4.
    rows = [(r, "+", t, 1.0 + 0.01 * r) for r in (1, 2, 3) for t in (0, 10)]
    rows += [(r, "-", t, -3.0 + 0.01 * r) for r in (1, 2, 3) for t in (0, 10)]
    corr = corrections(parse_points(points(rows)), "uni", "simple")
    assert corr.backlash == pytest.approx(4.0)
    assert corr.common == pytest.approx([1.0 - 0.02, 1.0 - 0.02])  # -(mean error) = -(-1 + 0.02)
    assert corr.forward == pytest.approx(corr.common - 2.0)  # + direction: -(1.02) = common - B/2
    assert corr.reverse == pytest.approx(corr.common + 2.0)


def test_choose_mode_rule():
    # s_pooled = 0.5 -> limit 4*0.5 = 2: a reversal spread of 1.9 stays uni, 2.1 goes bi
    s = np.array([0.5, 0.5])
    assert choose_mode("auto", np.array([0.0, 1.9]), s)[0] == "uni"
    assert choose_mode("auto", np.array([0.0, 2.1]), s)[0] == "bi"
    assert choose_mode("auto", np.array([0.0, 2.1]), None)[0] == "bi"
    assert choose_mode("auto", None, s)[0] == "uni"
    with pytest.raises(InputError):
        choose_mode("bi", None, s)
    # every number in the reason carries its unit
    assert "by 1.900 µm along the axis" in choose_mode("auto", np.array([0.0, 1.9]), s)[1]
    assert "4·s = 2.000 arcsec" in choose_mode("auto", np.array([0.0, 2.1]), s, unit="arcsec")[1]


def test_one_direction_table_gives_a_unidirectional_table():
    text = points([(r, "+", t, -t / 10 + 0.1 * r) for r in (1, 2) for t in (0, 10, 20)])
    corr = corrections(parse_points(text))
    assert corr.mode == "uni" and corr.backlash is None
    assert np.array_equal(corr.forward, corr.reverse)


def test_paper_vertical_axis_goes_bidirectional_and_reaches_its_floor():
    table = read_points(PAPER / "vertical_before.csv")
    corr = corrections(table)
    assert corr.mode == "bi"
    pred = predict(table, resample(corr, 256))
    # floor = 4 * largest s; the paper's table 4 prints s = 1.724 µm at 180 mm as the largest
    assert pred.floor == pytest.approx(4 * 1.724, abs=2e-3)
    assert pred.accuracy_before == pytest.approx(795.741, abs=1e-3)
    assert pred.accuracy_after < 0.02 * 795.741
    assert pred.floor <= pred.accuracy_after <= pred.floor * 1.01  # exact inverse on the targets


def test_paper_vertical_simple_method_is_worse_than_inverse():
    table = read_points(PAPER / "vertical_before.csv")
    simple = predict(table, resample(corrections(table, "bi", "simple"), 256)).accuracy_after
    inverse = predict(table, resample(corrections(table, "bi", "inverse"), 256)).accuracy_after
    assert inverse < simple < 0.02 * 795.741


def test_paper_vertical_uni_mode_leaves_the_varying_reversal():
    table = read_points(PAPER / "vertical_before.csv")
    pred = predict(table, resample(corrections(table, "uni"), 256))
    assert pred.accuracy_after > 100  # the reversal ranges 58..490 µm; one constant cannot fit it


def test_paper_horizontal_axis_stays_unidirectional():
    table = read_points(PAPER / "horizontal_before.csv")
    corr = corrections(table)
    assert corr.mode == "uni"  # as the paper chose
    pred = predict(table, resample(corr, 256))
    assert pred.accuracy_after < 9.152 / 2
    assert pred.accuracy_after >= pred.floor


def test_grid_spacing_and_reference():
    targets = np.arange(0.0, 601.0, 60.0)
    assert grid(targets, 256) == (0.0, 60.0, 11)  # the targets' own spacing
    assert grid(targets, 5) == (0.0, 150.0, 5)  # 600 / (5 - 1)
    start, spacing, count = grid(targets, 256, spacing=100.0, reference=250.0)
    assert (start, spacing, count) == (-50.0, 100.0, 8)  # 250 is a point; -50..650 covers 0..600
    with pytest.raises(InputError, match="at most 4"):
        grid(targets, 4, spacing=60.0)
    with pytest.raises(InputError, match="outside"):
        grid(targets, 256, reference=700.0)


def test_reference_zero_shifts_both_tables():
    table = read_points(PAPER / "vertical_before.csv")
    corr = corrections(table, "bi")
    ctable = resample(corr, 256, reference=150.0)
    at = list(ctable.positions).index(150.0)
    assert ctable.forward[at] == pytest.approx(0.0, abs=1e-12)
    assert ctable.reverse[at] - ctable.forward[at] == pytest.approx(corr.reverse[5] - corr.forward[5])


def test_table_lookup_end_zones_hand_worked():
    # points 0 and 10 mm with 2 and 4, overrun 5: ramps 0 at -5 -> 2 at 0, 4 at 10 -> 0 at 15
    values = [2.0, 4.0]
    assert table_lookup(values, 0.0, 10.0, 5.0, -2.5) == pytest.approx(1.0)
    assert table_lookup(values, 0.0, 10.0, 5.0, 5.0) == pytest.approx(3.0)
    assert table_lookup(values, 0.0, 10.0, 5.0, 12.5) == pytest.approx(2.0)
    assert table_lookup(values, 0.0, 10.0, 5.0, 15.0) == 0.0
    assert table_lookup(values, 0.0, 10.0, 5.0, -6.0) == 0.0
    assert table_lookup(values, 0.0, 10.0, 0.0, 10.5) == 0.0  # no overrun: 0 outside


def test_compensator_direction_tables_and_planner():
    table = CompTable(forward=(0.002, 0.004), reverse=(-0.002, -0.004), start=0.0, spacing=10.0,
                      overrun=0.0, max_rate=0.1, max_accel=1.0, enabled=True)
    comp = Compensator(table, cycle_s=0.001)
    assert comp.desired(5.0, +1) == pytest.approx(0.003)
    assert comp.desired(5.0, 0) == pytest.approx(0.003)  # standing still keeps forward
    assert comp.desired(5.0, -1) == pytest.approx(-0.003)
    applied = [comp.step(5.0, -1) for _ in range(400)]
    steps = np.diff([0.0, *applied])
    assert np.max(np.abs(steps)) <= 0.1 * 0.001 * (1 + 1e-9)
    assert applied[-1] == pytest.approx(-0.003)
    off = Compensator(CompTable(**{**table.__dict__, "enabled": False}), cycle_s=0.001)
    assert off.desired(5.0, 1) == 0.0


def test_plc_table_is_in_axis_units():
    corr = corrections(read_points(PAPER / "vertical_before.csv"), "bi")
    ctable = resample(corr, 256, overrun=10.0)
    plc = ctable.to_plc(max_rate=1.0, max_accel=10.0)
    assert plc.forward[0] == pytest.approx(ctable.forward[0] / 1000)
    comp = Compensator(plc, cycle_s=0.001)
    assert comp.desired(15.0, 1) == pytest.approx(ctable.correction(15.0, 1) / 1000)


def test_compensate_cli_linuxcnc(cli, tmp_path):
    out = tmp_path / "x.comp"
    result = cli("compensate", PAPER / "vertical_before.csv", "--format", "linuxcnc", "-o", out,
                 "--method", "simple")
    assert result.code == 0, result.err
    assert "mode: bi" in result.out and "COMP_FILE_TYPE = 0" in result.out and "floor" in result.out
    # the paper's vertical means do not lie on any polynomial within their scatter: kept as measured
    assert "smoothing, forward: not smoothed: no polynomial up to degree 8" in result.out
    lines = out.read_text().splitlines()
    assert len(lines) == 11
    nominal, forward, reverse = (float(v) for v in lines[1].split())
    # 30 mm, simple method: + error -8.8 µm, - error -414.7 µm (paper tables 4, 5), so the
    # actual positions written are 29.991200 and 29.585300 mm
    assert nominal == 30.0
    assert forward == pytest.approx(29.9912, abs=1e-6)
    assert reverse == pytest.approx(29.5853, abs=1e-6)


def test_compensate_cli_errors(cli, tmp_path):
    assert_one_line_error(cli("compensate", tmp_path / "nope.csv", "--format", "csv", "-o", tmp_path / "o"),
                          "no such file")
    assert_one_line_error(cli("compensate", PAPER / "horizontal_before.csv", "--format", "pmac",
                              "-o", tmp_path / "o"), "counts-per-unit")
    assert_one_line_error(cli("compensate", PAPER / "horizontal_before.csv", "--format", "csv",
                              "-o", tmp_path / "o", "--spacing", "0.5"), "at most")


@pytest.mark.parametrize(("option", "value", "says"), [
    ("--counts-per-unit", "nan", "finite number > 0, found 'nan'"),
    ("--counts-per-unit", "-1000", "finite number > 0, found '-1000'"),
    ("--spacing", "0", "finite number > 0"),
    ("--max-points", "2.5", "not a whole number"),
    ("--overrun", "-1", "≥ 0"),
    ("--reference", "inf", "finite number"),
])
def test_compensate_numeric_options_are_checked(cli, tmp_path, option, value, says):
    result = cli("compensate", PAPER / "horizontal_before.csv", "--format", "pmac", "-o", tmp_path / "o",
                 f"{option}={value}")
    assert_one_line_error(result, says)
    assert option in result.err and not (tmp_path / "o").exists()


def test_a_golden_offset_campaign_gets_a_table_on_its_nominal_grid(cli, tmp_path):
    """Targets carrying golden offsets are off the grid a controller wants: the table defaults to
    the plan's nominal spacing from its first nominal target (the old default was span/(N-1) at the
    format's point limit: 1024 csv points every 0.0978 mm here); --spacing still rules."""
    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from tests.fakes import SMALL, FakeMachine

    config = parse_config(SMALL.replace("velocity = 25.0", 'velocity = 25.0\noffsets = "golden"\noffset_fraction = 0.2'),
                          "small.toml")
    assert config.plan.offsets == "golden"
    start_campaign(config, tmp_path / "c", opener=FakeMachine())
    result = cli("compensate", tmp_path / "c" / "points.csv", "--format", "csv", "-o", tmp_path / "t.csv")
    assert result.code == 0, result.err
    assert "table: 3 points from 0 every 50 mm" in result.out and "nominal grid" in result.out
    given = cli("compensate", tmp_path / "c" / "points.csv", "--format", "csv", "-o", tmp_path / "t.csv",
                "--spacing", "25")
    assert "table: 5 points from 0 every 25 mm" in given.out and "nominal grid" not in given.out


def test_a_pmac_spacing_of_fractional_counts_names_spacing(cli, tmp_path):
    result = cli("compensate", PAPER / "vertical_before.csv", "--format", "pmac", "--counts-per-unit", "1000.01",
                 "--reference", "0", "--mode", "uni", "-o", tmp_path / "t.pmac")
    assert_one_line_error(result, "not a whole number", "--spacing 30.000699993", "30001 counts")
    hinted = cli("compensate", PAPER / "vertical_before.csv", "--format", "pmac", "--counts-per-unit", "1000.01",
                 "--reference", "0", "--mode", "uni", "--spacing", "30.000699993", "-o", tmp_path / "t.pmac")
    assert hinted.code == 0, hinted.err  # the spacing it names is accepted

"""Every table format against a hand-worked example (values worked out by hand in comments).

Input tables (ControllerTable: positions mm, corrections µm, correction = added to the command,
≈ -error):
  BI: points 0, 10, 20 mm; forward [-5, 3, 0] µm; reverse [-7, 1, 2] µm (bidirectional).
  UNI: the same points; common [-6, 2, 1] µm, backlash B̄ = +2 µm, so forward = common - 1 =
       [-7, 1, 0] and reverse = common + 1 = [-5, 3, 2]; reference 0.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.compensation.corrections import corrections
from campaign.compensation.grid import ControllerTable, resample
from campaign.compensation.table_file import read_comp_table
from campaign.errors import BAD_INPUT
from campaign.pointtable import read_points
from protocols.tables import FormatOptions, render
from tests.conftest import DATA

BI = ControllerTable("linear", 0.0, 10.0, np.array([-5.0, 3.0, 0.0]), np.array([-7.0, 1.0, 2.0]),
                     np.array([-6.0, 2.0, 1.0]), "bi", None, reference=10.0)
UNI = ControllerTable("linear", 0.0, 10.0, np.array([-7.0, 1.0, 0.0]), np.array([-5.0, 3.0, 2.0]),
                      np.array([-6.0, 2.0, 1.0]), "uni", 2.0, reference=0.0)


def test_linuxcnc_type0_triplets():
    # actual = nominal - correction: 0 - (-0.005) = 0.005, 0 - (-0.007) = 0.007;
    # 10 - 0.003 = 9.997, 10 - 0.001 = 9.999; 20 - 0 = 20, 20 - 0.002 = 19.998
    out = render("linuxcnc", BI, FormatOptions(joint=2))
    assert out.text == ("0.000000 0.005000 0.007000\n"
                        "10.000000 9.997000 9.999000\n"
                        "20.000000 20.000000 19.998000\n")
    assert out.notes == ["[JOINT_2]", "COMP_FILE = <this file>", "COMP_FILE_TYPE = 0"]


def test_linuxcnc_point_limit():
    n = 257
    big = ControllerTable("linear", 0.0, 1.0, np.zeros(n), np.zeros(n), np.zeros(n), "bi", None)
    with pytest.raises(BAD_INPUT, match="256"):
        render("linuxcnc", big)


def test_pmac_hand_worked():
    # 1000 counts/mm, 1/16 count: common 2 µm = 2 counts = 32; 1 µm = 16; -6 µm = -96.
    # entries start one spacing (10000 counts) above zero and end with the value at zero:
    # 32 16 -96; count length 3 * 10000. Backlash I186 = lost motion -B̄ = -2 µm = -32.
    out = render("pmac", UNI, FormatOptions(counts_per_unit=1000))
    assert out.text == "#1\nDEFINE COMP 3,30000\n32 16 -96\nI51=1\n"
    assert any("I186 = -32" in n for n in out.notes)
    with pytest.raises(BAD_INPUT, match="mode uni"):
        render("pmac", BI, FormatOptions(counts_per_unit=1000))


def test_pmac_paper_turntable():
    # Han et al. 2012: the paper's table 3 is round(-error_counts * 16) at 10..90 deg, 0 at 0 deg (the
    # simple method), 1000 counts per degree, 10 entries of 10000 counts
    table = read_points(DATA / "paper-2012-pmac-turntable" / "forward_errors.csv")
    ctable = resample(corrections(table, "auto", "simple"), 256)
    text = render("pmac", ctable, FormatOptions(counts_per_unit=1000)).text
    lines = text.splitlines()
    assert lines[1] == "DEFINE COMP 10,100000"
    assert lines[2] == "84 55 66 41 100 59 66 40 135 0"
    assert lines[3] == "I51=1"


def test_twincat_cnc_hand_worked():
    # 0.1 µm units: setpoints 0, 100000, 200000; value = actual - programmed = -correction:
    # pos = [50, -30, 0], neg = [70, -10, -20]
    text = render("twincat_cnc", BI, FormatOptions(axis_number=3)).text
    fields = dict(line.split(None, 1) for line in text.splitlines())
    assert text.splitlines()[0] == "kopf.achs_nr 3"  # the logical axis number heads the list
    assert not any(line.startswith("#") for line in text.splitlines())  # no provenance given, no comment
    assert fields["kw.ssfk.interval"] == "100000"
    assert fields["kw.ssfk.kw_startpos"] == "0"
    assert fields["kw.ssfk.kw_nr_max"] == "3"
    assert fields["kw.ssfk.unit"] == "1" and fields["kw.ssfk.bilateral"] == "1"
    assert [fields[f"kw.ssfk.table[{i}].setpoint"] for i in range(3)] == ["0", "100000", "200000"]
    assert [fields[f"kw.ssfk.table[{i}].pos"] for i in range(3)] == ["50", "-30", "0"]
    assert [fields[f"kw.ssfk.table[{i}].neg"] for i in range(3)] == ["70", "-10", "-20"]


def test_siemens_hand_worked():
    # positive value moves the axis negative: value = -correction in mm: 0.006, -0.002, -0.001
    out = render("siemens", UNI, FormatOptions(axis_name="AX1"))
    assert out.text.splitlines() == [
        "%_N_AX_EEC_INI", "CHANDATA(1)",
        "$AA_ENC_COMP[0,0,AX1]=0.006000", "$AA_ENC_COMP[0,1,AX1]=-0.002000", "$AA_ENC_COMP[0,2,AX1]=-0.001000",
        "$AA_ENC_COMP_STEP[0,AX1]=10.000000", "$AA_ENC_COMP_MIN[0,AX1]=0.000000",
        "$AA_ENC_COMP_MAX[0,AX1]=20.000000", "$AA_ENC_COMP_IS_MODULO[0,AX1]=0", "M17"]
    assert "MD32450 BACKLASH = -0.002000 (lost motion = -B̄)" in out.notes
    with pytest.raises(BAD_INPUT):
        render("siemens", BI)


def test_siemens_never_writes_minus_zero():
    """A zero correction (0.0 negated is -0.0) and one under half a nanometre are written 0.000000."""
    tiny = ControllerTable("linear", 0.0, 10.0, np.array([0.0, 4e-4, -1.0]), np.array([0.0, 4e-4, -1.0]),
                           np.array([0.0, 4e-4, -1.0]), "uni", 0.0, reference=0.0)
    out = render("siemens", tiny, FormatOptions(axis_name="AX1"))
    assert "$AA_ENC_COMP[0,0,AX1]=0.000000" in out.text and "$AA_ENC_COMP[0,1,AX1]=0.000000" in out.text
    assert "$AA_ENC_COMP[0,2,AX1]=0.001000" in out.text and "-0.000000" not in out.text + "".join(out.notes)


def test_fanuc_unidirectional_hand_worked():
    # detection unit 1 µm (1000 per mm): cumulative [-6, 2, 1] -> increments [0, 8, -1];
    # reference at point 0, interval 10 mm = 10000; backlash 1851 = -B̄ = -2
    text = render("fanuc", UNI, FormatOptions(counts_per_unit=1000)).text
    assert text.splitlines() == ["3620 = 0", "3621 = 0", "3622 = 2", "3623 = 1", "3624 = 10000", "1851 = -2",
                                 "pitch[0] = 0", "pitch[1] = 8", "pitch[2] = -1"]


def test_fanuc_bidirectional_hand_worked():
    # forward [-5, 3, 0] -> [0, 8, -3]; reverse [-7, 1, 2] -> [0, 8, 1] at points 3..5;
    # reference 10 mm = point 1; 3627 = reverse correction at the reference less the forward
    # one there (the + reference return makes the forward correction the datum) = 1 - 3 = -2
    text = render("fanuc", BI, FormatOptions(counts_per_unit=1000)).text
    lines = text.splitlines()
    assert lines[:8] == ["3620 = 1", "3621 = 0", "3622 = 2", "3623 = 1", "3624 = 10000",
                         "3605#0 = 1", "3626 = 3", "3627 = -2"]
    assert lines[8:] == [f"pitch[{i}] = {v}" for i, v in enumerate([0, 8, -3, 0, 8, 1])]


def test_fanuc_magnification():
    # increments of 300 detection units exceed 127: magnification ceil(301/127) = 3, 300/3 = 100
    t = ControllerTable("linear", 0.0, 10.0, np.array([0.0, 300.0]), np.array([0.0, 300.0]),
                        np.array([0.0, 300.0]), "uni", None, reference=0.0)
    lines = render("fanuc", t, FormatOptions(counts_per_unit=1000)).text.splitlines()
    assert "3623 = 3" in lines and lines[-1] == "pitch[1] = 100"


def test_heidenhain_hand_worked():
    # common in mm: -0.006, 0.002, 0.001; BACKLASH = reverse - forward: -0.002, -0.002, 0.002
    text = render("heidenhain", BI, FormatOptions(axis_name="X")).text
    assert text.splitlines() == ["BEGIN X.COM", "NR AXISPOS X BACKLASH",
                                 "0 0.0000 -0.00600 -0.00200", "1 10.0000 +0.00200 -0.00200",
                                 "2 20.0000 +0.00100 +0.00200", "[END]"]


def test_csv_and_json():
    assert render("csv", BI).text.splitlines() == [
        "position_mm,correction_forward_um,correction_reverse_um",
        "0.000000,-5.0000,-7.0000", "10.000000,3.0000,1.0000", "20.000000,0.0000,2.0000"]
    doc = json.loads(render("json", UNI).text)
    assert doc["forward"] == [-7.0, 1.0, 0.0] and doc["backlash"] == 2.0
    assert doc["positions"] == [0.0, 10.0, 20.0] and doc["correction_unit"] == "um"


def test_pmac_command_reproduces_the_paper_by_default(tmp_path):
    """Seed 003 through the command line with no method option: the published table."""
    from campaign.cli import main
    from tests.conftest import DATA

    out = tmp_path / "comp.pmc"
    assert main(["compensate", str(DATA / "paper-2012-pmac-turntable/forward_errors.csv"), "--format", "pmac",
                 "--counts-per-unit", "1000", "-o", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert "DEFINE COMP 10,100000" in lines
    assert "84 55 66 41 100 59 66 40 135 0" in lines
    assert lines[-1] == "I51=1"


def test_twincat_cnc_needs_a_logical_axis_number_and_not_0():
    with pytest.raises(BAD_INPUT, match="--axis-number"):
        render("twincat_cnc", BI)
    with pytest.raises(BAD_INPUT, match="1..65534"):
        render("twincat_cnc", BI, FormatOptions(axis_number=0))
    assert "kopf.achs_nr 65534" in render("twincat_cnc", BI, FormatOptions(axis_number=65534)).text


def test_linuxcnc_inch_table_for_an_inch_machine():
    # 10 mm = 0.3937008 in; actual 9.997 mm = 0.3935827 in
    text = render("linuxcnc", BI, FormatOptions(units="inch")).text
    assert text.splitlines()[1] == "0.3937008 0.3935827 0.3936614"


def test_siemens_point_limit_by_control_and_provenance_comments():
    big = ControllerTable("linear", 0.0, 1.0, np.zeros(201), np.zeros(201), np.zeros(201), "uni", None)
    with pytest.raises(BAD_INPUT, match="808D takes at most 200"):
        render("siemens", big, FormatOptions(control="808d"))
    text = render("siemens", big, FormatOptions(provenance=(("machine", "mill-3"), ("axis", "X")))).text
    assert text.splitlines()[:3] == ["%_N_AX_EEC_INI", "; machine: mill-3", "; axis: X"]


def test_heidenhain_old_tnc_needs_a_power_of_two_spacing():
    with pytest.raises(BAD_INPUT, match="power-of-two spacing"):
        render("heidenhain", UNI, FormatOptions(control="tnc426"))  # 10 mm
    eight = ControllerTable("linear", 0.0, 8.0, UNI.forward, UNI.reverse, UNI.common, "uni", 2.0)
    assert render("heidenhain", eight, FormatOptions(control="tnc426")).text.startswith("BEGIN X.COM")


def test_twincat_cnc_provenance_on_whole_line_comments_that_read_back(tmp_path):
    # Beckhoff's list syntax: a whole-line comment is "# " at the start of the line
    options = FormatOptions(axis_number=3, provenance=(("machine", "mill-3"), ("axis", "X"), ("operator", "")))
    path = tmp_path / "ssfk.lis"
    path.write_text(render("twincat_cnc", BI, options).text)
    assert path.read_text().splitlines()[:3] == ["# machine: mill-3", "# axis: X", "kopf.achs_nr 3"]
    back = read_comp_table(path, "linear", None, options)
    assert back.forward == pytest.approx(BI.forward) and back.reverse == pytest.approx(BI.reverse)

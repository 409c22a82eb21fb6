"""`verify` takes any table `compensate` writes: every format read back gives the table it was
rendered from, to the format's resolution, or says which line is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.compensation.grid import ControllerTable
from campaign.compensation.table_file import read_comp_table
from campaign.errors import BAD_INPUT
from protocols.tables import FormatOptions, render, sniff

POSITIONS = 11
FORWARD = np.array([-5.0, 3.0, 0.0, 1.2, -2.4, 6.1, 7.7, -3.3, 0.4, 2.2, -1.0])
REVERSE = FORWARD + np.linspace(-2.0, 3.0, POSITIONS)
BI = ControllerTable("linear", 0.0, 10.0, FORWARD, REVERSE, (FORWARD + REVERSE) / 2, "bi", None, reference=0.0)
UNI = ControllerTable("linear", 0.0, 10.0, FORWARD, FORWARD, FORWARD, "uni", None, reference=0.0)
CPU = 1000.0  # counts per mm: 1 count = 1 µm, 1/16 count = 0.0625 µm

# format -> (table rendered, resolution of the written values in µm, options to read it back)
CASES = {
    "linuxcnc": (BI, 1e-3, FormatOptions()),
    "csv": (BI, 1e-4, FormatOptions()),
    "json": (BI, 1e-9, FormatOptions()),
    "twincat_cnc": (BI, 0.05, FormatOptions(axis_number=1)),
    "siemens": (UNI, 1e-3, FormatOptions()),
    "heidenhain": (UNI, 1e-2, FormatOptions()),
    "pmac": (UNI, 0.0625 / 2, FormatOptions(counts_per_unit=CPU)),
    "fanuc": (BI, 1.0, FormatOptions(counts_per_unit=CPU)),
}


@pytest.mark.parametrize("fmt", list(CASES))
def test_every_format_reads_back_the_table_it_was_rendered_from(tmp_path, fmt):
    table, resolution, options = CASES[fmt]
    path = tmp_path / f"table.{fmt}"
    path.write_text(render(fmt, table, options).text)
    assert sniff(path.read_text()) == fmt
    back = read_comp_table(path, "linear", None, options)
    assert back.start == pytest.approx(table.start) and back.spacing == pytest.approx(table.spacing)
    assert back.mode == table.mode
    forward, reverse = back.forward, back.reverse
    if fmt == "fanuc":  # incremental: the + correction at the reference (point 0) is the datum
        forward, reverse = forward + table.forward[0], reverse + table.forward[0]
    assert np.max(np.abs(forward - table.forward)) <= resolution + 1e-9
    assert np.max(np.abs(reverse - table.reverse)) <= resolution + 1e-9


def test_a_bad_line_is_named(tmp_path):
    path = tmp_path / "comp.txt"
    path.write_text("0.000000 0.005000 0.007000\n10.000000 9.997000 oops\n")
    with pytest.raises(BAD_INPUT, match="line 2: value 'oops' is not a number"):
        read_comp_table(path, "linear", "linuxcnc")
    path.write_text("0 0 0\n10 0 0\n25 0 0\n")
    with pytest.raises(BAD_INPUT, match="not equidistant"):
        read_comp_table(path, "linear")
    path.write_text("hello\n")
    with pytest.raises(BAD_INPUT, match="give --comp-format"):
        read_comp_table(path, "linear")


def test_a_rotary_csv_does_not_fit_a_linear_axis(tmp_path):
    rotary = ControllerTable("rotary", 0.0, 10.0, FORWARD, REVERSE, (FORWARD + REVERSE) / 2, "bi", None)
    path = tmp_path / "r.csv"
    path.write_text(render("csv", rotary).text)
    with pytest.raises(BAD_INPUT, match="a rotary table does not fit the linear axis"):
        read_comp_table(path, "linear")
    back = read_comp_table(path, "rotary")
    assert np.allclose(back.forward, FORWARD, atol=1e-4)


def test_pmac_needs_counts_per_unit(tmp_path):
    path = tmp_path / "t.pmc"
    path.write_text(render("pmac", UNI, FormatOptions(counts_per_unit=CPU)).text)
    with pytest.raises(BAD_INPUT, match="--counts-per-unit"):
        read_comp_table(path, "linear")


@pytest.mark.parametrize("fmt", ["csv", "twincat_cnc", "siemens", "pmac"])
def test_verify_reads_the_provenance_of_every_format_that_has_comments(fmt, tmp_path):
    from dataclasses import replace

    from campaign.compensation.table_file import read_comp_provenance

    table, _, options = CASES[fmt]
    said = (("points", "/runs/a/points.csv"), ("machine", "press 7"), ("axis", "Z"), ("software", "axiscal 0.1.0"))
    path = tmp_path / f"t.{fmt}"
    path.write_text(render(fmt, table, replace(options, provenance=said)).text)
    assert read_comp_provenance(path) == dict(said)


def test_formats_without_comments_carry_no_provenance(tmp_path):
    from campaign.compensation.table_file import read_comp_provenance

    path = tmp_path / "t.comp"
    path.write_text(render("linuxcnc", BI, FormatOptions(provenance=(("machine", "press 7"),))).text)
    assert read_comp_provenance(path) == {}


def test_compensate_names_the_campaign_and_the_dates_in_the_provenance(cli, tmp_path):
    """The provenance says which campaign (its directory), when it was measured (meta.json's
    `created`) and when the table was written, beside machine, axis and software."""
    import json
    from datetime import UTC, datetime

    from campaign.compensation.table_file import read_comp_provenance
    from campaign.discovery.simulate import simulate_campaign
    from campaign.model import ErrorModel
    from campaign.pointtable import write_points
    from tests.test_discovery import CONFIG, PLAN

    directory = tmp_path / "spindle-2026"
    directory.mkdir()
    table = simulate_campaign(CONFIG, ErrorModel({"linear_scale": {"ppm": -12.0}}), seed=1)
    table.meta.update(machine="mill-3", axis="Y")
    write_points(directory / "points.csv", table)
    (directory / "config.toml").write_text(PLAN)
    (directory / "meta.json").write_text(json.dumps({"format_version": 2, "created": "2026-03-02T08:15:00+00:00"}))
    before = datetime.now(UTC).replace(microsecond=0)
    result = cli("compensate", directory / "points.csv", "--format", "csv", "-o", tmp_path / "t.csv")
    assert result.code == 0, result.err
    said = read_comp_provenance(tmp_path / "t.csv")
    assert said["campaign"] == "spindle-2026" and said["measured"] == "2026-03-02T08:15:00+00:00"
    assert said["machine"] == "mill-3" and said["axis"] == "Y" and said["software"].startswith("axiscal ")
    assert before <= datetime.fromisoformat(said["written"]) <= datetime.now(UTC)


def test_the_control_is_named_as_the_manual_writes_it(cli, tmp_path):
    """`--control 808D` as on the control's front panel: the same 200-point limit as 808d."""
    from campaign.discovery.simulate import simulate_campaign
    from campaign.model import ErrorModel
    from campaign.pointtable import write_points
    from tests.test_discovery import CONFIG

    write_points(tmp_path / "p.csv", simulate_campaign(CONFIG, ErrorModel({"linear_scale": {"ppm": -12.0}}), seed=1))
    for control in ("808D", "808d"):
        result = cli("compensate", tmp_path / "p.csv", "--format", "siemens", "--control", control,
                     "--spacing", "1", "-o", tmp_path / f"{control}.spf")
        assert result.code == 2 and "at most 200" in result.err, result.err
    assert cli("compensate", tmp_path / "p.csv", "--format", "siemens", "--control", "808D",
               "--spacing", "5", "-o", tmp_path / "ok.spf").code == 0


# Issue 26 item 4: a table is read in the unit it was written in.
INCH_COMP = "0.0 0.0001 -0.0001\n1.0 1.0002 0.9998\n2.0 2.0001 1.9999\n3.0 3.0000 3.0000\n"
"""An inch machine's LinuxCNC COMP_FILE (LINEAR_UNITS = inch): nominal every inch, actual a few
ten-thousandths off."""


def test_an_inch_linuxcnc_table_is_read_in_inches_when_told(tmp_path):
    path = tmp_path / "inch.comp"
    path.write_text(INCH_COMP)
    as_mm = read_comp_table(path, "linear", "linuxcnc", FormatOptions(units="mm"))
    as_inch = read_comp_table(path, "linear", "linuxcnc", FormatOptions(units="inch"))
    assert as_inch.spacing == pytest.approx(25.4) and as_mm.spacing == pytest.approx(1.0)
    assert np.allclose(as_inch.positions, np.array([0.0, 1.0, 2.0, 3.0]) * 25.4)
    # trim = nominal - actual: -0.0001 in = -2.54 µm forward at 0
    assert as_inch.forward[0] == pytest.approx(-2.54) and as_mm.forward[0] == pytest.approx(-0.1)
    assert np.allclose(as_inch.forward, as_mm.forward * 25.4)
    with pytest.raises(BAD_INPUT, match="rotary joint"):
        read_comp_table(path, "rotary", "linuxcnc", FormatOptions(units="inch"))


def test_the_unit_assumed_is_said_and_units_only_apply_to_linuxcnc(tmp_path):
    from campaign.compensation.table_file import table_units_note

    path = tmp_path / "t.comp"
    path.write_text(INCH_COMP)
    note = table_units_note(path, None, None)
    assert note is not None and "read in mm" in note and "--units inch" in note
    assert table_units_note(path, None, "inch") is None
    csv = tmp_path / "t.csv"
    csv.write_text(render("csv", ControllerTable("linear", 0.0, 10.0, np.zeros(3), np.zeros(3), np.zeros(3), "uni",
                                                 None), FormatOptions()).text)
    assert table_units_note(csv, None, None) is None
    with pytest.raises(BAD_INPUT, match="--units applies to LinuxCNC"):
        table_units_note(csv, None, "inch")


def test_a_spike_between_neighbours_is_warned_about(tmp_path):
    from campaign.compensation.table_file import table_spikes

    smooth = np.array([0.0, 1.5, 3.0, 3.8, 5.1, 6.0, 6.4, 7.9])
    table = ControllerTable("linear", 0.0, 60.0, smooth, smooth, smooth, "uni", None)
    assert table_spikes(table, "t") == []
    spiked = smooth.copy()
    spiked[4] += 200.0  # a 0.2 mm trim typed among µm
    warned = table_spikes(ControllerTable("linear", 0.0, 60.0, spiked, spiked, spiked, "uni", None), "t")
    assert len(warned) == 1 and "between 180 and 240" in warned[0] and "spike" in warned[0]

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

"""ecmc's encoder correction table (`encoder: lookuptable: filename:`), written and read back.

Hand-worked: the UNI table of tests/test_table_formats.py (points 0, 10, 20 mm, common correction
[-6, 2, 1] µm, B̄ = 2 µm). ecmc (10.0.0 and later) subtracts scale·value from the encoder position,
scale 1 by default, so the value is the correction: -6 µm = -0.006 mm, 2 µm = 0.002 mm, 1 µm = 0.001 mm.
"""

from __future__ import annotations

import numpy as np
import pytest

from campaign.compensation.grid import ControllerTable
from campaign.compensation.table_file import read_comp_table
from campaign.errors import BAD_INPUT
from protocols.tables import FormatOptions, TableRead, ecmc, parse, render, sniff

UNI = ControllerTable("linear", 0.0, 10.0, np.array([-7.0, 1.0, 0.0]), np.array([-5.0, 3.0, 2.0]),
                      np.array([-6.0, 2.0, 1.0]), "uni", 2.0, reference=0.0)
BI = ControllerTable("linear", 0.0, 10.0, np.array([-5.0, 3.0, 0.0]), np.array([-7.0, 1.0, 2.0]),
                     np.array([-6.0, 2.0, 1.0]), "bi", None)


def test_ecmc_rows_are_the_correction_in_axis_units():
    out = render("ecmc", UNI, FormatOptions(provenance=(("machine", "bl-01"),)))
    assert out.text.splitlines()[1:] == ["# machine: bl-01", "# encoder position, value ecmc subtracts from it (lookuptable: scale: 1) (axis unit)",
                                         "PREC=10",
                                         "0.000000 -0.006000000", "10.000000 0.002000000", "20.000000 0.001000000"]
    assert out.text.startswith("# ecmc ") and out.text.endswith("\n") and "\n\n" not in out.text
    assert any("lookuptable: filename:" in note for note in out.notes)
    assert any("reversal" in note and "2" in note for note in out.notes)  # B̄ is not in the file: said
    with pytest.raises(BAD_INPUT, match="use --mode uni"):
        render("ecmc", BI)


def test_ecmc_reads_back_what_it_wrote_and_is_recognised(tmp_path):
    text = render("ecmc", UNI).text
    assert sniff(text) == "ecmc"
    assert parse("ecmc", text, "t.corr") == TableRead(0.0, 10.0, (-0.006, 0.002, 0.001), (-0.006, 0.002, 0.001),
                                                      "uni")
    assert "0.000000 -0.006000000" in text  # the correction itself, not its negative
    path = tmp_path / "t.corr"
    path.write_text(text)
    table = read_comp_table(path, "linear")  # what `axiscal verify --comp t.corr` loads
    assert np.allclose(table.forward, [-6.0, 2.0, 1.0]) and np.allclose(table.reverse, table.forward)
    assert (table.start, table.spacing, table.mode) == (0.0, 10.0, "uni")


def test_a_table_written_by_hand_as_ecmc_reads_it():
    # An engineer's own file: a comment, a precision line, rows from -10 mm every 10 mm.
    text = "# X axis of bl-01, 2025\nPREC=5\n-10 0.0012\n0 0\n10 -0.0008\n"
    assert parse("ecmc", text, "x.corr") == TableRead(-10.0, 10.0, (0.0012, 0.0, -0.0008), (0.0012, 0.0, -0.0008),
                                                      "uni")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_ecmc_rule_applied_to_our_file_removes_a_known_error(seed):
    """ecmc's documented rule, actual = raw − scale·value(raw) (scale 1), applied to the file axiscal
    writes for a known error: where ecmc's loop stops (actual = nominal), the axis's true position
    raw + error(raw) is the nominal one to within the error's change over the error itself."""
    rng = np.random.default_rng(seed)
    positions = np.arange(0.0, 601.0, 50.0)  # mm
    slope, amplitude, phase = rng.uniform(-20, 20), rng.uniform(2, 8), rng.uniform(0, 2 * np.pi)

    def error_mm(x):  # actual minus nominal: a pitch slope and a periodic part, µm → mm
        return (slope * x / 600.0 + amplitude * np.sin(2 * np.pi * x / 200.0 + phase)) / 1000.0

    correction_um = -error_mm(positions) * 1000.0  # axiscal's table: what the control adds, minus the error
    table = ControllerTable("linear", 0.0, 50.0, correction_um, correction_um, correction_um, "uni", None)
    rows = ecmc.read_rows(render("ecmc", table).text, "x.corr")
    table_x, values = [p for p, _ in rows], [v for _, v in rows]
    residuals = []
    for nominal in positions:
        raw = nominal
        for _ in range(50):  # ecmc's loop: move the raw position until actual = nominal
            raw += nominal - ecmc.apply_encoder_table(raw, table_x, values, scale=1.0)
        residuals.append(raw + error_mm(raw) - nominal)
    before = np.max(np.abs(error_mm(positions)))
    assert before > 0.002
    assert np.max(np.abs(residuals)) < 0.01 * before, (before, residuals)


@pytest.mark.parametrize("text, says", [
    ("PREC=10\n0 0\n \n10 0\n20 0\n", "line 3: expected 'position value'"),  # a space is not an empty line
    ("0\n10 0\n20 0\n", "line 1: expected 'position value'"),
    ("PREC =5\n0 0\n10 0\n20 0\n", "line 1: position 'PREC' is not a number"),  # sscanf("PREC=%d") fails
    ("0 0\n10 x\n20 0\n", "line 2: value 'x' is not a number"),
    ("0 0\n10 0\n", "at least 3 rows"),
    ("0 0\n20 0\n10 0\n", "not in increasing order"),
    ("0 0\n10 0\n25 0\n", "not equidistant"),
])
def test_a_bad_ecmc_table_names_the_line(text, says):
    with pytest.raises(BAD_INPUT, match=says):
        parse("ecmc", text, "bad.corr")


def test_ecmc_reader_takes_what_ecmcs_loader_takes():
    """ecmcLookupTable.h: commas as spaces, empty lines skipped, text after the two numbers ignored,
    PREC=n (also first in the file, where it makes the file recognisable as ecmc's)."""
    text = "PREC=6\n-10, 0.0012 first row\n\n0 0\n10 -0.0008  # last\nPREC=10\n"
    assert sniff(text) == "ecmc"
    assert parse("ecmc", text, "x.corr") == TableRead(-10.0, 10.0, (0.0012, 0.0, -0.0008), (0.0012, 0.0, -0.0008),
                                                      "uni")

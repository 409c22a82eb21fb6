"""`axiscal analyze`: JSON output, the plot, standards, and one-line errors for every bad input."""

import json
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.conftest import PAPER, assert_one_line_error

HORIZONTAL = PAPER / "horizontal_before.csv"
KEYS = ("A", "A_up", "A_down", "E", "E_up", "E_down", "M", "B", "B_mean", "R", "R_up", "R_down")


def test_json_has_every_key(cli):
    result = cli("analyze", HORIZONTAL, "--json")
    assert result.code == 0
    data = json.loads(result.out)
    for key in KEYS + ("standard", "unit", "runs", "targets"):
        assert key in data, key
    assert data["A"] == pytest.approx(9.152, abs=5e-4)
    assert data["unit"] == "um" and data["runs"] == 3 and len(data["targets"]) == 11


def test_default_output_is_tables_with_units(cli):
    result = cli("analyze", HORIZONTAL)
    assert result.code == 0
    assert "9.152" in result.out and "value (µm)" in result.out and not re.search(r"\bum\b", result.out) and "target mm" in result.out


@pytest.mark.parametrize("name", ["GB/T 17421.2", "JIS B 6190-2", "iso230-2"])
def test_aliases_give_iso_2014(cli, name):
    data = json.loads(cli("analyze", HORIZONTAL, "--json", "--standard", name).out)
    assert data["standard"] == "ISO 230-2:2014" and data["A"] == pytest.approx(9.152, abs=5e-4)


def test_1988_uses_three_sigma(cli):
    data = json.loads(cli("analyze", HORIZONTAL, "--json", "--standard", "ISO230-2:1988").out)
    t0 = data["targets"][0]
    assert data["R_up"] == pytest.approx(max(6 * t["s_up"] for t in data["targets"]))
    assert data["A"] > 9.152 and t0["R_up"] == pytest.approx(6 * t0["s_up"])


def test_vdi3441_keys(cli):
    data = json.loads(cli("analyze", HORIZONTAL, "--json", "--standard", "VDI 3441").out)
    for key in ("Pa", "Ps_max", "U_max", "P"):
        assert isinstance(data[key], float), key
    assert data["U_max"] == pytest.approx(data["B"])
    assert data["Pa"] == pytest.approx(data["M"])
    assert data["P"] >= data["Pa"]


def test_unknown_standard(cli):
    assert_one_line_error(cli("analyze", HORIZONTAL, "--standard", "ASME"), "unknown standard")


def test_png_plot_is_valid(cli, tmp_path):
    out = tmp_path / "plot.png"
    assert cli("analyze", HORIZONTAL, "--plot", out).code == 0
    head = out.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    assert int.from_bytes(head[16:20], "big") > 300


def test_svg_plot_is_valid(cli, tmp_path):
    out = tmp_path / "plot.svg"
    assert cli("analyze", HORIZONTAL, "--plot", out, "--json").code == 0
    root = ET.parse(out).getroot()
    assert root.tag.endswith("svg")
    assert "9.152" in out.read_text()


def test_bad_plot_extension(cli, tmp_path):
    assert_one_line_error(cli("analyze", HORIZONTAL, "--plot", tmp_path / "x.jpg"), ".jpg")


def test_a_plot_path_that_cannot_be_a_file_is_refused_before_anything_runs(cli, tmp_path):
    """A directory named x.png, or a path under a file: exit 2 before the work (a new user's
    trial lost a whole campaign's result to `run --plot DIR`, an internal error at its end). The same
    check guards run, verify, discover and history trend (campaign.plot.check_plot_path)."""
    (tmp_path / "x.png").mkdir()
    assert_one_line_error(cli("analyze", HORIZONTAL, "--plot", tmp_path / "x.png"), "x.png", "is a directory")
    (tmp_path / "f.txt").write_text("a file\n")
    assert_one_line_error(cli("analyze", HORIZONTAL, "--plot", tmp_path / "f.txt" / "y.png"), "is a file, not a directory")
    # a folder that does not exist yet is made (make demo writes its plot into the campaign's own)
    assert cli("analyze", HORIZONTAL, "--plot", tmp_path / "new" / "y.png").code == 0
    assert (tmp_path / "new" / "y.png").stat().st_size > 1000
    # as `make demo` asks: the plot inside the campaign directory the run makes (the first version of this
    # check refused it, and make demo failed on a fresh clone)
    assert cli("demo", "--fake", "--out", tmp_path / "d", "--plot", tmp_path / "d" / "iso230.png").code == 0
    assert (tmp_path / "d" / "iso230.png").is_file()
    assert_one_line_error(cli("demo", "--fake", "--out", tmp_path / "c", "--plot", tmp_path / "x.png"),
                          "is a directory")
    assert not (tmp_path / "c").exists()


def _write(tmp_path, content, name="t.csv", binary=False):
    path = tmp_path / name
    if binary:
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8", newline="")
    return path


GOOD_HEADER = "run,direction,target_mm,deviation_um\n"
BAD_INPUTS = {
    "empty": ("", ["empty"]),
    "blank lines only": ("\n\n  \n", ["empty"]),
    "header only": (GOOD_HEADER, ["no data rows"]),
    "comments only": ("# just a comment\n", ["no header"]),
    "wrong delimiter": ("run;direction;target_mm;deviation_um\n1;+;0;1\n", ["delimiter", ":1"]),
    "missing column": ("run,direction,target_mm\n1,+,0\n", ["missing column 'deviation_um'"]),
    "non-numeric": (GOOD_HEADER + "1,+,0,1.0\n1,+,10,abc\n", [":3", "deviation_um", "abc"]),
    "nan": (GOOD_HEADER + "1,+,0,nan\n", [":2", "deviation_um", "finite"]),
    "inf": (GOOD_HEADER + "1,+,0,1\n1,+,5,-inf\n", [":3", "finite"]),
    "unknown direction": (GOOD_HEADER + "1,up,0,1\n", [":2", "direction", "up"]),
    "run zero": (GOOD_HEADER + "0,+,0,1\n", [":2", "run"]),
    "run fraction": (GOOD_HEADER + "1.5,+,0,1\n", [":2", "run"]),
    "short row": (GOOD_HEADER + "1,+,0\n", [":2", "expected 4 fields"]),
    "duplicate point": (GOOD_HEADER + "1,+,0,1\n1,+,0,2\n", [":3", "duplicate"]),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_one_line_exit_2(cli, tmp_path, case):
    content, fragments = BAD_INPUTS[case]
    path = _write(tmp_path, content)
    assert_one_line_error(cli("analyze", path), str(path), *fragments)


def test_binary_garbage(cli, tmp_path):
    path = _write(tmp_path, bytes(range(256)) * 8, binary=True)
    assert_one_line_error(cli("analyze", path), "binary")


def test_not_utf8(cli, tmp_path):
    path = _write(tmp_path, GOOD_HEADER.encode() + "1,+,0,\xe9\n".encode("latin-1"), binary=True)
    assert_one_line_error(cli("analyze", path), "UTF-8")


def test_missing_file_and_directory(cli, tmp_path):
    assert_one_line_error(cli("analyze", tmp_path / "nope.csv"), "no such file")
    assert_one_line_error(cli("analyze", tmp_path), "directory")


def test_bom_crlf_comments_and_unicode_minus(cli, tmp_path):
    text = "\ufeff# machine: press\r\n" + GOOD_HEADER.replace("\n", "\r\n")
    for run in (1, 2):
        text += f"{run},+,0,\u22121.5\r\n{run},+,10,2\r\n{run},\u2212,10,2.5\r\n{run},-,0,\u22121\r\n"
    path = _write(tmp_path, text)
    data = json.loads(cli("analyze", path, "--json").out)
    assert data["targets"][0]["mean_up"] == pytest.approx(-1.5)
    assert data["targets"][0]["mean_down"] == pytest.approx(-1.0)
    assert data["runs"] == 2


def test_few_runs_warn_and_one_run_has_no_repeatability(cli, tmp_path):
    path = _write(tmp_path, GOOD_HEADER + "1,+,0,1\n1,+,10,2\n1,-,10,2\n1,-,0,1\n")
    result = cli("analyze", path, "--json")
    data = json.loads(result.out)
    assert result.code == 0 and "warning: 1 run(s)" in result.err
    assert data["R"] is None and data["R_up"] is None and data["targets"][0]["s_up"] is None
    assert data["E"] == pytest.approx(1.0) and data["B"] == pytest.approx(0.0)


@pytest.mark.machine
def test_subprocess_entry_points_no_traceback(tmp_path):
    """The installed console script and `python -m campaign` behave the same on bad input."""
    path = _write(tmp_path, GOOD_HEADER + "1,+,0,x\n")
    script = Path(sys.executable).with_name("axiscal")
    for cmd in ([sys.executable, "-m", "campaign"], [str(script)]):
        proc = subprocess.run([*cmd, "analyze", str(path)], check=False, capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 2 and proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1


def test_other_numeric_columns_are_kept_as_extra(tmp_path):
    from campaign.pointtable import read_points

    path = _write(tmp_path, "run,direction,target_mm,deviation_um,point,note,samples\n"
                            "1,+,0,1,0,ok,10\n1,+,10,2,1,fine,\u22121\n")
    table = read_points(path)
    assert list(table.extra) == ["point", "samples"]  # 'note' is text: left out
    assert list(table.extra["point"]) == [0, 1] and list(table.extra["samples"]) == [10, -1]


@pytest.mark.parametrize("value", ["nan", "inf", "0", "-2", "fast"])
def test_speed_must_be_a_finite_positive_number(cli, value):
    assert_one_line_error(cli("demo", "--speed", value), "--speed")


def test_a_partial_table_is_analysed_as_far_as_it_goes(cli, tmp_path):
    """Target 0 measured one way only (a campaign stopped in run 1): no error, no verdict."""
    path = _write(tmp_path, GOOD_HEADER + "1,+,0,1\n1,+,10,1\n1,-,10,1\n")
    result = cli("analyze", path, "--json", "--tolerance", "10")
    assert result.code == 0, result.err
    data = json.loads(result.out)
    assert data["verdict"] == "not judged" and data["A"] is None
    assert any("1 of 4 points missing" in r for r in data["reasons"])
    assert data["targets"][0]["n_down"] == 0 and data["targets"][1]["n_down"] == 1


def glitched_table(tmp_path, glitch_um: float):
    """11 targets × 2 directions × 5 runs, 0.5 µm noise, one reading `glitch_um` off."""
    import numpy as np

    rng = np.random.default_rng(3)
    lines = [GOOD_HEADER.replace("\n", ",material_temp_c\n")]
    for run in range(1, 6):
        for d in ("+", "-"):
            for i in range(11):
                dev = -0.0124 * 60 * i + (0.5 if d == "+" else -0.5) + rng.normal(0, 0.5)
                if (run, d, i) == (4, "-", 6):
                    dev += glitch_um
                lines.append(f"{run},{d},{60 * i},{dev:.4f},20.1\n")
    return _write(tmp_path, "".join(lines))


def test_a_12_um_glitch_is_listed_in_outliers(cli, tmp_path):
    data = json.loads(cli("analyze", glitched_table(tmp_path, 12.0), "--json").out)
    assert [(o["run"], o["direction"], o["target"]) for o in data["outliers"]] == [(4, "-", 360.0)]
    assert data["outliers"][0]["score"] > data["outliers"][0]["critical"]
    assert data["outlier_test"]["s_with_outliers"] > 2 * data["outlier_test"]["s_without_outliers"]
    assert data["R"] > 12  # reported, not removed: R includes it
    assert not json.loads(cli("analyze", glitched_table(tmp_path, 0.0), "--json").out)["outliers"]
    text = cli("analyze", glitched_table(tmp_path, 12.0)).out
    assert "1 outlier(s)" in text and "run 4, direction -, target 360" in text


def test_the_verdict_needs_a_tolerance_and_follows_the_decision_rule(cli, tmp_path):
    table = glitched_table(tmp_path, 0.0)
    data = json.loads(cli("analyze", table, "--json").out)
    assert data["verdict"] == "not judged" and any("no tolerance" in r for r in data["reasons"])
    a, u = data["A"], data["uncertainty"]["U_A_um"]
    assert u > 0 and data["decision_rule"].startswith("ISO 14253-1")
    assert json.loads(cli("analyze", table, "--json", "--tolerance", f"{a + u + 0.01}").out)["verdict"] == "pass"
    assert json.loads(cli("analyze", table, "--json", "--tolerance", f"{a + u / 2}").out)["verdict"] == "not judged"
    assert json.loads(cli("analyze", table, "--json", "--tolerance", f"{a - u - 0.01}").out)["verdict"] == "fail"


def test_without_the_material_temperature_the_budget_is_incomplete_and_nothing_is_judged(cli):
    data = json.loads(cli("analyze", HORIZONTAL, "--json", "--tolerance", "50").out)
    assert data["verdict"] == "not judged"
    assert any("material temperature" in r for r in data["reasons"]) and data["uncertainty"]["missing"]


def display_width(line: str) -> int:
    import unicodedata

    return sum(0 if unicodedata.combining(c) else 1 for c in line)


@pytest.mark.machine
@pytest.mark.parametrize("argv", [("analyze", HORIZONTAL), ("refine", HORIZONTAL), ("discover", HORIZONTAL),
                                  ("compensate", HORIZONTAL, "--format", "csv", "-o", "{tmp}/t.csv")])
def test_80_columns_cut_no_number_and_print_micrometres(cli, tmp_path, monkeypatch, argv):
    monkeypatch.setenv("COLUMNS", "80")
    result = cli(*(str(a).format(tmp=tmp_path) for a in argv))
    assert result.code == 0, result.err
    lines = result.out.splitlines()
    assert max(display_width(ln) for ln in lines) <= 80
    assert "…" not in result.out
    assert not [ln for ln in lines if re.search(r"\bum\b", ln)], "um instead of µm"
    if argv[0] == "analyze":
        data = json.loads(cli("analyze", HORIZONTAL, "--json").out)
        for target in data["targets"]:  # every per-target number, whole
            for key in ("mean_up", "mean_down", "s_up", "R"):
                assert f"{target[key]:.3f}" in result.out
        wide = cli("analyze", HORIZONTAL, "--wide").out
        assert "means and scatter" not in wide and "means and scatter" in result.out


def test_no_command_is_one_error_line_after_the_list_of_commands(cli):
    result = cli()
    assert_one_line_error(result, "no command given")
    assert "analyze" in result.out and "discover" in result.out  # the commands, listed


def test_no_help_text_shows_a_doubled_percent_sign(cli):
    """argparse formats `help` with %, not `description`: a '%%' written in a description was shown as
    it is (history plant's '95 %%')."""
    import argparse

    from campaign.cli import build_parser

    def every(parser: argparse.ArgumentParser):
        yield parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    yield from every(sub)

    commands = next(a for a in build_parser([])._actions if isinstance(a, argparse._SubParsersAction)).choices
    parsers = [p for name in commands for p in every(build_parser([name]))]  # each registered in full
    assert len(parsers) > 30
    for parser in parsers:
        assert "%%" not in parser.format_help(), parser.prog

"""`axiscal convert`: Renishaw .rtl and ecmc ISO 230-2 files to point tables and back.

The .rtl and ecmc texts here are written by hand from the layouts in issue 16 / docs/convert.md,
not by axiscal's writers; the ISO 230-2 values they must give come from the paper's published
table and from a small evaluation written in this file, independent of campaign.iso230."""

import csv
import json

import numpy as np
import pytest

from tests.conftest import PAPER, assert_one_line_error

PUBLISHED = json.loads((PAPER / "published_summary.json").read_text())["in_point_table_directions"]


def paper_rows():
    """(run, direction, target, deviation) of the paper's horizontal axis before compensation."""
    with open(PAPER / "horizontal_before.csv") as f:
        return [(int(r["run"]), 1 if r["direction"] == "+" else -1, float(r["target_mm"]), float(r["deviation_um"]))
                for r in csv.DictReader(line for line in f if not line.startswith("#"))]


def foreign_rtl(rows, runs=3) -> str:
    """An .rtl as another program writes it: CRLF, a blank line too many, targets 4 per line over
    three lines with stray spaces, reverse runs N..1, environment and equipment sections, and a
    section axiscal does not know."""
    targets = sorted({t for _, _, t, _ in rows})
    value = {(r, d, t): e for r, d, t, e in rows}
    lines = ["HEADER::", "File type  : rtl", "Owner      : LaserXL", "Version no : V20.02.02", "", "",
             "TARGET DATA::", "Filetype  : ISO", f"Target-count: {len(targets)}", "Targets :"]
    for i in range(0, len(targets), 4):
        lines.append("  " + "   ".join(f"{t:.4f}" for t in targets[i:i + 4]) + " ")
    lines += ["Flags: 0 0 2 0", "", "USER-TEXT::", "Machine:  Press 7", "Serial No: SN-0042",
              "Date: 2022-03-14 10:21:05", "By: Li", "Axis: X", "Location: Hall 2", "TITLE: before compensation", "",
              "RUNS::", f"Run-count: {2 * runs}", "", "DEVIATIONS::", "Run Target Data:"]
    for run in range(1, runs + 1):
        for n, t in enumerate(targets, start=1):
            lines.append(f"{2 * run - 1}   {n}      {value[(run, 1, t)]}")
        for n in range(len(targets), 0, -1):
            lines.append(f"{2 * run}   {n}      {value[(run, -1, targets[n - 1])]}")
    lines += ["", "ENVIRONMENT::", "Air temp   : 20.4", "Air Press  : 1008.2", "Air Humid  : 41.0",
              "Mat temp 1 : 20.1", "Exp coeff  : 11.7", "", "EQUIPMENT::", "Laser: XL-80 123456", "",
              "VENDOR-NOTES::", "calibrated in house", "", "EOF::", ""]
    return "\r\n".join(lines)


def analyze(cli, path):
    result = cli("analyze", path, "--json")
    assert result.code == 0, result.err
    return json.loads(result.out)


def test_an_rtl_from_other_software_reads_with_the_published_values(cli, tmp_path):
    source = tmp_path / "laserxl.rtl"
    source.write_bytes(foreign_rtl(paper_rows()).encode("cp1252"))
    result = cli("convert", source, "-o", tmp_path / "p.csv")
    assert result.code == 0, result.err
    values = analyze(cli, tmp_path / "p.csv")
    for key in ("A", "E", "M", "B", "A_up", "A_down", "R_up", "R_down"):
        assert round(values[key], 3) == PUBLISHED[key], key
    text = (tmp_path / "p.csv").read_text()
    for line in ("# machine: Press 7", "# serial: SN-0042", "# date: 2022-03-14 10:21:05", "# operator: Li",
                 "# axis: X", "# location: Hall 2", "# air_temp_c: 20.4", "# air_pressure_hpa: 1008.2",
                 "# rtl.Exp_coeff: 11.7", "# rtl.EQUIPMENT: Laser: XL-80 123456"):
        assert line in text, line


def test_points_to_rtl_and_back_keeps_every_iso_value_and_the_metadata(cli, tmp_path):
    rtl = tmp_path / "h.rtl"
    assert cli("convert", PAPER / "horizontal_before.csv", "-o", rtl).code == 0
    text = rtl.read_text()
    sections = [line for line in text.splitlines() if line.endswith("::")]
    assert sections == ["HEADER::", "TARGET DATA::", "USER-TEXT::", "RUNS::", "DEVIATIONS::", "EOF::"]
    assert rtl.read_bytes().count(b"\r\n") == len(text.splitlines()) and "Target-count: 11" in text and "Flags: 0 0 2 0" in text and "Run-count: 6" in text
    deviations = text.split("Run Target Data:")[1].split()
    assert deviations[:6] == ["1", "1", "-1.3", "1", "2", "-2.1"]  # run 1 forward from target 1
    assert deviations[33:36] == ["2", "11", "-7.7"]  # run 2 is the reverse of run 1, from target 11
    back = tmp_path / "back.csv"
    assert cli("convert", rtl, "-o", back).code == 0
    before, after = analyze(cli, PAPER / "horizontal_before.csv"), analyze(cli, back)
    for key in ("A", "A_up", "A_down", "E", "E_up", "E_down", "M", "B", "B_mean", "R", "R_up", "R_down"):
        assert after[key] == pytest.approx(before[key], abs=1e-9), key
    again = tmp_path / "again.rtl"
    assert cli("convert", back, "-o", again).code == 0
    assert again.read_text().split("RUNS::")[1] == text.split("RUNS::")[1]


def test_recorded_metadata_and_environment_go_into_the_rtl(cli, tmp_path):
    source = tmp_path / "rec.csv"
    source.write_text("# machine: mill-3\n# axis: Y\n# operator: Ana\n"
                      "run,direction,target_mm,deviation_um,air_temp_c\n"
                      "1,+,0,0.5,20.0\n1,+,10,1.5,20.2\n1,-,10,1.0,20.4\n1,-,0,0.0,20.2\n")
    assert cli("convert", source, "-o", tmp_path / "r.rtl").code == 0
    text = (tmp_path / "r.rtl").read_text()
    assert "Machine: mill-3" in text and "By: Ana" in text and "Axis: Y" in text
    assert "ENVIRONMENT::" in text and "Air temp   : 20.20" in text


def test_a_unidirectional_rtl(cli, tmp_path):
    rtl = ("HEADER::\nTARGET DATA::\nTarget-count: 3\nTargets :\n0 50 100\nFlags: 0 1 2 0\nRUNS::\nRun-count: 2\n"
           "DEVIATIONS::\nRun Target Data:\n1 1 0.0\n1 2 2.0\n1 3 4.0\n2 1 1.0\n2 2 3.0\n2 3 5.0\nEOF::")
    (tmp_path / "u.rtl").write_text(rtl)
    said = cli("convert", tmp_path / "u.rtl", "-o", tmp_path / "u.csv")
    assert said.code == 0 and "A↑ 6.828 µm" in said.out  # one direction: its own values, not an empty list
    rows = [line for line in (tmp_path / "u.csv").read_text().splitlines() if line[:1].isdigit()]
    assert rows[0] == "1,+,0.000000,0.0000" and rows[-1] == "2,+,100.000000,5.0000" and len(rows) == 6
    assert cli("convert", tmp_path / "u.csv", "-o", tmp_path / "u2.rtl").code == 0
    assert "Flags: 0 1 2 0" in (tmp_path / "u2.rtl").read_text()


def test_an_rtl_from_a_table_without_a_date_says_so(cli, tmp_path):
    """A bare table with no `# date:` gives 'Date: not recorded' (it gave an empty 'Date:') and a
    warning; read back, no date is invented."""
    rtl = ("HEADER::\nTARGET DATA::\nTarget-count: 3\nTargets :\n0 50 100\nFlags: 0 1 2 0\nRUNS::\nRun-count: 2\n"
           "DEVIATIONS::\nRun Target Data:\n1 1 0.0\n1 2 2.0\n1 3 4.0\n2 1 1.0\n2 2 3.0\n2 3 5.0\nEOF::")
    (tmp_path / "u.rtl").write_text(rtl)
    assert cli("convert", tmp_path / "u.rtl", "-o", tmp_path / "u.csv").code == 0
    said = cli("convert", tmp_path / "u.csv", "-o", tmp_path / "u2.rtl")
    assert said.code == 0 and "no measurement date" in " ".join(said.out.split())
    assert "Date: not recorded" in (tmp_path / "u2.rtl").read_text().splitlines()
    back = cli("convert", tmp_path / "u2.rtl", "-o", tmp_path / "u3.csv", "--json")
    assert back.code == 0 and "date" not in json.loads(back.out)["meta"]


def test_an_rtl_from_a_campaign_directory_carries_the_day_it_was_started(cli, tmp_path):
    directory = tmp_path / "c"
    directory.mkdir()
    (directory / "meta.json").write_text(json.dumps({"format_version": 2, "created": "2026-03-02T08:15:00+00:00"}))
    rows = "".join(f"{r},{d},{t},{e}\n" for r in (1, 2) for d, sign in (("+", 1), ("-", -1))
                   for t, e in ((0.0, 1.0 * sign), (50.0, 2.0), (100.0, 3.0)))
    (directory / "points.csv").write_text("run,direction,target_mm,deviation_um\n" + rows)
    assert cli("convert", directory / "points.csv", "-o", tmp_path / "c.rtl").code == 0
    assert "Date: 2026-03-02" in (tmp_path / "c.rtl").read_text().splitlines()


def hand_ecmc(targets, fwd, bwd) -> str:
    """An ecmc file from the description: readings (mm) per target i and cycle j, 1-based."""
    lines = ["# Input data file for ISO230-2 calcs", "REF_PV=IOC_TEST:m0s005-Enc01-PosAct",
             "TGT_SET_PV=IOC_TEST:Axis1-PosSet", "UNIT=mm", f"CYCLES={fwd.shape[1]}", f"POSITIONS={len(targets)}",
             "DEC=5"]
    for j in range(fwd.shape[1]):
        for i, t in enumerate(targets):
            lines.append(f"TGT_DATA[{i + 1}]={t}")
            lines.append(f"REF_DATA_FWD[{i + 1},{j + 1}]={float(fwd[i, j])!r} ")
        for i in reversed(range(len(targets))):
            lines.append(f"REF_DATA_BWD[{i + 1},{j + 1}]={float(bwd[i, j])!r}")
    return "\n".join(lines) + "\n"


def independent_iso230(targets, fwd, bwd):
    """ISO 230-2:2014 A, B, R, E, M from readings (mm) -> µm; written from the standard's formulas."""
    up = (fwd - targets[:, None]) * 1000.0
    down = (bwd - targets[:, None]) * 1000.0
    mu, md = up.mean(axis=1), down.mean(axis=1)
    su, sd = up.std(axis=1, ddof=1), down.std(axis=1, ddof=1)
    mean = (mu + md) / 2
    b = mu - md
    r = np.maximum.reduce([2 * su + 2 * sd + np.abs(b), 4 * su, 4 * sd])
    a = max(np.max(mu + 2 * su), np.max(md + 2 * sd)) - min(np.min(mu - 2 * su), np.min(md - 2 * sd))
    e = max(mu.max(), md.max()) - min(mu.min(), md.min())
    return {"A": a, "B": np.max(np.abs(b)), "R": r.max(), "E": e, "M": mean.max() - mean.min()}


def test_ecmc_reads_with_the_values_of_an_independent_evaluation(cli, tmp_path):
    rng = np.random.default_rng(7)
    targets = np.array([15.0, 25.0, 35.0, 45.0, 55.0])
    systematic = np.array([1.6, 21.6, -9.1, -31.3, 26.6]) * 1e-3
    fwd = targets[:, None] + systematic[:, None] + rng.normal(0, 0.4e-3, (5, 5))
    bwd = targets[:, None] + systematic[:, None] - 3e-3 + rng.normal(0, 0.4e-3, (5, 5))
    source = tmp_path / "axis1_ISO230.dat"
    source.write_text(hand_ecmc(targets, fwd, bwd))
    result = cli("convert", source, "-o", tmp_path / "p.csv", "--json")
    assert result.code == 0, result.err
    assert json.loads(result.out)["points"] == 50
    values = analyze(cli, tmp_path / "p.csv")
    for key, expected in independent_iso230(targets, fwd, bwd).items():
        assert values[key] == pytest.approx(expected, abs=2e-4), key  # the table keeps 1e-4 µm
    text = (tmp_path / "p.csv").read_text()
    assert "# ecmc.REF_PV: IOC_TEST:m0s005-Enc01-PosAct" in text and "# ecmc.DEC: 5" in text


def test_an_ecmc_file_with_a_reading_missing_says_so(cli, tmp_path):
    """A REF_DATA_BWD line missing (a cycle cut short) is converted as far as it goes, and said:
    in the text and in JSON `missing`."""
    targets = np.array([15.0, 25.0, 35.0])
    fwd = targets[:, None] + np.zeros((3, 3))
    bwd = targets[:, None] + np.full((3, 3), -2e-3)
    lines = [ln for ln in hand_ecmc(targets, fwd, bwd).splitlines() if not ln.startswith("REF_DATA_BWD[2,3]")]
    source = tmp_path / "cut_ISO230.dat"
    source.write_text("\n".join(lines) + "\n")
    found = json.loads(cli("convert", source, "-o", tmp_path / "p.csv", "--json").out)
    assert found["points"] == 17 and found["missing"] == ["1 of 18 points missing (3 targets × 2 direction(s) × 3 runs)"]
    text = cli("convert", source, "-o", tmp_path / "q.csv")
    said = " ".join(text.out.split())  # the console wraps at its width
    assert text.code == 0 and "warning:" in said and "1 of 18 points missing" in said


def test_points_to_ecmc_and_back(cli, tmp_path):
    dat = tmp_path / "x_ISO230.dat"
    assert cli("convert", PAPER / "horizontal_before.csv", "-o", dat).code == 0
    text = dat.read_text()
    assert "UNIT=mm" in text and "CYCLES=3" in text and "POSITIONS=11" in text
    assert "TGT_DATA[11]=600.000000000" in text and "REF_DATA_FWD[1,1]=-0.001300000" in text
    assert "REF_DATA_BWD[11,3]=" in text
    assert cli("convert", dat, "-o", tmp_path / "back.csv").code == 0
    before, after = analyze(cli, PAPER / "horizontal_before.csv"), analyze(cli, tmp_path / "back.csv")
    for key in ("A", "E", "M", "B", "R", "R_up", "R_down"):
        assert after[key] == pytest.approx(before[key], abs=1e-9), key


HEAD = "TARGET DATA::\nTarget-count: 2\nTargets :\n0 10\nFlags: 0 0 2 0\nRUNS::\nRun-count: 2\nDEVIATIONS::\n"
BAD_RTL = [
    ("no sections", "hello\n", "before the first section"),
    ("no targets", "HEADER::\nTARGET DATA::\nTargets :\nFlags: 0 0 2 0\nRUNS::\nRun-count: 2\nDEVIATIONS::\nEOF::\n",
     "no Target-count"),
    ("count", HEAD.replace("Target-count: 2", "Target-count: 3"), "Target-count is 3 but 2 targets"),
    ("bad number", HEAD.replace("0 10", "0 1O"), "line 4: target '1O' is not a number"),
    ("bad line", HEAD + "Run Target Data:\n1 1 0.5\n1 2\n", "line 11: expected 'run target_number deviation'"),
    ("missing", HEAD + "Run Target Data:\n1 1 0.5\n1 2 0.1\n2 2 0.3\n", "lacks run 2, target 1"),
    ("odd runs", HEAD.replace("Run-count: 2", "Run-count: 3"), "even Run-count"),
    # a Run-count of 10²⁰ with two values: the missing ones are counted, not listed (listed, memory ran out)
    ("huge run count", HEAD.replace("Run-count: 2", "Run-count: 99999999999999999998")
     + "Run Target Data:\n99999999999999999998 1 0.5\n99999999999999999998 2 0.5\n",
     "lacks run 1, target 1 (199999999999999999994 values missing)"),
]


@pytest.mark.parametrize(("case", "text", "says"), BAD_RTL, ids=[c for c, _, _ in BAD_RTL])
def test_a_bad_rtl_is_one_error_line_and_no_output(cli, tmp_path, case, text, says):
    (tmp_path / "bad.rtl").write_text(text)
    out = tmp_path / "out.csv"
    assert_one_line_error(cli("convert", tmp_path / "bad.rtl", "-o", out), says)
    assert not out.exists() and list(tmp_path.iterdir()) == [tmp_path / "bad.rtl"]


@pytest.mark.parametrize(("text", "says"), [
    ("UNIT=mm\nTGT_DATA[1]=0\n", "fewer than 2 TGT_DATA"),
    ("TGT_DATA[1]=0\nTGT_DATA[2]=10\nREF_DATA_FWD[1,1]=x\n", "line 3: 'x' is not a number"),
    ("TGT_DATA[1]=0\nTGT_DATA[2]=10\nREF_DATA_FWD[3,1]=0.1\n", "line 3: REF_DATA_FWD[3,1] has no TGT_DATA[3]"),
    ("TGT_DATA[1]=0\nTGT_DATA[2]=10\nREF_DATA_FWD(1,1)=0.1\n", "line 3: expected TGT_DATA[i]=value"),
    ("UNIT=inch\nTGT_DATA[1]=0\n", "line 1: UNIT must be mm or deg"),
])
def test_a_bad_ecmc_file_is_one_error_line(cli, tmp_path, text, says):
    (tmp_path / "bad.dat").write_text(text)
    assert_one_line_error(cli("convert", tmp_path / "bad.dat", "-o", tmp_path / "o.csv"), says)
    assert not (tmp_path / "o.csv").exists()


def test_format_by_option_and_unknown_extension(cli, tmp_path):
    assert_one_line_error(cli("convert", PAPER / "horizontal_before.csv", "-o", tmp_path / "x.txt"),
                          "cannot tell the format")
    assert cli("convert", PAPER / "horizontal_before.csv", "-o", tmp_path / "x.txt", "--to", "rtl").code == 0
    assert (tmp_path / "x.txt").read_text().startswith("HEADER::")
    assert_one_line_error(cli("convert", tmp_path / "nope.rtl", "-o", tmp_path / "y.csv"), "no such file")


@pytest.mark.machine
def test_demo_points_to_rtl_and_back_keep_every_iso_value(cli, tmp_path, demo_campaign):
    points = demo_campaign()[1] / "points.csv"
    assert cli("convert", points, "-o", tmp_path / "d.rtl").code == 0
    text = (tmp_path / "d.rtl").read_text()
    sections = [line for line in text.splitlines() if line.endswith("::")]
    assert sections == ["HEADER::", "TARGET DATA::", "USER-TEXT::", "RUNS::", "DEVIATIONS::", "ENVIRONMENT::", "EOF::"]
    assert "Run-count: 10" in text and "Machine: sim-press" in text
    assert cli("convert", tmp_path / "d.rtl", "-o", tmp_path / "back.csv").code == 0
    before, after = analyze(cli, points), analyze(cli, tmp_path / "back.csv")
    for key in ("A", "A_up", "A_down", "E", "E_up", "E_down", "M", "B", "B_mean", "R", "R_up", "R_down"):
        assert after[key] == pytest.approx(before[key], abs=1e-9), key


def test_a_round_trip_says_what_the_rtl_cannot_hold_and_keeps_the_simulated_mark(cli, tmp_path):
    """points.csv of a campaign -> .rtl -> .csv: the ISO values stay; what the .rtl has no place
    for (per-point columns, the campaign's tolerance) is said, and so is the verdict's change
    (PASS for the campaign, NOT JUDGED for the file alone: the old convert said nothing); the
    simulated mark travels in the TITLE and comes back."""
    from campaign.config import parse_config
    from campaign.measure import start_campaign
    from tests.fakes import SMALL, FakeMachine

    config = parse_config(SMALL.replace("tolerance = 10.0", "tolerance = 500.0"), "small.toml")
    machine = FakeMachine(setup=lambda parts: parts.laser.env.update(material_temp_c=20.4))
    start_campaign(config, tmp_path / "c", opener=machine)
    points = tmp_path / "c" / "points.csv"
    simulated = "# simulated: yes (not a measurement of a real axis)\n"
    points.write_text(simulated + points.read_text())  # as the simulated machine's campaigns say it
    out = cli("convert", points, "-o", tmp_path / "c.rtl", "--json")
    assert out.code == 0, out.err
    said = json.loads(out.out)
    lost = " ".join(said["not_carried"])
    assert "tolerance on A (500 µm" in lost and "the per-point columns time_s" in lost
    assert said["verdict_change"].startswith(f"the verdict changes: PASS for {points}, NOT JUDGED for ")
    text = cli("convert", points, "-o", tmp_path / "c2.rtl")
    assert "not carried by rtl:" in text.out and "warning: the verdict changes: PASS" in text.out
    assert "TITLE: SIMULATED, not a measurement of a real axis" in (tmp_path / "c.rtl").read_text()
    back = cli("convert", tmp_path / "c.rtl", "-o", tmp_path / "back.csv", "--json")
    assert back.code == 0 and json.loads(back.out)["verdict_change"] is None
    assert simulated in (tmp_path / "back.csv").read_text()
    before, after = analyze(cli, points), analyze(cli, tmp_path / "back.csv")
    for key in ("A", "E", "M", "B", "R"):
        assert after[key] == pytest.approx(before[key], abs=1e-3), key

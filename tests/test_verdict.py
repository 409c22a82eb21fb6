"""One verdict for every command (campaign/verdict.py, campaign/assess.py) and the uncertainty
budget (campaign/uncertainty.py): incomplete campaigns are not judged, the decision rule, the
budget's terms against hand calculation."""

import json
import math

import numpy as np
import pytest

from campaign.config import config_with, parse_config
from campaign.iso230 import evaluate
from campaign.measure.session import start_campaign
from campaign.pointtable import PointTable
from campaign.uncertainty import budget
from campaign.verdict import Planned, judge
from tests.fakes import SMALL, AxisFault, FakeMachine


def table(runs=5, targets=11, sigma=0.5, seed=1, material=20.1):
    rng = np.random.default_rng(seed)
    rows = [(r, d, 60.0 * i) for r in range(1, runs + 1) for d in (1, -1) for i in range(targets)]
    run, direction, target = (np.array(c) for c in zip(*rows))
    deviation = -0.0124 * target + 0.5 * direction + rng.normal(0, sigma, len(rows))
    optional = {"material_temp_c": np.full(len(rows), material), "air_temp_c": np.full(len(rows), 20.0),
                "air_pressure_hpa": np.full(len(rows), 1013.25), "humidity_pct": np.full(len(rows), 50.0)}
    return PointTable("linear", run, direction, target.astype(float), deviation, optional)


def test_budget_terms_against_hand_calculation():
    t = table()
    ev = evaluate(t)
    b = budget(t, ev)
    terms = {term.name: term.u for term in b.terms}
    assert terms["laser wavelength"] == pytest.approx(0.5 / 2 * 600e-3)  # 0.5 µm/m, k = 2, over 600 mm
    # air: about 0.95 µm/m per K (reference §6) × 0.1 K, 0.27 µm/m per hPa × 0.5 hPa, 0.0085 × 3 %RH
    expected_air = 0.6 * math.sqrt((0.95 * 0.1) ** 2 + (0.27 * 0.5) ** 2 + (0.0085 * 3) ** 2)
    assert terms["air refractive index"] == pytest.approx(expected_air, rel=0.03)
    assert terms["uncorrected expansion"] == pytest.approx(11.5 * 0.6 * 0.1 / math.sqrt(3), rel=1e-6)
    assert terms["misalignment (cosine error)"] == pytest.approx(0.5 ** 2 / 1200 * 1000 / math.sqrt(3))
    s = max(x for r in ev.targets for x in (r.s_up, r.s_down))
    assert terms["statistics: the means (finite runs)"] == pytest.approx(math.sqrt(2) * s / math.sqrt(5))
    linear = [u for term in b.terms if "A" in term.applies for u in [term.u]]
    assert b.expanded["A"] == pytest.approx(2 * math.sqrt(sum(u * u for u in linear)))
    assert b.expanded["B"] < b.expanded["E"] < b.expanded["A"]  # length terms cancel in B


def test_a_certificate_value_replaces_the_typical_one():
    t = table()
    config = parse_config(SMALL + "\n[instrument]\nwavelength_uncertainty_ppm = 0.2\nmodel = \"XL-80\"\n", "c.toml")
    b = budget(t, evaluate(t), config)
    term = next(x for x in b.terms if x.name == "laser wavelength")
    assert term.u == pytest.approx(0.1 * 0.6) and "certificate" in term.source and "NOT" not in term.source
    default = next(x for x in budget(t, evaluate(t)).terms if x.name == "laser wavelength")
    assert "NOT from a certificate" in default.source


@pytest.mark.parametrize("margin, expected", [(0.01, "pass"), (-0.01, "not judged")])
def test_decision_rule_at_the_edges(margin, expected):
    t = table()
    ev = evaluate(t)
    b = budget(t, ev)
    a, u = ev.summary["A"], b.expanded["A"]
    assert judge(t, ev, {"A": a + u + margin}, b).verdict == expected
    assert judge(t, ev, {"A": a - u - 0.01}, b).verdict == "fail"
    assert judge(t, ev, {"A": a - u + 0.01}, b).verdict == "not judged"


def test_missing_points_against_the_plan_are_not_judged():
    t = table()
    ev = evaluate(t)
    v = judge(t, ev, {"A": 100.0}, budget(t, ev), plan=Planned(points=120, runs=6))
    assert v.verdict == "not judged"
    assert v.reasons[:2] == ("incomplete campaign: 10 of 120 planned points are missing",
                             "incomplete campaign: 5 of 6 planned runs measured")


def test_other_tolerances_are_judged_too():
    t = table()
    ev = evaluate(t)
    v = judge(t, ev, {"A": 100.0, "B": 0.01}, budget(t, ev))
    assert v.verdict == "fail" and [c["parameter"] for c in v.checks] == ["A", "B"]
    assert "reversal value B" in v.reasons[0]


def test_an_interrupted_campaign_directory_is_not_judged(cli, tmp_path):
    cfg = parse_config(SMALL + "\n[environment]\nnormalise_to_20c = false\n", "small.toml")
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    result = cli("analyze", tmp_path / "c", "--json")
    assert result.code == 0, result.err
    data = json.loads(result.out)
    assert data["verdict"] == "not judged" and data["planned_points"] == 12 and data["points"] == 3
    assert "incomplete campaign: 9 of 12 planned points are missing" in data["reasons"]
    same = json.loads(cli("analyze", tmp_path / "c" / "points.csv", "--json").out)  # its points.csv: the same
    assert same["reasons"] == data["reasons"]


def test_the_report_of_an_interrupted_campaign_has_no_pass(cli, tmp_path):
    cfg = parse_config(SMALL, "small.toml")
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(8))))
    assert cli("report", tmp_path / "c", "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    assert "<span class='word'>NOT JUDGED</span>" in html and "PASS" not in html
    assert "planned points are missing" in html and "Per run" in html and "SIMULATED" in html


def test_report_takes_a_point_table_file(cli, tmp_path):
    from tests.conftest import PAPER

    assert cli("report", PAPER / "horizontal_before.csv", "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    assert "NOT JUDGED" in html and "material temperature" in html and "9.152" in html


def test_compensate_refuses_an_incomplete_campaign_unless_partial(cli, tmp_path):
    """An incomplete campaign gets exit 2 naming what is missing, resume and --partial (the old code
    warned and wrote the table, exit 0); --partial writes it and says which travel it covers."""
    from tests.conftest import assert_one_line_error

    cfg = parse_config(SMALL.replace("cycles = 2", "cycles = 3"), "small.toml")
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    # move 17 is the overrun before run 3: runs 1 and 2 are complete, run 3 is missing
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(17))))
    result = cli("compensate", tmp_path / "c" / "points.csv", "--format", "csv", "-o", tmp_path / "t.csv")
    assert_one_line_error(result, "incomplete campaign (6 of 18 planned points are missing", "axiscal resume",
                          "--partial")
    assert not (tmp_path / "t.csv").exists()
    partial = cli("compensate", tmp_path / "c" / "points.csv", "--format", "json", "-o", tmp_path / "t.json",
                  "--partial")
    assert partial.code == 0, partial.err
    assert "--partial: the table covers 0 to 100 mm of the planned 0 to 100 mm" in partial.out
    assert json.loads((tmp_path / "t.json").read_text())["provenance"]["machine"] == "fake"
    # the same points outside their directory: no plan, but the grid shows what is missing
    (tmp_path / "bare.csv").write_text((tmp_path / "c" / "points.csv").read_text())
    bare = cli("compensate", tmp_path / "bare.csv", "--format", "csv", "-o", tmp_path / "b.csv")
    assert bare.code == 0, bare.err  # whole runs: nothing is seen missing
    lines = (tmp_path / "c" / "points.csv").read_text().splitlines(keepends=True)
    (tmp_path / "cut.csv").write_text("".join(lines[:-2]))  # run 2 lacks its last two points
    assert_one_line_error(cli("compensate", tmp_path / "cut.csv", "--format", "csv", "-o", tmp_path / "b.csv"),
                          "2 of 12 points missing")


def test_compensate_partial_names_the_travel_a_first_run_covers(cli, tmp_path):
    cfg = parse_config(SMALL, "small.toml")
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    # the fourth move goes to 100 mm: only 0 and 50 mm are measured, upwards
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(4))))
    result = cli("compensate", tmp_path / "c" / "points.csv", "--format", "json", "-o", tmp_path / "t.json",
                 "--partial")
    assert result.code == 0, result.err
    assert "the table covers 0 to 50 mm of the planned 0 to 100 mm" in result.out


def test_verify_refuses_a_table_that_does_not_cover_the_plan(cli, tmp_path):
    from tests.conftest import PAPER, ROOT, assert_one_line_error

    assert cli("compensate", PAPER / "vertical_before.csv", "--format", "json", "-o", tmp_path / "v.json").code == 0
    result = cli("verify", ROOT / "campaign" / "demo.toml", "--comp", tmp_path / "v.json", "--out", tmp_path / "x")
    assert_one_line_error(result, "v.json: the table covers 0 to 300 mm, the plan's targets 0 to 600 mm", "refused")
    assert not (tmp_path / "x").exists()


def test_one_parameter_proven_out_of_tolerance_fails_the_axis_even_when_another_is_undecided():
    t = table()
    ev = evaluate(t)
    b = budget(t, ev)
    r, u_r = ev.summary["R"], b.expanded["R"]
    v = judge(t, ev, {"A": 100.0, "B": 0.01, "R": r + u_r / 2}, b)  # B fails, R cannot be decided
    assert v.verdict == "fail" and len(v.reasons) == 1 and "reversal value B" in v.reasons[0]
    assert [c["result"] for c in v.checks] == ["pass", "fail", "not judged"]
    assert any("repeatability R" in n and "cannot decide" in n for n in v.notes)
    undecided = judge(t, ev, {"A": 100.0, "R": r + u_r / 2}, b)
    assert undecided.verdict == "not judged" and "repeatability R" in undecided.reasons[0]


def test_an_incomplete_campaign_judges_no_parameter():
    t = table()
    ev = evaluate(t)
    v = judge(t, ev, {"A": 100.0}, budget(t, ev), plan=Planned(points=120, runs=6))
    assert v.verdict == "not judged" and [c["result"] for c in v.checks] == ["not judged"]


def test_a_table_in_one_direction_is_judged_on_its_unidirectional_values_named_as_such():
    t = table()
    keep = t.direction > 0
    up = PointTable("linear", t.run[keep], t.direction[keep], t.target[keep], t.deviation[keep],
                    {k: v[keep] for k, v in t.optional.items()})
    ev = evaluate(up)
    v = judge(up, ev, {"A": 100.0}, budget(up, ev))
    assert v.verdict == "pass" and ev.summary.get("A") is None
    assert v.checks[0]["value"] == pytest.approx(ev.summary["A_up"], abs=1e-4)
    assert v.reasons[0].startswith("unidirectional accuracy A↑ (only the + direction was measured) = ")


def test_the_report_lists_every_tolerance_with_its_result(cli, tmp_path):
    from campaign.pointtable import write_points

    write_points(tmp_path / "p.csv", table())
    assert cli("report", tmp_path / "p.csv", "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    for name in ("accuracy A", "systematic deviation E", "reversal value B", "repeatability R"):
        assert f"<td>{name}</td>" in html
    assert html.count("not judged on") == 4  # a bare table has no tolerance, not even on A


def test_a_simulated_campaign_stays_marked_when_its_table_is_copied_out(cli, tmp_path):
    import shutil

    cfg = parse_config(SMALL, "small.toml")
    assert "sim" in (cfg.controller.type, cfg.instrument.type)
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine())
    shutil.copy(tmp_path / "c" / "points.csv", tmp_path / "copy.csv")
    assert json.loads(cli("analyze", tmp_path / "copy.csv", "--json").out)["simulated"] is True
    assert cli("report", tmp_path / "copy.csv", "-o", tmp_path / "r.html").code == 0
    assert "SIMULATED" in (tmp_path / "r.html").read_text()


def test_compensate_on_a_campaign_stopped_in_its_first_run_says_so_and_how_to_go_on(cli, tmp_path):
    from tests.conftest import assert_one_line_error

    cfg = parse_config(SMALL, "small.toml")
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    # move 7 is the second target on the way back in run 1: three targets +, one −
    start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(7))))
    result = cli("compensate", tmp_path / "c" / "points.csv", "--format", "csv", "-o", tmp_path / "t.csv")
    assert_one_line_error(result, "incomplete campaign (8 of 12 planned points are missing")
    assert f"axiscal resume {tmp_path / 'c'}" in result.err and not (tmp_path / "t.csv").exists()


def test_the_report_says_when_before_and_after_are_not_like_for_like(cli, tmp_path):
    cfg = parse_config(SMALL, "small.toml")
    start_campaign(cfg, tmp_path / "after", opener=FakeMachine())
    cfg = config_with(cfg, {"campaign": {"on_fault": "abort"}})
    start_campaign(cfg, tmp_path / "before", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(10))))
    assert cli("report", tmp_path / "after", "--before", tmp_path / "before", "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    assert "The before campaign is incomplete (" in html and "not like for like" in html
    assert "The after campaign is incomplete" not in html


def test_a_rotary_report_names_the_angle_uncertainty_it_used(cli, tmp_path):
    text = SMALL.replace("[axis]", "[axis]\nkind = \"rotary\"\nunit = \"deg\"").replace("soft_limit_max = 105.0",
                                                                                     "soft_limit_max = 360.0")
    cfg = parse_config(text, "rotary.toml")
    start_campaign(cfg, tmp_path / "r", opener=FakeMachine())
    assert cli("report", tmp_path / "r", "-o", tmp_path / "r.html").code == 0
    html = (tmp_path / "r.html").read_text()
    assert "<th>Angle uncertainty</th><td>not given: the budget uses 1 arcsec" in html
    assert "Length uncertainty" not in html and "µm/m" not in html.split("Angle uncertainty")[1][:200]


def test_report_of_a_bare_table_takes_a_tolerance_and_its_operator(cli, tmp_path):
    from campaign.pointtable import write_points

    t = table()
    t.meta["operator"] = "J. Smith"
    write_points(tmp_path / "p.csv", t)
    assert cli("report", tmp_path / "p.csv", "--tolerance", "100").code == 0  # default: beside the table
    html = (tmp_path / "p.html").read_text()
    assert "<span class='word'>PASS</span>" in html and "Operator: J. Smith." in html


def test_a_single_run_states_no_uncertainty_rather_than_a_smaller_one(cli, tmp_path):
    """One run has no scatter: every parameter's U rests on it, so none is stated (it was stated
    without the statistics terms, understated), and a tolerance gives 'not judged' naming why."""
    t = table(runs=1)
    ev = evaluate(t)
    b = budget(t, ev)
    assert b.expanded == {} and any("fewer than 2 runs" in m for m in b.missing)
    five = budget(table(), evaluate(table()))
    assert set(five.expanded) == {"A", "E", "B", "R"} and five.missing == ()
    v = judge(t, ev, {"A": 1000.0, "E": 1000.0}, b)  # A needs s; E has a value from one run
    assert v.verdict == "not judged" and [c["U"] for c in v.checks if c["parameter"] == "E"] == [None]
    assert any("no stated uncertainty" in r for r in v.reasons)
    rows = "".join(f"1,{'+' if d > 0 else '-'},{x:.3f},{e:.4f}\n" for d, x, e in zip(t.direction, t.target, t.deviation))
    (tmp_path / "one.csv").write_text("run,direction,target_mm,deviation_um\n" + rows)
    said = cli("analyze", tmp_path / "one.csv", "--tolerance", "1000", "--json")
    assert said.code == 0, said.err
    out = json.loads(said.out)
    assert "U_A_um" not in json.dumps(out) and "not judged" in json.dumps(out)


@pytest.mark.parametrize("purpose", ["follow-up", "diagnostic"])
def test_a_follow_up_or_diagnostic_gets_no_pass_or_fail(purpose: str) -> None:
    """[campaign] purpose: only acceptance and verification campaigns are judged."""
    t = table()
    ev = evaluate(t)
    unc = budget(t, ev)
    assert judge(t, ev, {"A": 1000.0}, unc, purpose="acceptance").verdict == "pass"
    v = judge(t, ev, {"A": 1000.0}, unc, purpose=purpose, follows="runs/first")
    assert v.verdict == "not judged"
    assert v.reasons[0] == f'not an acceptance test: a {purpose} of runs/first ([campaign] purpose = "{purpose}")'

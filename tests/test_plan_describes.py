"""plan.jsonl (plan format 2) describes the campaign: with config.toml deleted a directory still
replays and resumes; an older plan (format 1) still reads, with its config.toml (fast tier, on the
in-process fake axis and laser)."""

import json

import pytest

from campaign.config import config_with, parse_config
from campaign.errors import InputError
from campaign.measure.replay import replay
from campaign.measure.session import resume_campaign, start_campaign
from campaign.plan import PLAN_VERSION, Capture, build_plan
from campaign.pointtable import read_points
from campaign.record.directory import open_campaign, read_json_lines
from tests.fakes import SMALL, AxisFault, FakeMachine, linear_error_um

STABLE = 'method = "stable"\nstable_tolerance = 0.4\nstable_window_s = 0.5\n'
"""Appended to SMALL, which ends in its [capture] table."""


def interrupted(tmp_path, extra=""):
    """A campaign stopped by an axis fault at its 6th move (3 points recorded)."""
    cfg = config_with(parse_config(SMALL + extra, "small.toml"), {"campaign": {"on_fault": "abort"}})
    outcome = start_campaign(cfg, tmp_path / "c", opener=FakeMachine(setup=lambda p: p.axis.faults.append(AxisFault(6))))
    assert outcome.status == "interrupted" and outcome.points == 3
    return tmp_path / "c"


def deviations(directory):
    table = read_points(directory / "points.csv", partial=True)
    return {int(p): float(d) for p, d in zip(table.extra["point"], table.deviation)}


def to_format_1(directory):
    """Rewrite plan.jsonl as axiscal wrote it before plan format 2: no version, no config, no
    capture specs."""
    records = read_json_lines(directory / "plan.jsonl")
    for key in ("version", "config"):
        records[0].pop(key)
    for r in records[1:]:
        r.pop("capture", None)
    (directory / "plan.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))


def test_the_plan_records_the_config_and_each_capture_spec(tmp_path):
    d = interrupted(tmp_path, STABLE)
    records = read_json_lines(d / "plan.jsonl")
    assert records[0]["version"] == PLAN_VERSION == 2
    assert records[0]["config"] == json.loads((d / "meta.json").read_text())["config"]
    captures = [r for r in records if r.get("step") == "capture"]
    assert len(captures) == 12 and all(r["capture"]["method"] == "stable" for r in captures)
    assert {r["capture"]["stable_tolerance"] for r in captures} == {0.4}
    plan = open_campaign(d).recorded_plan()
    assert plan == build_plan(parse_config(SMALL + STABLE))  # the specs read back equal
    assert all(s.spec.stable_window_s == 0.5 for s in plan.steps if isinstance(s, Capture))


@pytest.mark.parametrize("extra", ["", STABLE])
def test_without_config_toml_a_campaign_resumes_and_replays(tmp_path, extra):
    d = interrupted(tmp_path, extra)
    (d / "config.toml").unlink()
    assert resume_campaign(d, opener=FakeMachine()).status == "completed"
    recorded = deviations(d)
    expected = {p.index: round(linear_error_um(p.target, p.direction), 4)
                for p in build_plan(parse_config(SMALL + extra)).points}
    assert recorded == pytest.approx(expected, abs=2e-4)  # the fake laser's quantisation
    capture, plan, points = replay(d)
    assert capture.method == ("stable" if extra else "dwell") and len(points) == len(plan.points) == 12
    assert {p.index: round(p.deviation, 4) for p in points} == recorded  # the same capture function


def test_a_format_1_plan_reads_with_its_config_toml_and_not_without(tmp_path):
    d = interrupted(tmp_path, STABLE)
    to_format_1(d)
    plan = open_campaign(d).plan_for(open_campaign(d).config())
    assert all(s.spec.method == "stable" for s in plan.steps if isinstance(s, Capture))  # from config.toml
    assert resume_campaign(d, opener=FakeMachine()).status == "completed"
    (d / "config.toml").unlink()
    with pytest.raises(InputError, match=r"no config.toml, and its plan.jsonl \(an older format\)"):
        replay(d)


def test_a_capture_spec_out_of_range_in_the_plan_is_refused_naming_the_line(tmp_path):
    d = interrupted(tmp_path)
    records = read_json_lines(d / "plan.jsonl")
    first = next(i for i, r in enumerate(records) if r.get("step") == "capture")
    records[first]["capture"]["average_s"] = -1.0
    (d / "plan.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    (d / "config.toml").unlink()
    with pytest.raises(InputError, match=rf"plan.jsonl: line {first + 1}: key 'capture.average_s'"):
        replay(d)


def baseline(tmp_path, extra=""):
    """A completed fake campaign, its config file and a compensation table made from it."""
    (tmp_path / "small.toml").write_text(SMALL + extra)
    cfg = parse_config(SMALL + extra, str(tmp_path / "small.toml"))
    assert start_campaign(cfg, tmp_path / "before", opener=FakeMachine()).status == "completed"
    return tmp_path / "before"


@pytest.mark.parametrize("broken, fragment", [
    ("format 1 plan, no config.toml", "not a baseline campaign"),
    ("no meta.json", "not a campaign directory (no meta.json)"),
    ("another axis", "the baseline measured axis 'X', the config measures axis 'Y'"),
    ("no points", "recorded no points.csv"),
])
def test_verify_refuses_a_baseline_that_is_not_one(cli, tmp_path, broken, fragment):
    from tests.conftest import assert_one_line_error

    before = baseline(tmp_path)
    assert cli("compensate", before / "points.csv", "--format", "json", "-o", tmp_path / "t.json").code == 0
    if broken == "format 1 plan, no config.toml":
        to_format_1(before)
        (before / "config.toml").unlink()
    elif broken == "no meta.json":
        (before / "meta.json").unlink()
    elif broken == "another axis":  # the baseline measured axis X
        (tmp_path / "y.toml").write_text(SMALL.replace("[axis]", '[axis]\nname = "Y"'))
    else:
        (before / "points.csv").unlink()
    config = tmp_path / ("y.toml" if broken == "another axis" else "small.toml")
    result = cli("verify", config, "--comp", tmp_path / "t.json", "--before", before, "--out", tmp_path / "after")
    assert_one_line_error(result, fragment)
    assert not (tmp_path / "after").exists()  # refused before anything was opened or recorded


def test_a_baseline_without_config_toml_is_valid_when_its_plan_describes_it(tmp_path):
    from campaign.measure.verify import baseline_points

    before = baseline(tmp_path)
    (before / "config.toml").unlink()
    table = baseline_points(before, parse_config(SMALL))
    assert len(table) == 12

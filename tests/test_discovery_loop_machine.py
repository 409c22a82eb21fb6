"""Issue 24's acceptance on the simulated machine: campaigns recorded with `axiscal run` (real pyads
against the loopback PLC, real pyserial over a pty), planned as users plan them (the shipped
horizontal config: 11 targets over 600 mm, golden offsets, 5 runs), then the follow-up campaign
`discover --follow-up` wrote, run on the same machine, and both fitted together. One seed each here;
the fast tier (tests/test_discovery_loop.py) runs more seeds on the fast simulator."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from campaign.cli import main
from campaign.commands.discover import read_tables
from tests.conftest import DATA, CliResult

BASE = (DATA / "configs" / "horizontal-sim.toml").read_text()
BOW = ("[effects.linear_scale]\nppm = -12.4\n[effects.nonlinear_lead]\np2_um = 0.49\np3_um = 0.73\n"
       "start_mm = 0.0\nend_mm = 600.0\n[effects.noise]\nsigma_um = 0.34\nreading_sigma_um = 0.05\n")


def first_campaign(cli, tmp_path, extra: str, seed: int, fixed_dwell: bool = False, count: int = 11):
    """Record the user's campaign on a machine with the bow and `extra`; returns its directory."""
    (tmp_path / "machine.toml").write_text(BOW + extra)
    config = re.sub(r'(?m)^model = .*$', f'model = "{tmp_path / "machine.toml"}"', BASE)
    config = re.sub(r"\[sim\]\nseed = \d+", f"[sim]\nseed = {seed}", config)
    config = config.replace("count = 11", f"count = {count}")
    if fixed_dwell:  # the ISO fixed-dwell test: every capture at the same wait
        config = config.replace('method = "stable"', 'method = "dwell"')
    (tmp_path / "c.toml").write_text(config)
    assert cli("run", tmp_path / "c.toml", "--out", tmp_path / "first").code == 0
    return tmp_path / "first"


def discover_json(cli, *args) -> dict:
    said = cli("discover", *map(str, args), "--json")
    assert said.code == 0, said.err
    return json.loads(said.out)


def the_loop(cli, tmp_path, first) -> tuple[dict, dict]:
    """discover --follow-up on the first campaign, run the follow-up (each of its campaigns: the first
    in second/, any other in second-2/, ...), discover them all together (a scan's dense profile.csv
    with the first table)."""
    alone = discover_json(cli, first / "points.csv", "--follow-up", "-o", tmp_path / "follow.toml")
    assert alone["follow_up"] and alone["follow_up"]["campaigns"], (alone["unresolved"], alone["follow_up"])
    tables = []
    for i, campaign in enumerate(alone["follow_up"]["campaigns"]):
        out = tmp_path / ("second" if i == 0 else f"second-{i + 1}")
        assert cli("plan", campaign["file"]).code == 0  # within the axis's limits
        assert cli("run", campaign["file"], "--out", out).code == 0
        tables.append(out / ("profile.csv" if campaign["capture"] == "scan" else "points.csv"))
    return alone, discover_json(cli, first / "points.csv", *tables)


def follow_up_machine_time_s(tmp_path) -> float:
    """The campaign time recorded by all the follow-up's campaigns together, s."""
    return sum(machine_time_s(d) for d in tmp_path.glob("second*"))


def machine_time_s(directory) -> float:
    """The campaign time the recorder stamped on the campaign's last event, s."""
    return float(json.loads((directory / "events.jsonl").read_text().splitlines()[-1])["t_s"])


# A fixed-dwell first campaign with backlash or settling alone, followed up, is tested on the fast simulator
# (tests/test_discovery_loop.py::test_the_follow_up_tells_backlash_from_settling, two seeds each); on this
# machine both reversals are followed up beside an aliased lead (the last test here). Its own machine run
# (about 14 s of CPU) was left out on 2026-11-28 to keep the suite under 10 minutes.


@pytest.mark.machine
@pytest.mark.parametrize("seed", [4])  # 5 and 6 too by hand: about 50 s each, the suite keeps under 10 min
def test_the_follow_up_scans_a_10_mm_lead(cli, tmp_path, seed):
    """Issue 33 item 4: the follow-up of an aliased lead on the simulated PLC (which streams its
    position) is a slow scan over the period cluster, at most a quarter of the first campaign's
    machine time (the estimate and the time recorded); its profile fitted with the first table
    names the lead, period within 1 %, nothing unresolved, nothing the machine lacks and no region
    left after the fit (each table weighed by its own uncertainty, each sweep its own offset and slope).
    Not seed 2: its follow-up runs on noise seed 3, whose reading noise holds six draws in a row at
    −1.9 to −2.6σ, −2.3σ on average (numpy's stream for [3, 2] from draw 20451), a 12 ms dip of −0.12 µm in one sweep at
    294.5 mm that the locator rightly leaves as one bin's departure, about 6σ of that bin."""
    first = first_campaign(cli, tmp_path, "[effects.periodic_lead]\namplitude_um = 1.0\nperiod_mm = 10.0\n"
                                          "phase_rad = 0.3\n", seed=seed)
    alone, both = the_loop(cli, tmp_path, first)
    assert any("periodic_lead" in u["effects"] for u in alone["unresolved"]), alone["unresolved"]
    follow = alone["follow_up"]
    assert follow["capture"] == "scan", follow["parts"]
    assert 4 * follow["duration_s"] <= follow["first_duration_s"], follow
    assert 4 * follow_up_machine_time_s(tmp_path) <= machine_time_s(first)
    assert "periodic_lead" in both["added"] and not both["unresolved"], (both["added"], both["unresolved"])
    assert both["model"]["periodic_lead"]["period_mm"] == pytest.approx(10.0, rel=0.01)
    # nothing the machine lacks (issue 34): the lead, its bow and scale alone; nothing left located
    assert set(both["added"]) <= {"periodic_lead", "nonlinear_lead", "linear_scale"}, both["added"]
    assert not both["located"]["after"]["regions"], both["located"]["after"]["regions"]
    assert not both["local_errors"], both["local_errors"]
    # before naming, the lead is located where it was measured, and nothing past the scan's end where the
    # curve ran on alone (a bump of -3.3 µm peaking 6.8 mm past it, where nothing was measured)
    data = read_tables([str(first / "points.csv"), str(tmp_path / "second" / "profile.csv")])[0]
    scanned = data.x[data.campaign_index == 1]
    targets = np.unique(data.x[data.campaign_index == 0])
    knot = float(np.ptp(data.x)) / 147  # the position curve's knot spacing (MAX_BASIS basis functions)
    gaps = [(float(targets[targets < scanned.min()].max(initial=data.x.min())) + 2 * knot, scanned.min() - 0.4),
            (scanned.max() + 0.4, float(targets[targets > scanned.max()].min(initial=data.x.max())) - 2 * knot)]
    for region in both["located"]["before"]["regions"]:
        assert region["over"] != "position" or not any(lo < region["peak_at"] < hi for lo, hi in gaps), region


BUMP = "[effects.local_defect]\namplitude_um = 3.0\ncentre_mm = 250.0\nwidth_mm = 100.0\n"


@pytest.fixture(scope="module")
def bump_first(tmp_path_factory):
    """The 21-target campaign (30 mm apart) with a +3 µm bump 100 mm wide at 250 mm, recorded once for
    the two tests that read it (one xdist group: one worker records it)."""

    def quiet(*args: str) -> CliResult:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([str(a) for a in args])
        return CliResult(code, out.getvalue(), err.getvalue())

    return first_campaign(quiet, tmp_path_factory.mktemp("bump"), BUMP, seed=3, count=21)


@pytest.mark.machine
@pytest.mark.xdist_group("bump_first")
def test_a_local_bump_outside_the_vocabulary(cli, bump_first):
    """21 targets (30 mm apart), a +3 µm bump 100 mm wide at 250 mm: located within its width, the
    gap shrinks to the noise, nothing named for it, said as what it is."""
    first = bump_first
    found = discover_json(cli, first / "points.csv")
    local = found["local"]
    assert local is not None and abs(local["params"]["centre_mm"] - 250.0) <= 100.0
    assert set(found["added"]) <= {"nonlinear_lead"} and not found["unresolved"]
    assert found["gap_after_um"] <= 1.3 * found["noise_um"] < local["gap_without_um"]
    text = cli("discover", first / "points.csv").out
    assert "no effect of the model has this shape" in " ".join(text.split())


@pytest.mark.machine
@pytest.mark.xdist_group("bump_first")
def test_the_follow_up_measures_a_located_local_error_densely(cli, tmp_path, bump_first):
    """Issue 34 item 6: a located local error gets denser targets over its region (not beside it),
    within the first campaign's machine time; fitted together, it is located within its width,
    nothing is named for it and nothing is unresolved."""
    alone, both = the_loop(cli, tmp_path, bump_first)
    follow = alone["follow_up"]
    assert follow["duration_s"] <= follow["first_duration_s"]
    regions = [z["region_mm"] for z in alone["zones"]]
    assert any(low <= 250.0 <= high for low, high in regions), regions
    inside = [t for t in follow["targets"] if any(low - 10 <= t <= high + 10 for low, high in regions)]
    assert len(inside) == len(follow["targets"]) > 8, (regions, follow["targets"])
    assert both["local"] is not None and abs(both["local"]["params"]["centre_mm"] - 250.0) <= 50.0
    assert set(both["added"]) <= {"nonlinear_lead"} and not both["unresolved"], both["added"]
    assert both["gap_after_um"] <= 1.3 * both["noise_um"]


@pytest.mark.machine
@pytest.mark.parametrize("truth, extra", [("backlash", "[effects.backlash]\nb_um = 1.5\n"),
                                          ("settling", "[effects.settling]\ne0_um = 3.0\ntau_s = 2.0\n")])
def test_the_follow_up_of_a_reversal_and_an_aliased_lead(cli, tmp_path, truth, extra):
    """Issue 34 item 6's Done-when on the shipped config: backlash or settling (not told apart at the
    first campaign's constant wait) beside an aliased 10 mm lead and the bow. The follow-up's parts
    keep their own cycles and waits (the wait ladder a campaign of its own, the cluster scanned
    once: the joint fit keeps the ladder's waits beside a profile), so together they take at most
    half the first campaign's machine time, estimated and recorded (the cluster stopped at, about
    0.5 and 0.9 of it); fitted with the first campaign, the truth is named and nothing is
    unresolved. Seed 31 was not looked at while the planner was written."""
    lead = "[effects.periodic_lead]\namplitude_um = 1.0\nperiod_mm = 10.0\nphase_rad = 0.3\n"
    first = first_campaign(cli, tmp_path, extra + lead, seed=31)
    alone, both = the_loop(cli, tmp_path, first)
    groups = [set(u["effects"]) for u in alone["unresolved"]]
    assert {"backlash", "settling"} in groups and any("periodic_lead" in g for g in groups), groups
    follow = alone["follow_up"]
    assert not follow["unplanned"] and len(follow["campaigns"]) >= 2, follow
    assert "scan" in [c["capture"] for c in follow["campaigns"]], follow
    # each campaign of the follow-up on noise of its own: none draws the first's scatter, nor each other's
    seeds = [int(re.search(r"\[sim\]\nseed = (\d+)", Path(c["file"]).read_text()).group(1)) for c in follow["campaigns"]]
    assert len(set(seeds)) == len(seeds) and 31 not in seeds, seeds
    assert 2 * follow["duration_s"] <= follow["first_duration_s"], follow
    assert 2 * follow_up_machine_time_s(tmp_path) <= machine_time_s(first)
    assert {truth, "periodic_lead"} <= set(both["added"]) and not both["unresolved"], (both["added"],
                                                                                       both["unresolved"])
    assert set(both["added"]) <= {truth, "periodic_lead", "nonlinear_lead", "linear_scale"}, both["added"]
    assert both["model"]["periodic_lead"]["period_mm"] == pytest.approx(10.0, rel=0.01)


@pytest.mark.machine
def test_a_follow_up_of_a_machine_given_by_a_relative_model_path_runs(cli, tmp_path):
    """The shipped configs name their model relative to the config. The follow-up, written from the
    campaign directory's config.toml, named that path from the campaign directory, where the file is
    not (a new user's trial: "error model ... is missing", an empty campaign); it now names the model
    the campaign kept (sim-model.toml). Its noise seed is the next one: with the first's, the k-th
    approach drew the same scatter in both campaigns, and the two tables were not independent."""
    (tmp_path / "cases").mkdir()
    (tmp_path / "cases" / "machine.toml").write_text(BOW + "[effects.backlash]\nb_um = 3.0\n")
    config = re.sub(r'(?m)^model = .*$', 'model = "machine.toml"', BASE).replace('method = "stable"', 'method = "dwell"')
    (tmp_path / "cases" / "c.toml").write_text(config)
    assert cli("run", tmp_path / "cases" / "c.toml", "--out", tmp_path / "runs" / "first").code == 0
    (tmp_path / "next").mkdir()
    follow = discover_json(cli, tmp_path / "runs" / "first" / "points.csv", "--follow-up", "-o",
                           tmp_path / "next" / "f.toml")["follow_up"]
    assert follow and follow["campaigns"]
    written = (tmp_path / "next" / "f.toml").read_text()
    assert 'model = "../runs/first/sim-model.toml"' in written
    seed = int(re.search(r"\[sim\]\nseed = (\d+)", BASE).group(1))
    assert int(re.search(r"\[sim\]\nseed = (\d+)", written).group(1)) == seed + 1
    assert cli("run", tmp_path / "next" / "f.toml", "--out", tmp_path / "runs" / "second").code == 0
    assert machine_time_s(tmp_path / "runs" / "second") > 0

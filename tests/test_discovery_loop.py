"""Issue 24, items 2 to 4 and the bow left from issue 26, in the fast tier (the fast simulator, tables
written as the recorder writes them): several campaigns fitted together, the follow-up campaign
discover writes, an error outside the vocabulary, and the bow beside an unresolved period. The
acceptance on the simulated machine is tests/test_discovery_loop_machine.py."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from campaign.config import load_config, parse_config
from campaign.discovery.data import campaign_data, join_campaigns
from campaign.discovery.effects import FORMS
from campaign.discovery.local import zones
from campaign.discovery.records import Unresolved
from campaign.discovery.search import discover
from campaign.discovery.simulate import simulate_campaign
from campaign.model import EFFECT_PARAMS, ErrorModel
from campaign.pointtable import write_points
from tests.conftest import DATA, sweep
from tests.test_discovery_period import RECORDED

USER = (DATA / "configs" / "horizontal-sim.toml").read_text()
"""The shipped horizontal config: 11 targets over 600 mm, golden offsets, 5 runs."""
BOW = {"linear_scale": {"ppm": -12.4},
       "nonlinear_lead": {"p2_um": 0.49, "p3_um": 0.73, "start_mm": 0.0, "end_mm": 600.0},
       "noise": {"sigma_um": 0.34, "reading_sigma_um": 0.05}}
BUMP = {"amplitude_um": 3.0, "centre_mm": 250.0, "width_mm": 100.0, "direction": 0.0}


def user_config(count: int = 11, seed: int = 3):
    """The shipped config with a fixed dwell (the fast simulator models the dwell capture)."""
    text = USER.replace("count = 11", f"count = {count}").replace('method = "stable"', 'method = "dwell"')
    return parse_config(re.sub(r"(\[plan\][^\[]*?)seed = \d+", lambda m: m.group(1) + f"seed = {seed}", text,
                               flags=re.DOTALL))


def found(config, machine: dict, seed: int, **kwargs):
    table = simulate_campaign(config, ErrorModel(machine), seed=seed, **kwargs)
    return discover(campaign_data(table), ErrorModel({"linear_scale": {}}), {"linear_scale": set()})


def test_the_simulators_bump_is_not_in_the_vocabulary():
    """The two lists are kept apart on purpose: the simulated machine can make an error that
    discovery has no name for."""
    assert "local_defect" in EFFECT_PARAMS and "local_defect" not in FORMS


@pytest.mark.machine
@pytest.mark.parametrize("seed", sweep(1, 2, 3))
def test_a_local_bump_is_located_and_nothing_soaks_it_up(seed):
    """21 targets (30 mm apart), a +3 µm bump 100 mm wide at 250 mm (three targets see it at half its height or more) beside the bow: located within
    its width, the gap shrinks to the noise, no vocabulary effect named for it."""
    result = found(user_config(count=21), {**BOW, "local_defect": BUMP}, seed)
    assert result.local is not None, result.notes
    # a bump, or a step up and one down (a raised zone: the raised cosine's flat top follows two steps)
    [zone] = [z for z in zones(result.local_errors) if z.region_mm[0] <= 250.0 <= z.region_mm[1]]
    assert abs(zone.centre_mm - 250.0) <= 100.0 and 50.0 <= zone.region_mm[1] - zone.region_mm[0] <= 400.0
    assert zone.size_um == pytest.approx(3.0, abs=0.6) and all(e.directions == "both" for e in zone.members)
    assert set(result.added) <= {"nonlinear_lead"} and not result.unresolved
    assert result.gap_after_um <= 1.3 * result.noise_um < result.local.gap_without_um
    assert "no effect of the model" not in result.local.sentence()  # the command adds that
    if result.local.kind == "bump":
        assert re.fullmatch(r"a local error of \+\d\.?\d* µm at \d+\.?\d* mm, width \d+\.?\d* mm, both directions",
                            result.local.sentence())


@pytest.mark.machine
def test_a_bump_in_one_direction_says_so():
    result = found(user_config(count=21), {**BOW, "local_defect": {**BUMP, "direction": -1.0}}, 2)
    assert result.local is not None and result.local.directions == "-"
    assert "seen in the − direction; in the + direction below 3σ (" in result.local.sentence()
    assert "only" not in result.local.sentence()  # what was seen, not more
    time = result.local.time_text()
    assert re.fullmatch(r"no change with time detected \([+-]\S+ ± \S+ µm over the campaign, F-test p = \S+\)", time)
    assert "backlash" not in result.added and "position_dependent_backlash" not in result.added


@pytest.mark.machine
@pytest.mark.parametrize("seed", sweep(1, *range(2, 9)))
def test_no_local_error_where_there_is_none(seed):
    """The null case: the bow alone, 11 and 21 targets; the local search adds nothing."""
    for count in (11, 21):
        assert found(user_config(count=count), BOW, seed).local is None


@pytest.mark.machine
def test_a_start_model_with_the_simulators_bump(cli, tmp_path):
    table = simulate_campaign(user_config(count=21), ErrorModel({**BOW, "local_defect": BUMP}), seed=1)
    write_points(tmp_path / "p.csv", table)
    (tmp_path / "half.toml").write_text("[effects.linear_scale]\n[effects.local_defect]\namplitude_um = 3.0\n")
    said = cli("discover", tmp_path / "p.csv", "--model", tmp_path / "half.toml")
    assert said.code == 2 and said.err.startswith("error:") and "local_defect" in said.err
    whole = "".join(f"{k} = {v!r}\n" for k, v in BUMP.items())
    (tmp_path / "whole.toml").write_text(f"[effects.linear_scale]\n[effects.local_defect]\n{whole}")
    held = json.loads(cli("discover", tmp_path / "p.csv", "--model", tmp_path / "whole.toml", "--json").out)
    assert held["local"] is None and held["gap_after_um"] <= 1.3 * held["noise_um"]


@pytest.mark.parametrize("seed", sweep(1, 2, 3))
@pytest.mark.machine  # about a second in all: the fast tier stays under a minute
def test_the_bow_beside_an_unresolved_period_is_not_biased(seed):
    """A 1 µm, 10 mm lead at 11 targets stays unresolved; the bow fitted without it took the wave's
    values at the targets: P3 came out 0.30 to 0.44 µm low on these seeds (true 0.73 µm) with the
    old code. Averaged over the candidate periods it is within 0.15 µm, and both within 3 reported σ."""
    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    result = found(user_config(seed=seed), {**BOW, **lead}, seed)
    assert [u.effects for u in result.unresolved] == [("periodic_lead",)]
    bow, error = result.params()["nonlinear_lead"], result.errors["nonlinear_lead"]
    for key, true in (("p2_um", 0.49), ("p3_um", 0.73)):
        assert abs(bow[key] - true) < 3 * error[key], (key, bow, error)
    assert abs(bow["p3_um"] - 0.73) < 0.15, bow
    assert "periodic_lead" not in result.params()  # nothing added for the period itself


@pytest.mark.machine
def test_campaigns_fitted_together_share_effects_and_each_has_its_offset(cli, tmp_path):
    config = user_config()
    machine = {**BOW, "backlash": {"b_um": 2.0}}
    first = simulate_campaign(config, ErrorModel(machine), seed=1)
    second = simulate_campaign(config, ErrorModel(machine), seed=2)
    second.deviation = second.deviation + 5.0  # a new laser datum
    write_points(tmp_path / "a.csv", first)
    write_points(tmp_path / "b.csv", second)
    out = json.loads(cli("discover", tmp_path / "a.csv", tmp_path / "b.csv", "--json").out)
    assert out["campaigns"] == [str(tmp_path / "a.csv"), str(tmp_path / "b.csv")]
    assert out["offsets_um"][1] - out["offsets_um"][0] == pytest.approx(5.0, abs=0.2)
    assert out["gap_after_um"] <= 1.3 * out["noise_um"]
    assert [set(t) for t in out["tables"]] == [{"gap_um", "noise_um"}] * 2  # each table's own, its points alone
    assert all(t["gap_um"] <= 1.3 * t["noise_um"] for t in out["tables"])
    assert len(out["disagreement_after"]["by_run"]) == 10  # runs numbered on: 1-5, then 6-10
    data = join_campaigns([campaign_data(first), campaign_data(second)], ["a", "b"])
    assert data.campaigns == 2 and float(np.nanmax(data.t)) < 1.01 * float(np.nanmax(campaign_data(first).t))


def test_campaigns_with_and_without_a_time_column_are_refused(cli, tmp_path):
    table = simulate_campaign(user_config(), ErrorModel(BOW), seed=1)
    write_points(tmp_path / "a.csv", table)
    lines = (tmp_path / "a.csv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("run,"))
    names = lines[header].split(",")
    keep = [i for i, n in enumerate(names) if n != "time_s"]
    cut = lines[:header] + [",".join(line.split(",")[i] for i in keep) for line in lines[header:]]
    (tmp_path / "b.csv").write_text("\n".join(cut) + "\n")
    said = cli("discover", tmp_path / "a.csv", tmp_path / "b.csv")
    assert said.code == 2 and said.err.startswith("error:") and len(said.err.strip().splitlines()) == 1


@pytest.mark.machine
@pytest.mark.parametrize("seed", sweep(1, 2, 3))
def test_the_period_cluster_is_sized_on_the_wave_the_data_show(seed):
    """A 3 µm wave over half the travel at 17 targets: the period is unresolved and the final model
    holds its best candidate without a name (HELD_PREFIX; before, the reversal's stand-in kept it as
    periodic_lead, and the unresolved period was saved with the model). The follow-up sizes its cluster
    on the amplitude of each candidate's sine beside the rest of the model; fitted beside the held sine
    too, two sines at one period fought and it came out at 140-2,000 µm (a scenario reviewer saw 160 µm)."""
    from dataclasses import replace

    from campaign.discovery.effects import HELD_PREFIX
    from campaign.discovery.fit import linear_fit
    from campaign.discovery.followup import _amplitude

    wave = {"partial_wave": {"amplitude_um": 3.0, "period_mm": 60.0, "phase_rad": 0.3, "start_mm": 300.0,
                             "end_mm": 600.0}, "backlash": {"b_um": 1.5}}
    data = campaign_data(simulate_campaign(user_config(count=17, seed=seed), ErrorModel({**BOW, **wave}), seed=seed))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    held_name = HELD_PREFIX + "periodic_lead"
    assert any(t.name == held_name for t in result.final.terms)  # the case: a candidate is held
    assert "periodic_lead" not in result.final_model().effects  # unresolved: never saved
    periods = next(u.periods_mm for u in result.unresolved if u.periods_mm)
    amplitudes = [_amplitude(data, result.final, p) for p in periods[:3]]
    assert all(0.75 < a < 3.0 for a in amplitudes), amplitudes
    # the same sine in the model under its own name is left out as well
    named = linear_fit(data, [replace(t, name="periodic_lead") if t.name == held_name else t
                              for t in result.final.terms])
    assert [_amplitude(data, named, p) for p in periods[:3]] == pytest.approx(amplitudes, rel=1e-6)


def written_follow_up(cli, tmp_path, config_text: str, machine: dict, seed: int = 1):
    """A first campaign from `config_text` on the fast simulator, recorded beside its config; then
    discover --follow-up. Returns (the first table's path, its config, discover's JSON)."""
    directory = tmp_path / "first"
    directory.mkdir()
    (directory / "config.toml").write_text(config_text)
    config = load_config(directory / "config.toml")
    write_points(directory / "points.csv", simulate_campaign(config, ErrorModel(machine), seed=seed))
    said = cli("discover", directory / "points.csv", "--follow-up", "-o", tmp_path / "follow.toml", "--json")
    assert said.code == 0, said.err
    return directory / "points.csv", config, json.loads(said.out)


@pytest.mark.machine
@pytest.mark.parametrize("seed", sweep(1, 2))
@pytest.mark.parametrize("truth", ["backlash", "settling"])
def test_the_follow_up_tells_backlash_from_settling(cli, tmp_path, truth, seed):
    """A fixed-dwell first campaign (the ISO test) with a reversal: backlash or settling, cannot tell;
    the follow-up discover writes (waits over a decade), simulated and fitted with the first,
    names the true one and leaves nothing unresolved, in less machine time than the first."""
    effect = {"backlash": {"backlash": {"b_um": 1.5}}, "settling": {"settling": {"e0_um": 3.0, "tau_s": 2.0}}}[truth]
    text = user_config().text.replace('method = "stable"', 'method = "dwell"')
    first, _, out = written_follow_up(cli, tmp_path, text, {**BOW, **effect}, seed)
    assert any(set(u["effects"]) == {"backlash", "settling"} for u in out["unresolved"])
    follow = out["follow_up"]
    assert follow["capture"] == "dwell" and follow["duration_s"] <= follow["first_duration_s"]
    assert any("decade" in p["why"] for p in follow["parts"])
    assert cli("plan", tmp_path / "follow.toml").code == 0
    config = load_config(tmp_path / "follow.toml")
    assert config.plan.dwell_s * (1 + config.plan.dwell_jitter) >= 10 * config.plan.dwell_s * (
        1 - config.plan.dwell_jitter) * 0.99
    second = simulate_campaign(config, ErrorModel({**BOW, **effect}), seed=seed + 100,
                               dwell_jitter=config.plan.dwell_jitter)
    write_points(tmp_path / "second.csv", second)
    both = json.loads(cli("discover", first, tmp_path / "second.csv", "--json").out)
    assert truth in both["added"] and not both["unresolved"], (both["added"], both["unresolved"])
    assert set(both["added"]) <= {truth, "nonlinear_lead"}


@pytest.mark.machine
@pytest.mark.parametrize("seed", sweep(1, 2))
def test_the_follow_up_pins_an_aliased_period(cli, tmp_path, seed):
    """A 10 mm lead at 11 targets on a controller that does not stream its position (LinuxCNC): periods
    fit alike; the follow-up is a stop-and-go cluster of targets at most a quarter of the shortest
    candidate apart, shorter than the first campaign; fitted together, the period is named within 2 %.
    (On a streaming controller it is a scan: tests/test_discovery_loop_machine.py.)"""
    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    text = user_config(seed=seed).text.replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "linuxcnc"')
    first, _, out = written_follow_up(cli, tmp_path, text, {**BOW, **lead}, seed)
    candidates = next(u["periods_mm"] for u in out["unresolved"] if u["effects"] == ["periodic_lead"])
    follow = out["follow_up"]
    assert follow["capture"] == "dwell" and follow["duration_s"] <= follow["first_duration_s"]
    assert any("not a scan" in p["why"] and "linuxcnc" in p["why"] for p in follow["parts"])
    config = load_config(tmp_path / "follow.toml")
    from campaign.plan import build_plan

    targets = np.array(build_plan(config).targets)
    # the cluster (a local error that fits as well beside the period gets its own dense targets, issue 34)
    runs = np.split(targets, np.flatnonzero(np.diff(targets) > min(candidates) / 4) + 1)
    assert max(np.ptp(run) for run in runs) >= 2 * 10.0, runs
    second = simulate_campaign(config, ErrorModel({**BOW, **lead}), seed=seed + 100)
    write_points(tmp_path / "second.csv", second)
    both = json.loads(cli("discover", first, tmp_path / "second.csv", "--json").out)
    assert "periodic_lead" in both["added"] and not both["unresolved"]
    assert both["model"]["periodic_lead"]["period_mm"] == pytest.approx(10.0, rel=0.02)


@pytest.mark.parametrize("controller", ["sim", "ads", "linuxcnc", "epics"])
def test_the_scan_planning_rule(tmp_path, controller):
    """The planning rule alone (no discovery): an aliased period's follow-up is a scan over the
    cluster on a controller that streams its position (ADS, the simulated PLC), at the speed of
    followup.scan_speed, within a quarter of the first campaign's machine time; on one that does
    not it is the stop-and-go cluster, and the why says so; merged with a part that stops, it stops;
    beside a wait ladder (a campaign of its own) it is still scanned."""
    from campaign.discovery.fit import linear_fit
    from campaign.discovery.followup import SCAN_SAMPLES_PER_PERIOD, plan_follow_up
    from campaign.plan import EXPECTED_TIMING_U_S

    text = user_config().text.replace('[axis_driver]\ntype = "sim"', f'[axis_driver]\ntype = "{controller}"')
    if controller == "ads":
        text = text.replace("[axis_driver]", '[axis_driver]\nams_net_id = "127.0.0.1.1.1"').replace(
            '[instrument]\ntype = "sim"', '[instrument]\ntype = "serial"\nport = "/dev/ttyUSB0"')
    config = parse_config(text, str(tmp_path / "first" / "config.toml"))
    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    data = campaign_data(simulate_campaign(config, ErrorModel({**BOW, **lead}), seed=1))
    group = Unresolved(("periodic_lead",), "aliased", "more targets", periods_mm=(10.0, 15.9, 4.4),
                       period_delta_bic=(0.0, 1.0, 2.0))
    follow = plan_follow_up([group], [], data, linear_fit(data, []), config, None, 0.34, tmp_path / "f.toml",
                            ["first/points.csv"])
    assert follow is not None and [p.effects for p in follow.parts] == [["periodic_lead"]]
    capture, why = follow.config.capture, follow.parts[0].why
    if controller in ("sim", "ads"):
        rate, speed = follow.config.instrument.rate_hz, capture.scan_velocity
        assert capture.method == "scan" and follow.config.plan.cycles == 1 and speed is not None
        assert 4 * follow.duration_s <= follow.first_duration_s
        by_samples = rate * 4.4 / SCAN_SAMPLES_PER_PERIOD
        by_timing = capture.scan_wanted_u / (EXPECTED_TIMING_U_S * 1000)
        assert 0.9 * min(by_samples, by_timing, config.axis.max_velocity) <= speed <= min(by_samples, by_timing)
        targets = follow.config.plan.targets or []
        assert targets[-1] - targets[0] >= 3 * 15.9 * 0.99  # the cluster's span
        assert "NEW/profile.csv" in follow.text and "scanned" in why
        stopping = Unresolved(("backlash", "settling"), "a reversal", "vary the wait")
        merged = plan_follow_up([group, stopping], [], data, linear_fit(data, []), config, 1.5, 0.34,
                                tmp_path / "f.toml", ["first/points.csv"])
        # the wait ladder is a campaign of its own (its waits and cycles), the cluster another, scanned
        # once as alone: the joint fit counts a profile's bins as settled and keeps the ladder's waits
        assert merged is not None and len(merged.campaigns) == 2
        ladder, cluster = sorted(merged.campaigns, key=lambda c: c.config.capture.method == "scan")
        assert [p.effects for p in ladder.parts] == [["backlash", "settling"]] and ladder.config.plan.dwell_jitter > 0
        assert [p.effects for p in cluster.parts] == [["periodic_lead"]] and cluster.config.plan.cycles == 1
        assert cluster.config.capture.method == "scan" and "not a scan" not in cluster.parts[0].why
        assert cluster.duration_s == pytest.approx(follow.duration_s)
        assert merged.duration_s == pytest.approx(ladder.duration_s + cluster.duration_s)
        assert ladder.path == tmp_path / "f.toml" or cluster.path == tmp_path / "f.toml"
        alone_region = plan_follow_up([group], [], data, linear_fit(data, []), config, None, 0.34,
                                      tmp_path / "f.toml", ["first/points.csv"], [(240.0, 260.0)])
        assert alone_region is not None and alone_region.config.capture.method == "dwell"  # a local error of its own
        assert any("one capture method" in p.why for p in alone_region.parts)
    else:
        assert capture.method == "dwell" and "NEW/points.csv" in follow.text
        assert f'not a scan: axis_driver.type = "{controller}" does not stream its actual position' in why


@pytest.mark.machine
@pytest.mark.parametrize("seed", [1, 2])
def test_an_aliased_period_is_followed_up_by_a_slow_scan(cli, tmp_path, seed):
    """Issue 33 item 4: on a controller that streams its position (the simulated PLC), the follow-up
    of an aliased 10 mm lead is a scan over the cluster's span: its laser rate, its speed from the
    rules of followup.scan_speed (samples per shortest candidate period, the timing within
    capture.scan_wanted_u, the axis), at most a quarter of the first campaign's machine time; its
    header says to fit its profile.csv. On LinuxCNC the same draw keeps the stops and says why."""
    from campaign.discovery.followup import SCAN_SAMPLES_PER_PERIOD
    from campaign.plan import EXPECTED_TIMING_U_S

    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    first, config, out = written_follow_up(cli, tmp_path, user_config(seed=seed).text, {**BOW, **lead}, seed)
    candidates = next(u["periods_mm"] for u in out["unresolved"] if u["effects"] == ["periodic_lead"])
    follow = out["follow_up"]
    assert follow["capture"] == "scan", follow["parts"]
    assert 4 * follow["duration_s"] <= follow["first_duration_s"], follow
    scan = load_config(tmp_path / "follow.toml")
    assert scan.campaign.purpose == "follow-up" and scan.plan.cycles == 1
    rate, speed = scan.instrument.rate_hz, scan.capture.scan_velocity
    assert rate >= config.instrument.rate_hz and speed == follow["scan_velocity"]
    assert rate * min(candidates) / speed >= SCAN_SAMPLES_PER_PERIOD
    assert speed * EXPECTED_TIMING_U_S * 1000 <= scan.capture.scan_wanted_u * 1.0001
    assert speed <= scan.axis.max_velocity and speed >= 0.5 * min(  # not needlessly slow
        rate * min(candidates) / SCAN_SAMPLES_PER_PERIOD, scan.capture.scan_wanted_u / (EXPECTED_TIMING_U_S * 1000))
    assert max(follow["targets"]) - min(follow["targets"]) >= 2 * max(candidates)  # over the cluster
    assert cli("plan", tmp_path / "follow.toml").code == 0
    assert "NEW/profile.csv" in (tmp_path / "follow.toml").read_text()
    said = cli("discover", first, "--follow-up", "-o", tmp_path / "f2.toml")
    assert "sweeps" in said.out and "profile.csv" in " ".join(said.out.split())
    # a controller that does not stream its position: the stops, and why
    stopped = tmp_path / "linuxcnc"
    stopped.mkdir()
    text = user_config(seed=seed).text.replace('[axis_driver]\ntype = "sim"', '[axis_driver]\ntype = "linuxcnc"')
    _, _, out = written_follow_up(cli, stopped, text, {**BOW, **lead}, seed)
    follow = out["follow_up"]
    assert follow["capture"] == "dwell" and follow["scan_velocity"] is None
    why = " ".join(p["why"] for p in follow["parts"])
    assert "not a scan" in why and 'axis_driver.type = "linuxcnc"' in why and "stream" in why


@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_the_follow_up_stays_within_the_limits_and_says_why(cli, tmp_path):
    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    text = user_config().text.replace("soft_limit_max = 610.0", "soft_limit_max = 601.5")
    _, config, _ = written_follow_up(cli, tmp_path, text, {**BOW, **lead})
    said = (tmp_path / "follow.toml").read_text()
    assert said.startswith("# Follow-up campaign") and "Machine time (estimate)" in said
    followed = load_config(tmp_path / "follow.toml")
    assert followed.axis == config.axis and cli("plan", tmp_path / "follow.toml").code == 0


@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_nothing_unresolved_writes_no_follow_up(cli, tmp_path):
    _, _, out = written_follow_up(cli, tmp_path, user_config().text, BOW)
    assert out["follow_up"] is None and not (tmp_path / "follow.toml").exists()


@pytest.mark.parametrize("args, fragment", [
    (["--follow-up"], "-o"),
    (["-o", "x.toml"], "--follow-up"),
    (["--follow-up", "-o", "x.json"], ".toml"),
    (["--follow-up", "-o", "x.toml", "--config", "nope.toml"], "nope.toml"),
])
def test_follow_up_options_are_checked(cli, tmp_path, args, fragment):
    table = simulate_campaign(user_config(), ErrorModel(BOW), seed=1)
    write_points(tmp_path / "p.csv", table)
    said = cli("discover", tmp_path / "p.csv", *args)
    assert said.code == 2 and said.err.startswith("error:") and fragment in said.err


FIVE_TARGETS = ("run,direction,target_mm,deviation_um,time_s,capture_wait_s,samples\n"
                "1,+,152.579827,-2.3188,25.9,3.3,2\n"
                "1,+,290.237031,-4.4211,46,2.8,2\n"
                "1,+,457.702636,-6.5805,68.3,1.3,2\n"
                "1,+,595.358840,-6.8706,89.8,4.2,2\n"
                "1,-,595.358840,-5.3515,91.8,0.6,2\n"
                "1,-,457.702636,-5.0399,110,0.9,2\n"
                "1,-,290.237031,-3.2488,133.5,2.5,2\n"
                "1,-,152.579827,-0.7688,155.6,4.8,2\n"
                "1,-,0.000000,0.7988,179,4.2,2\n"
                "2,+,0.000000,-1.1206,182.2,1.8,2\n"
                "2,+,152.579827,-2.3379,204.6,3.2,2\n"
                "2,+,290.237031,-4.5923,223.4,1.5,2\n"
                "2,+,457.702636,-6.5940,246.3,1.9,2\n"
                "2,+,595.358840,-6.6019,264.3,0.7,2\n"
                "2,-,595.358840,-5.8117,266.3,0.6,2\n"
                "2,-,457.702636,-5.6290,287.7,4.1,2\n"
                "2,-,290.237031,-3.2408,313.1,4.4,2\n"
                "2,-,152.579827,-1.0203,335.4,5,2\n"
                "2,-,0.000000,0.5709,357.2,2.6,2\n")
"""A follow-up recorded on the simulated machine: 5 targets, 2 runs, waits 0.5 to 5 s."""


def test_a_follow_up_alone_is_read(cli, tmp_path):
    """Its periodogram has no peak, which is no internal error (it was a KeyError)."""
    (tmp_path / "p.csv").write_text(FIVE_TARGETS)
    said = cli("discover", tmp_path / "p.csv")
    assert said.code == 0, said.err
    assert "backlash" in said.out


DEMO = (DATA.parent / "campaign" / "demo.toml").read_text()
"""The shipped demo config: its error model inline ([sim.effects.*]), the dwell capture."""
DEMO_MODEL = {"backlash": {"b_um": 6.0}, **BOW}
SUB_TABLES = ('[instrument.line]\ntag = ""\nseparator = ";"\nfields = ["time_s", "position", "signal_pct"]\n'
              'position_scale = 0.001\n\n[sim.faults]\nbeam_break = { at_s = 300.0, duration_s = 3.0 }\n')


def demo_text(extra: str = "") -> str:
    """demo.toml with a 6 µm backlash added to its inline model, and `extra` tables at the end."""
    return DEMO.replace("[sim.effects.linear_scale]", "[sim.effects.backlash]\nb_um = 6.0\n\n"
                        "[sim.effects.linear_scale]") + "\n" + extra


@pytest.mark.parametrize("extra", ["", SUB_TABLES], ids=["demo", "demo+line+faults"])
def test_the_follow_up_of_a_config_with_sub_tables_keeps_them(cli, tmp_path, extra):
    """demo.toml's [sim.effects.*] (and [instrument.line], [sim.faults]) broke the follow-up: its TOML
    writer met the config's frozen tables (an internal error, exit 1, nothing printed). The follow-up
    keeps every sub-table as the first campaign had it, and reads back as the config it was made from."""
    _, config, out = written_follow_up(cli, tmp_path, demo_text(extra), DEMO_MODEL)
    assert out["follow_up"] is not None and out["follow_up"]["capture"] == "dwell"
    followed = load_config(tmp_path / "follow.toml")
    assert followed.sim.effects == config.sim.effects and followed.sim.faults == config.sim.faults
    assert followed.instrument.line == config.instrument.line and followed.axis == config.axis
    assert followed.plan.length is None and followed.plan.targets == tuple(out["follow_up"]["targets"])
    assert cli("plan", tmp_path / "follow.toml").code == 0


@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_the_findings_are_printed_when_the_follow_up_cannot_be_written(cli, tmp_path):
    directory = tmp_path / "first"
    directory.mkdir()
    (directory / "config.toml").write_text(demo_text())
    config = load_config(directory / "config.toml")
    write_points(directory / "points.csv", simulate_campaign(config, ErrorModel(DEMO_MODEL), seed=1))
    said = cli("discover", directory / "points.csv", "--follow-up", "-o", tmp_path / "no" / "such" / "f.toml")
    assert said.code == 2 and said.err.startswith("error:") and len(said.err.strip().splitlines()) == 1
    assert "no/such/f.toml" in said.err and "gap" in said.out and "stand-in" in said.out
    said = cli("discover", directory / "points.csv", "--follow-up", "-o", tmp_path / "no" / "f.toml", "--json")
    assert said.code == 2 and json.loads(said.out)["follow_up_error"].startswith("-o ")


@pytest.mark.machine  # about a second in all: the fast tier stays under a minute
def test_the_bow_is_averaged_when_a_bump_is_not_added_beside_an_unresolved_period():
    """A 10 mm lead at 11 targets and a +3 µm bump 150 mm wide: the bump would fit, but the period
    stays unresolved beside it, so the bump is not added. That branch returned the search's result
    as it was: the other effects were not averaged over the candidate periods (the issue-26 fix
    skipped; `averaged` empty with the old code)."""
    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    bump = {"amplitude_um": 3.0, "centre_mm": 300.0, "width_mm": 150.0, "direction": 0.0}
    result = found(user_config(seed=1), {**BOW, **lead, "local_defect": bump}, 1)
    assert result.local is None and any("would fit too" in n for n in result.notes)  # the branch
    assert [u.effects for u in result.unresolved] == [("periodic_lead",)]
    assert "linear_scale" in result.averaged and any("averaged" in n for n in result.notes)
    assert result.params()["linear_scale"] == result.averaged["linear_scale"]


@pytest.mark.machine
def test_a_thermal_time_constant_in_point_order_is_not_printed_in_seconds(cli, tmp_path):
    """Without a time column thermal_drift's τ is fitted in points; the summary said 's' (old code)."""
    config = parse_config(user_config().text.replace("cycles = 5", "cycles = 10"))
    drift = {"thermal_drift": {"growth_ppm": 10.0, "tau_s": 250.0, "pivot_mm": 300.0}}
    write_points(tmp_path / "p.csv", simulate_campaign(config, ErrorModel({**BOW, **drift}), seed=1))
    lines = (tmp_path / "p.csv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("run,"))
    keep = [i for i, n in enumerate(lines[header].split(",")) if n != "time_s"]
    cut = lines[:header] + [",".join(line.split(",")[i] for i in keep) for line in lines[header:]]
    (tmp_path / "q.csv").write_text("\n".join(cut) + "\n")
    said = " ".join(cli("discover", tmp_path / "q.csv").out.split())
    tau = re.search(r"named: thermal_drift .*?tau_s = \S+ (\w+)", said)
    assert tau is not None and tau.group(1) == "points", said


def test_tables_of_different_axis_kinds_are_refused(cli, tmp_path):
    """A linear table (mm, µm) and a rotary one (deg, arcsec) fitted together mixed their units
    silently with the old code (exit 0)."""
    table = simulate_campaign(user_config(), ErrorModel(BOW), seed=1)
    write_points(tmp_path / "a.csv", table)
    text = (tmp_path / "a.csv").read_text().replace("target_mm", "target_deg").replace("deviation_um", "deviation_arcsec")
    (tmp_path / "r.csv").write_text(text)
    said = cli("discover", tmp_path / "a.csv", tmp_path / "r.csv")
    assert said.code == 2 and said.err.startswith("error:") and len(said.err.strip().splitlines()) == 1
    assert "a.csv" in said.err and "r.csv" in said.err and "arcsec" in said.err and said.out == ""


def planned_follow_up(tmp_path, groups: list[Unresolved], budget_s: float | None = None):
    """The follow-up planned for `groups` after a first campaign of the shipped config (the bow only,
    fast simulator): the follow-up and the first campaign's targets."""
    from campaign.discovery.followup import plan_follow_up

    config = user_config()
    data = campaign_data(simulate_campaign(config, ErrorModel(BOW), seed=1))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    follow = plan_follow_up(groups, [], data, result.final, config, None, result.noise_um, tmp_path / "f.toml",
                            ["first/points.csv"], budget_s=budget_s)
    assert follow is not None
    return follow, sorted(set(np.round(data.x, 3)))


@pytest.mark.machine
def test_the_thermal_part_spans_the_travel_with_twice_the_runs_and_is_not_planned_beyond_the_budget(tmp_path):
    """Scale against thermal drift: a slope is seen over the travel and a drift over time, so twice
    the runs at targets over the whole travel. That takes longer than the first campaign (its moves
    cover the travel twice as often): issue 34 asks for at most the first campaign's machine time by
    construction, so it is said, with its cost, not planned (the old planner warned and wrote it).
    Given a larger budget it is planned: 5 of the first campaign's targets over the travel."""
    from campaign.plan import build_plan

    groups = [Unresolved(("linear_scale", "thermal_drift"), "", "")]
    follow, first = planned_follow_up(tmp_path, groups)
    assert not follow.parts and follow.duration_s == 0.0
    [said] = follow.unplanned
    assert "not within the budget" in said and re.search(r"it alone would take \d+\.\d min", said)
    follow, first = planned_follow_up(tmp_path, groups, budget_s=3 * follow.first_duration_s)
    targets = build_plan(follow.config).targets
    # exactly where the first campaign measured: its targets already hold its golden offsets
    assert set(np.round(targets, 3)) <= set(first) and len(targets) == 5 and follow.config.plan.offsets == "none"
    assert min(targets) == first[0] and max(targets) == first[-1]
    assert follow.config.plan.cycles == 2 * user_config().plan.cycles
    assert follow.duration_s <= 3 * follow.first_duration_s
    assert "whole travel" in follow.parts[0].why and "over a longer time" not in follow.parts[0].why


@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_the_growing_backlash_part_spans_the_travel(tmp_path):
    from campaign.plan import build_plan

    groups = [Unresolved(("backlash", "position_dependent_backlash"), "", "")]
    follow, first = planned_follow_up(tmp_path, groups)
    targets = build_plan(follow.config).targets
    assert set(np.round(targets, 3)) <= set(first) and min(targets) == first[0] and max(targets) == first[-1]
    assert follow.duration_s <= follow.first_duration_s and "whole travel" in follow.parts[0].why


@pytest.mark.machine
def test_a_follow_up_is_marked_as_one_and_never_longer_than_the_first_campaign(tmp_path):
    """Issue 34 item 6: every part together (settling against backlash, an aliased period, a growing
    reversal) fits the first campaign's machine time by construction; the config says it is a
    follow-up of the first campaign, so it is never judged as an acceptance test."""
    groups = [Unresolved(("backlash", "settling"), "", ""),
              Unresolved(("periodic_lead",), "", "", periods_mm=(10.0, 3.8, 6.56), period_delta_bic=(0, 1, 2)),
              Unresolved(("backlash", "position_dependent_backlash"), "", "")]
    follow, _ = planned_follow_up(tmp_path, groups)
    assert follow.parts and follow.duration_s <= follow.first_duration_s, (follow.duration_s, follow.unplanned)
    assert follow.config.campaign.purpose == "follow-up" and follow.config.campaign.follows == "first"
    assert 'purpose = "follow-up"' in follow.text and "not an acceptance test" in follow.text
    for budget in (0.3, 0.6):  # a smaller budget: fewer parts, each said with its cost
        smaller, _ = planned_follow_up(tmp_path, groups, budget_s=budget * follow.first_duration_s)
        assert smaller.duration_s <= budget * follow.first_duration_s
        assert all("not within the budget" in u for u in smaller.unplanned)
        assert len(smaller.parts) + len(smaller.unplanned) == 3


@pytest.mark.machine  # about a second: the fast tier stays under a minute
def test_a_cluster_is_bounded_and_says_so():
    """Candidates 0.5 mm and about 20 mm: a quarter of the shortest apart over three of the longest
    would be over 600 targets."""
    from campaign.discovery.followup import MAX_CLUSTER_TARGETS, _cluster

    config = user_config()
    data = campaign_data(simulate_campaign(config, ErrorModel(BOW), seed=1))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    targets, why = _cluster(data, result.final, [0.5, 20.0, 20.5], [], result.noise_um)
    assert len(targets) == MAX_CLUSTER_TARGETS and f"bounded to {MAX_CLUSTER_TARGETS} targets" in why
    assert max(np.diff(targets)) <= 0.5 / 4 + 1e-9


def test_a_scan_over_a_cluster_and_a_rival_region_keeps_its_windows_apart(tmp_path):
    """A cluster's targets and a rival region's (merged into one scan) may fall a hair apart: the
    written config must read back (no window shorter than the laser's sample spacing, none taking
    a neighbour's samples) and overlapping regions are measured once (one part, not two)."""
    from campaign.discovery.fit import linear_fit
    from campaign.discovery.followup import plan_follow_up
    from campaign.discovery.records import LocalRival

    config = parse_config(user_config().text, str(tmp_path / "first" / "config.toml"))
    lead = {"periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": 0.3}}
    data = campaign_data(simulate_campaign(config, ErrorModel({**BOW, **lead}), seed=1))
    rng = np.random.default_rng(7)
    for start in rng.uniform(260.0, 320.0, 4):
        region = (round(float(start), 3), round(float(start) + float(rng.uniform(5.0, 30.0)), 3))
        group = Unresolved(("periodic_lead",), "aliased", "more targets", periods_mm=(10.0, 15.9, 4.4),
                           period_delta_bic=(0.0, 1.0, 2.0), local_rivals=(LocalRival("a bump", region),))
        follow = plan_follow_up([group], [], data, linear_fit(data, []), config, None, 0.34, tmp_path / "f.toml",
                                ["first/points.csv"], [region, region, (region[0] + 1.0, region[1] + 5.0)])
        assert follow is not None and len(follow.campaigns) == 1
        scan = load_config(tmp_path / "f.toml") if (tmp_path / "f.toml").exists() else None
        written = parse_config(follow.text, str(tmp_path / "f.toml"))  # reads back: its windows are valid
        assert scan is None or scan.plan.targets == written.plan.targets
        assert written.capture.method == "scan"
        sample = written.capture.scan_velocity / written.instrument.rate_hz
        gaps = np.diff(written.plan.targets)
        assert gaps.min() >= 2 * sample * 0.999 and written.capture.scan_window <= gaps.min() + 1e-9
        assert written.capture.scan_window >= sample
        assert [p.effects for p in follow.parts].count(["local error"]) == 1, [p.why for p in follow.parts]


def test_a_region_after_a_dense_follow_up_takes_the_first_campaigns_spacing(tmp_path):
    """Fitted with a dense follow-up, a region's targets are a quarter of the FIRST campaign's
    spacing apart, and its why says that spacing (not that of the union of the tables' targets)."""
    from campaign.discovery.fit import linear_fit
    from campaign.discovery.followup import plan_follow_up

    config = parse_config(user_config().text, str(tmp_path / "first" / "config.toml"))
    first = campaign_data(simulate_campaign(config, ErrorModel(BOW), seed=2))
    dense = parse_config(user_config(count=121).text.replace("start = 0.0", "start = 400.0").replace(
        "length = 600.0", "length = 150.0"), str(tmp_path / "first" / "config.toml"))  # dense, beside the region
    data = join_campaigns([first, campaign_data(simulate_campaign(dense, ErrorModel(BOW), seed=3))], ["a", "b"])
    spacing = float(np.median(np.diff(np.unique(np.round(first.x, 6)))))
    follow = plan_follow_up([], [], data, linear_fit(data, []), config, None, 0.34, tmp_path / "f.toml",
                            ["a/points.csv", "b/points.csv"], [(150.0, 350.0)])
    assert follow is not None
    [part] = follow.parts
    assert f"the first campaign's are {spacing:.3g} mm apart" in part.why
    step = float(np.median(np.diff(follow.config.plan.targets or [])))
    assert spacing / 4 * 0.9 <= step <= spacing / 4 * 1.1, (step, spacing)
    # the same region measured that densely already: not measured again, nothing to plan
    again = parse_config(user_config(count=121).text.replace("length = 600.0", "length = 250.0").replace(
        "start = 0.0", "start = 125.0"), str(tmp_path / "first" / "config.toml"))
    data = join_campaigns([first, campaign_data(simulate_campaign(again, ErrorModel(BOW), seed=4))], ["a", "b"])
    assert plan_follow_up([], [], data, linear_fit(data, []), config, None, 0.34, tmp_path / "f.toml",
                          ["a/points.csv", "b/points.csv"], [(150.0, 350.0)]) is None
    # an effect that local errors there fit as well, and the tables measure densely there already: the
    # group is said unplanned (before, it was neither planned nor said, and the loop never ended)
    from campaign.discovery.followup import _asks
    from campaign.discovery.records import LocalRival

    bow = Unresolved(("nonlinear_lead",), "a bump fits as well", "denser targets over 150–350 mm",
                     local_rivals=(LocalRival("a bump", (150.0, 350.0)),))
    asks, unplanned = _asks([bow], [], data, linear_fit(data, []), config, None, 0.34, [])
    assert not asks and len(unplanned) == 1 and "nonlinear_lead" in unplanned[0], unplanned
    asks, unplanned = _asks([bow], [], first, linear_fit(first, []), config, None, 0.34, [])  # the first alone
    assert len(asks) == 1 and not unplanned


@pytest.mark.machine
@pytest.mark.parametrize("seed", [5])  # 6 too by hand (about 17 s each)
def test_the_loop_ends_when_the_tables_together_leave_nothing(cli, tmp_path, seed):
    """A located bump: the follow-up measures its region densely; fitted together, nothing is
    unresolved and what is left is noise, so the loop ends: no follow-up proposed, none written
    (exit 0), and --follow-up says so (it planned a third campaign over the same region before)."""
    machine = {**BOW, "local_defect": BUMP}
    first, _, out = written_follow_up(cli, tmp_path, user_config(count=21, seed=seed).text, machine, seed)
    assert out["follow_up"] is not None and out["follow_up"]["campaigns"], out["follow_up"]
    tables = []
    for i, campaign in enumerate(out["follow_up"]["campaigns"]):
        config = load_config(campaign["file"])
        tables.append(tmp_path / f"second-{i}.csv")
        write_points(tables[-1], simulate_campaign(config, ErrorModel(machine), seed=seed + 100 + i,
                                                   dwell_jitter=config.plan.dwell_jitter))
    both = json.loads(cli("discover", first, *tables, "--json").out)
    assert not both["unresolved"] and both["gap_after_um"] <= 1.3 * both["noise_um"], both["unresolved"]
    said = cli("discover", first, *tables, "--follow-up", "-o", tmp_path / "third.toml")
    assert said.code == 0 and not (tmp_path / "third.toml").exists()
    assert "no file written" in said.out and "--follow-up" not in said.out.split("follow-up:")[0]


@pytest.mark.machine  # a few seconds
def test_a_bump_beside_a_reversal_is_not_split_by_direction(cli):
    """tests/recorded/backlash-settling-bump-350mm.csv: `axiscal run` of the simulated horizontal axis
    (11 golden targets, stable trigger, sim seed 30) with a 2.5 µm bump 150 mm wide at 350 mm in both
    directions beside a 1.8 µm backlash and settling of 2 µm, τ 1 s. The bump was found as +4.3 µm in −
    and +1.0 µm in +: split by direction, it took the reversal where it lies and left the rest to
    nothing. A split must beat a reversal constant along the travel."""
    out = json.loads(cli("discover", RECORDED / "backlash-settling-bump-350mm.csv", "--json").out)
    bumps = [e for e in out["local_errors"] if 200.0 < e["region_mm"][0] + (e["region_mm"][1] - e["region_mm"][0]) / 2
             < 500.0]
    assert bumps and all(e["directions"] == "both" for e in bumps), out["local_errors"]
    assert not any("by_direction" in e["effect"] for e in out["local_errors"])


@pytest.mark.machine  # a few seconds
def test_bumps_found_in_an_effects_place_must_hold_what_it_held(cli):
    """tests/recorded/backlash-wave-300-600mm*.csv: `axiscal run` of the simulated horizontal axis (17
    golden targets, stable trigger, sim seed 24) with a 1 µm backlash and a 3 µm wave of period 60 mm
    over 300-600 mm, and its follow-up (a period cluster, a wait ladder). Backlash was named, then
    dropped: bumps searched anew in its place held the wave and predicted left-out targets better than
    the model without them. Beside those bumps the backlash still predicts better: it stays named."""
    tables = [RECORDED / f"backlash-wave-300-600mm{part}.csv" for part in ("", "-cluster", "-ladder")]
    out = json.loads(cli("discover", *tables, "--json").out)
    assert "backlash" in out["added"], out["notes"]
    b, error = out["model"]["backlash"]["b_um"], out["model_standard_errors"]["backlash"]["b_um"]
    assert abs(b - 1.0) < 3 * error + 0.05, (b, error)


@pytest.mark.machine  # a few seconds
def test_the_follow_up_measures_where_a_local_error_may_be():
    """tests/recorded/bow-step-minus-300mm.csv: `axiscal run` of the simulated horizontal axis (11
    golden targets, 0.7 µm noise, sim seed 1) with a bow and a 3 µm step at 300 mm in the − direction
    only. The step was fitted at 337 ± 18 mm, rising over 56 mm with one target on its rise, and the
    follow-up measured 309-365 mm, never its rise. A step with one target or none on its rise is said
    between the targets either side of its middle; a fitted region is measured widened by twice its
    centre's error."""
    from dataclasses import replace

    from campaign.discovery.data import campaign_data
    from campaign.discovery.followup import regions_to_measure, with_its_place_uncertain
    from campaign.discovery.local import Zone
    from campaign.pointtable import read_points

    data = campaign_data(read_points(RECORDED / "bow-step-minus-300mm.csv"))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    step = next(e for e in result.local_errors if e.kind == "step")
    assert step.between_mm is not None and step.between_mm[0] < 300.0 < step.between_mm[1]
    assert any(a < 300.0 < b for a, b in regions_to_measure(result)), regions_to_measure(result)
    fitted = replace(step, between_mm=None, params={**step.params, "centre_mm": 337.0, "width_mm": 56.0},
                     errors={**step.errors, "centre_mm": 18.0})
    low, high = fitted.region_mm
    assert not low <= 300.0 <= high  # the fit alone misses it
    wide = with_its_place_uncertain(Zone(fitted.region_mm, 3.0, "", (fitted,)))
    assert wide == pytest.approx((low - 36.0, high + 36.0))


@pytest.mark.machine  # a few seconds
def test_a_step_in_one_direction_stays_a_step_beside_its_dense_follow_up(cli):
    """tests/recorded/bow-step-minus-300mm-dense.csv: the follow-up `discover --follow-up` wrote for
    bow-step-minus-300mm.csv (22 points over the step's region), recorded with `axiscal run` on the same
    machine. Fitted together, position_dependent_backlash was named (b0 -0.39 ± 0.34 µm, k 6.9 µm/m):
    the local search tried only terms in both directions, and a reversal that grows along the travel
    held the step the − direction alone has. Now: nothing the machine lacks is named, and the step is
    placed within 10 mm of 300 mm, in the − direction alone."""
    out = json.loads(cli("discover", RECORDED / "bow-step-minus-300mm.csv",
                         RECORDED / "bow-step-minus-300mm-dense.csv", "--json").out)
    assert set(out["added"]) <= {"nonlinear_lead", "linear_scale"}, out["added"]
    steps = [e for e in out["local_errors"] if e["kind"] == "step"
             and abs((e["region_mm"][0] + e["region_mm"][1]) / 2 - 300.0) <= 10.0]
    assert steps and all(e["directions"] == "-" for e in steps), out["local_errors"]


@pytest.mark.machine  # a few seconds
def test_a_rival_the_data_leave_room_for_is_said(cli):
    """tests/recorded/backlash-and-settling*.csv: `axiscal run` of the simulated horizontal axis (11
    golden targets, stable trigger, sim seed 30) with a 1.8 µm backlash and settling of 2 µm, τ 1 s, and its
    follow-up's 20-point wait ladder. Fitted together they name settling alone, τ about 4 s. Beside
    it, settling's time constant refitted, a backlash fits about 2 µm (the truth 1.8): the data do not
    exclude it. Said in the notes, under `not_excluded` and on the first screen, with the waits that
    would show a settling of the refitted time constant fade; the follow-up's wait ladder reaches them
    and the loop does not end there."""
    from campaign.commands.discover import loop_ends, read_tables, to_tell
    from campaign.discovery.fit import linear_fit
    from campaign.discovery.followup import _asks

    tables = [RECORDED / f"backlash-and-settling{part}.csv" for part in ("", "-ladder")]
    out = json.loads(cli("discover", *tables, "--json").out)
    said = [n for n in out["notes"] if n.startswith("backlash beside settling is not excluded")]
    assert out["added"] == ["settling"] and said, out["notes"]
    [rival] = out["not_excluded"]
    assert rival["rival"] == "backlash" and 1.0 <= rival["b_um"] <= 3.0 and rival["waits_up_to_s"] > 1.0, rival
    screen = " ".join(cli("discover", *tables).out.split())
    assert "not excluded: backlash beside settling" in screen and "waits up to about" in screen, screen
    assert "--follow-up" in screen
    data = read_tables([str(t) for t in tables])[0]
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert not loop_ends(result, [str(t) for t in tables])
    asks, unplanned = _asks(to_tell(result), [], data, linear_fit(data, []), user_config(), 2.0, 0.36, [])
    [ladder] = asks
    waits = rival["waits_up_to_s"]
    assert not unplanned and ladder.plan["dwell_s"] * (1 + ladder.plan["dwell_jitter"]) >= 0.99 * max(waits, 5.0)


BACKLASH_AND_SETTLING = {"linear_scale": {"ppm": 10.0}, "backlash": {"b_um": 1.5},
                         "settling": {"e0_um": 2.0, "tau_s": 1.0}, "noise": {"sigma_um": 0.3, "reading_sigma_um": 0.03}}


@pytest.mark.parametrize("seed", [3, *(pytest.param(s, marks=pytest.mark.machine) for s in (6, 7))])
def test_backlash_beside_settling_is_tried_with_the_settling_refitted(seed):
    """1.5 µm backlash and 2 µm settling (τ 1 s), 13 golden targets, waits 0.4–3.6 s. Settling was named
    first and backlash then tried beside it with its time constant held as fitted alone, where the long
    τ (2.5–3.3 s on eight seeds) had taken the reversal: backlash explained nothing and was said "not
    excluded", and settling's τ stood 3σ off (a user's trial, named after three follow-ups at τ 5.2 ± 1.2 s).
    A rival in the model with a shape is now refitted beside the candidate: both are named here, each
    within 3σ of the truth (5 of 8 seeds; the other 3 still say settling with backlash not excluded)."""
    from tests.discovery_draws import plan_config

    data = campaign_data(simulate_campaign(plan_config(13, "golden"), ErrorModel(BACKLASH_AND_SETTLING), seed=seed,
                                           dwell_jitter=0.8))
    result = discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()})
    assert sorted(result.added) == ["backlash", "settling"], (result.added, result.not_excluded)
    params, errors = result.params(), result.errors
    for name, key, true in (("backlash", "b_um", 1.5), ("settling", "tau_s", 1.0), ("settling", "e0_um", 2.0)):
        assert abs(params[name][key] - true) < 3 * errors[name][key], (name, key, params[name], errors[name])


@pytest.mark.parametrize("alone", ["settling", "backlash"])
def test_settling_or_backlash_alone_gets_no_rival_named_beside_it(alone):
    truth = {k: v for k, v in BACKLASH_AND_SETTLING.items() if k not in ({"backlash", "settling"} - {alone})}
    from tests.discovery_draws import plan_config

    for seed in (1, 2):
        data = campaign_data(simulate_campaign(plan_config(13, "golden"), ErrorModel(truth), seed=seed, dwell_jitter=0.8))
        assert discover(data, ErrorModel({"linear_scale": {}}), {"linear_scale": set()}).added == [alone]


def test_a_config_beside_the_table_that_does_not_read_is_said(cli, tmp_path):
    """A config.toml beside a table gives discovery the campaign's sample period and capture method;
    one that does not read is said, with what is wrong, not silently passed over."""
    write_points(tmp_path / "points.csv", simulate_campaign(user_config(), ErrorModel(BOW), seed=2))
    plain = json.loads(cli("discover", tmp_path / "points.csv", "--json").out)
    assert not any("config.toml" in n for n in plain["notes"])
    (tmp_path / "config.toml").write_text("[plan]\ncount = 'eleven'\n")
    said = cli("discover", tmp_path / "points.csv", "--json")
    notes = [n for n in json.loads(said.out)["notes"] if "config.toml" in n]
    assert said.code == 0 and len(notes) == 1 and "does not read" in notes[0] and "sample period" in notes[0]
    assert json.loads(said.out)["added"] == plain["added"]  # the table itself is read as before

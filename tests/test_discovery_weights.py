"""A stop-and-go table and a scan profile fitted together (issue 34, the aliased lead's follow-up; issue
33's scan): each table is weighed by its own uncertainty (the table's repeatability, the profile's bin
scatter), each sweep of the profile has its own offset and slope, so that its thousands of bins, each far more precise than a stop-and-go point, do not make its systematic errors (the rest
it is referred to, the clocks' offset and rate) look like effects. The first table from the fast
simulator, the profile from the simulated scan streams with an instrument clock drawn at random
(tests/test_discovery_profile.py), aligned and profiled as a real scan is; truths drawn per seed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.cli import main
from campaign.commands.discover import config_beside
from campaign.discovery.data import campaign_data, join_campaigns, read_campaign, read_profile
from campaign.discovery.fit import design
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from campaign.pointtable import write_points
from campaign.stream.align import ControllerStream, InstrumentStream
from campaign.stream.scan import analyse_scan, write_profile
from drivers.sim.scan_streams import scan_machine
from tests.test_discovery_loop import user_config
from tests.test_discovery_profile import _clock


def _machine(rng: np.random.Generator, lead: bool) -> dict:
    """A bow, a scale error, a backlash, the shipped noise; a screw lead when `lead`."""
    machine = {"linear_scale": {"ppm": float(rng.uniform(-15, 15))},
               "nonlinear_lead": {"p2_um": float(rng.uniform(-1, 1)), "p3_um": float(rng.uniform(-1, 1)),
                                  "start_mm": 0.0, "end_mm": 600.0},
               "backlash": {"b_um": float(rng.uniform(0, 2))},
               "noise": {"sigma_um": 0.34, "reading_sigma_um": float(rng.uniform(0.02, 0.1))}}
    if lead:
        machine["periodic_lead"] = {"amplitude_um": float(rng.uniform(0.7, 1.5)),
                                    "period_mm": float(rng.uniform(6, 14)), "phase_rad": float(rng.uniform(0, 6.28))}
    return machine


def _tables(tmp_path, seed: int, machine: dict, rng: np.random.Generator) -> tuple[str, str]:
    """The first campaign (the shipped plan: 11 golden targets over 600 mm, 5 runs) and a 60 mm
    scan at 10 mm/s, one sweep each way, resting 3 s at each end (its rest steps refer it to rest)."""
    first = tmp_path / "points.csv"
    write_points(first, simulate_campaign(user_config(seed=seed), ErrorModel(machine), seed=seed))
    low = float(rng.uniform(50, 480))
    axis = scan_machine(ErrorModel(machine), "mm", 50.0, 200.0, low - 5, _clock(rng), 500.0, seed=seed)
    rec = axis.scan(low - 5, low + 65, 10.0, 1, end_dwell_s=3.0)
    result = analyse_scan(ControllerStream(rec.controller_time_s, rec.controller_position),
                          InstrumentStream(rec.instrument_time_s, rec.instrument_reading),
                          [low, low + 30, low + 60], 500.0)
    write_profile(str(tmp_path / "profile.csv"), result)
    return str(first), str(tmp_path / "profile.csv")


@pytest.mark.machine  # about a second in all: the fast tier stays under a minute
def test_each_table_is_weighed_by_its_own_uncertainty(tmp_path):
    """The profile's bins carry their scatter as uncertainty (a small fraction of the table's
    repeatability); each sweep its own offset and, beside the table, its own slope; the table's
    points its repeatability."""
    rng = np.random.default_rng(41)
    first, profile = _tables(tmp_path, 41, _machine(rng, lead=True), rng)
    table, _ = read_profile(profile)
    scan = read_campaign(profile, table)
    stops = read_campaign(first, None, config_beside(str(first)))
    both = join_campaigns([stops, scan], [first, profile])
    assert scan.u is not None and scan.sloped is not None and scan.sloped.all()
    assert 0.005 < float(np.median(scan.u)) < 0.1  # a bin's mean of a few samples of 0.02-0.1 µm noise
    assert both.u is not None and 0.25 < float(both.u[0]) < 0.45  # the table's repeatability: 0.34 µm
    assert both.datums == 3 and both.row_scale is not None and both.row_scale[-1] > 3
    assert design(both, [])[0].shape[1] == 5  # three offsets, the two sweeps' slopes
    assert design(scan, [])[0].shape[1] == 2  # alone: its two sweeps' offsets


@pytest.mark.machine  # about 5 s (a scan simulated): the fast tier stays under a minute
def test_a_scan_profile_beside_tables_keeps_their_waits_and_counts_as_settled(tmp_path):
    """A scan profile has no wait column (its bins are captured moving). The waits of the tables
    beside it were dropped: with a follow-up's wait ladder and a scanned cluster, settling was then
    never looked for and backlash-or-settling stayed unresolved. The profile's bins count as long
    settled (an infinite wait); whether the waits vary is decided by the points captured at a stop."""
    import dataclasses

    from campaign.discovery.simulate import simulate_campaign
    from campaign.discovery.vocabulary import candidate_names, waits_vary

    rng = np.random.default_rng(43)
    machine = _machine(rng, lead=False) | {"settling": {"e0_um": 3.0, "tau_s": 2.0}}
    first, profile = _tables(tmp_path, 43, machine, rng)
    scan = read_campaign(profile, read_profile(profile)[0])
    fixed = read_campaign(first, None, config_beside(str(first)))
    ladder = campaign_data(simulate_campaign(user_config(seed=44), ErrorModel(machine), seed=44, dwell_jitter=0.8))
    for stops in (fixed, ladder):
        for parts in ([stops, scan], [scan, stops]):
            both = join_campaigns(parts, ["a", "b"])
            assert both.w is not None and stops.w is not None
            at_scan = both.campaign == (0 if parts[0] is scan else 1)
            assert np.isinf(both.w[at_scan][:, 0]).all() and np.isfinite(both.w[~at_scan][:, 0]).all()
            assert waits_vary(both) == waits_vary(stops) == (stops is ladder)
            assert ("settling" in candidate_names(both, [], [])) == (stops is ladder)
    assert join_campaigns([dataclasses.replace(fixed, w=None), scan], ["a", "b"]).w is None  # its waits unknown


@pytest.mark.machine  # 4 simulated campaigns and scans, each discovered in both file orders: about 16 s of CPU
@pytest.mark.parametrize("seed, lead", [(51, True), (54, False)])  # 52, 53, 55 too by hand: ~14 s each
def test_a_table_and_a_scan_profile_name_nothing_the_machine_lacks(tmp_path, capsys, seed, lead):
    """Fitted together: only what the machine has is named (the bow, the scale, its backlash, its
    screw lead, whose period is within 1 %, nothing unresolved about it); an unresolved group holds
    an effect the machine has (the table's fixed dwell cannot tell its backlash from settling); no
    region is left after the named effects, and no local error is added."""
    rng = np.random.default_rng(seed)
    machine = _machine(rng, lead)
    first, profile = _tables(tmp_path, seed, machine, rng)
    assert main(["discover", first, profile, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert main(["discover", profile, first, "--json"]) == 0  # the other order: the same conclusions
    reversed_ = json.loads(capsys.readouterr().out)
    assert set(reversed_["added"]) == set(out["added"]), (reversed_["added"], out["added"])
    assert not reversed_["located"]["after"]["regions"], reversed_["located"]["after"]["regions"]
    assert not reversed_["local_errors"] and len(reversed_["unresolved"]) == len(out["unresolved"])
    assert set(out["added"]) <= set(machine) - {"noise"}, (out["added"], machine)
    if lead:
        assert "periodic_lead" in out["added"], out["added"]
        assert out["model"]["periodic_lead"]["period_mm"] == pytest.approx(machine["periodic_lead"]["period_mm"],
                                                                           rel=0.01)
    assert all(set(u["effects"]) & set(machine) and "periodic_lead" not in u["effects"]
               for u in out["unresolved"]), out["unresolved"]
    assert not out["located"]["after"]["regions"], out["located"]["after"]["regions"]
    assert not out["local_errors"], out["local_errors"]


@pytest.mark.parametrize("seed", [61, 62, 63])
def test_a_table_of_one_run_takes_the_pooled_repeatability_not_the_spread_of_its_errors(seed):
    """A follow-up of one cycle repeats nothing, so it cannot show its own scatter; weighed by the
    spread of its deviations (the errors sought, microns) its points counted a few per cent of
    the first campaign's in the joint fit, and the locator's noise came out 1-2 µm on a 0.3 µm axis
    (a 2.5 µm step was 'nothing beyond the noise'). It takes the repeatability of the tables that
    repeat (one axis, one laser), whatever the order of the files."""
    from campaign.discovery.data import campaign_data, keep_rows, repeatability
    from campaign.discovery.locate import locate

    rng = np.random.default_rng(seed)
    machine = _machine(rng, lead=False) | {"local_defect": {"amplitude_um": 3.0, "centre_mm": float(rng.uniform(100, 500)),
                                                             "width_mm": 80.0}}
    first = campaign_data(simulate_campaign(user_config(seed=seed), ErrorModel(machine), seed=seed))
    again = campaign_data(simulate_campaign(user_config(count=21, seed=seed + 1), ErrorModel(machine), seed=seed + 1))
    one_run = keep_rows(again, again.run == again.run.min())
    for parts in ([first, one_run], [one_run, first]):
        joined = join_campaigns(parts, ["first.csv", "follow.csv"])
        assert joined.u is not None
        which = 1 if parts[1] is one_run else 0
        u_one_run = joined.u[joined.campaign == which]
        assert np.allclose(u_one_run, repeatability(first))
        assert u_one_run[0] < 0.5 * float(np.std(one_run.y))  # not the spread of its errors
        located = locate(joined, joined.y)  # before any model, as `discover` locates first
        assert located.noise_um < 2 * machine["noise"]["sigma_um"], located.noise_um

"""A scan through `axiscal run` on the simulated machine (issue 33 item 1): the axis sweeps the
plan's travel at scan_velocity in both directions for the plan's cycles; the instrument streams
over the pty with its own clock ([sim] instrument_*), the controller's actual position arrives as
ADS device notifications through the real pyads client; both streams are recorded (raw.csv,
positions.csv, each sweep made durable in sweeps.csv), then aligned into profile.csv and the point
table, which says it is a diagnostic. Each case draws its instrument clock; the truth is the
simulated axis's own error model at rest."""

from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest

from campaign.config import parse_config
from campaign.measure import start_campaign
from campaign.model import sim_model
from campaign.pointtable import read_points
from drivers.factory import open_hardware

SCAN = """
[campaign]
machine = "sim-scan"
purpose = "diagnostic"
[axis]
soft_limit_min = -10.0
soft_limit_max = 110.0
max_velocity = 50.0
max_acceleration = 200.0
[plan]
start = 0.0
length = 60.0
count = 7
overrun = 4.0
cycles = 2
dwell_s = 2.5
velocity = 20.0
[instrument]
rate_hz = 500.0
[capture]
method = "scan"
scan_velocity = {velocity}
[sim]
seed = {seed}
instrument_offset_s = {offset}
instrument_rate_ppm = {rate}
instrument_latency_s = {latency}
instrument_jitter_s = {jitter}
[sim.effects.linear_scale]
ppm = {ppm}
[sim.effects.backlash]
b_um = {backlash}
[sim.effects.periodic_lead]
amplitude_um = 0.4
period_mm = 10.0
phase_rad = {phase}
[sim.effects.noise]
sigma_um = 0.2
reading_sigma_um = 0.05
"""


def draw(seed: int) -> dict:
    rng = np.random.default_rng([seed, 330])
    sign = rng.choice([-1.0, 1.0], 2)
    return {"seed": seed, "velocity": round(float(rng.uniform(8.0, 20.0)), 3),
            "offset": round(float(sign[0] * rng.uniform(0.01, 0.08)), 6),
            "rate": round(float(sign[1] * rng.uniform(10, 80)), 3), "latency": round(float(rng.uniform(0.002, 0.03)), 6),
            "jitter": round(float(rng.uniform(0, 20e-6)), 8), "ppm": round(float(rng.uniform(-20, 20)), 3),
            "backlash": round(float(rng.uniform(0, 3)), 3), "phase": round(float(rng.uniform(0, 6.28)), 3)}


@pytest.mark.machine
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_scan_through_the_executor_aligns_its_streams_and_tabulates_the_targets(tmp_path, seed):
    d = draw(seed)
    config = parse_config(SCAN.format(**d), "scan.toml")
    epochs: list[float] = []

    def seen(hardware, parts, executor):
        epochs.append(parts.plc.handler.notifications.epoch_s)  # the PLC's clock: its stamps are epoch + t

    out = start_campaign(config, tmp_path / "c", opener=open_hardware, on_open=seen)
    assert out.status == "completed" and out.points == out.planned == 4  # 2 passes, up and down
    sweeps = (tmp_path / "c" / "sweeps.csv").read_text().splitlines()
    assert sweeps[0] == "point,run,direction,end,t_s,samples,positions" and len(sweeps) == 5
    positions = np.loadtxt(tmp_path / "c" / "positions.csv", delimiter=",", skiprows=1)
    assert np.all(np.diff(positions[:, 2]) > 0) and len(positions) > 0.9 * out.duration_s * config.instrument.rate_hz  # one per tick (PLC scan)

    table = read_points(tmp_path / "c" / "points.csv")
    assert table.meta["purpose"] == "diagnostic" and table.meta["capture"] == "scan"
    assert sorted(set(table.run.tolist())) == [1, 2] and set(table.direction.tolist()) == {1, -1}
    assert len(table) == 2 * 2 * 7

    # the clock offset found against the truth: instrument = offset + (1 + rate)·t, t the machine's
    # time; the analysis refers the controller's stamps to its first one
    t0 = positions[0, 2] - epochs[0]
    found = float(table.meta["clock_offset_ms"].split("±")[0]) / 1e3
    stated_u = float(table.meta["clock_offset_ms"].split("±")[1]) / 1e3
    t_ref = float(table.meta["clock_reference_s"].split()[0])
    truth = d["offset"] + d["rate"] * 1e-6 * (t_ref + t0) + t0
    assert abs(found - truth) < max(4 * stated_u, 20e-6), (found, truth, stated_u)

    # the mean deviation at each target and direction against the simulated axis at rest
    model = sim_model(config.sim)
    errors = []
    for direction in (1, -1):
        for target in sorted(set(table.target.tolist())):
            mine = (table.direction == direction) & (table.target == target)
            truth_um = float(model.deviation_um(np.array([target]), direction, 0.0, np.inf)[0])
            errors.append(float(np.mean(table.deviation[mine])) - truth_um)
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.35, errors
    profile = (tmp_path / "c" / "profile.csv").read_text().splitlines()
    assert any(line.startswith("position_mm,direction,pass,deviation_um,time_s") for line in profile)


def _lines(path) -> list[bytes]:
    """The whole lines of an appended file (a torn last line left out)."""
    data = path.read_bytes() if path.exists() else b""
    return data[:data.rfind(b"\n") + 1].splitlines(keepends=True)


@pytest.mark.machine
def test_kill_9_during_a_pass_loses_nothing_recorded_and_resume_continues_at_that_pass(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    from tests.conftest import ROOT
    from tests.test_demo_e2e import axiscal

    d = draw(4)
    (tmp_path / "scan.toml").write_text(SCAN.format(**d))
    out = tmp_path / "k"
    proc = subprocess.Popen([sys.executable, "-m", "campaign", "run", str(tmp_path / "scan.toml"), "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while len(_lines(out / "sweeps.csv")) < 4:  # the header and 3 sweeps: pass 2 is under way
        assert proc.poll() is None and time.monotonic() < end, proc.stderr.read() if proc.stderr else ""
        time.sleep(0.02)
    time.sleep(0.3)  # into the rest or the down sweep of pass 2: at least 6 s of machine time
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    assert len(_lines(out / "sweeps.csv")) == 4  # killed before pass 2 was recorded whole
    kept = {name: _lines(out / name) for name in ("raw.csv", "positions.csv", "sweeps.csv", "events.jsonl")}

    resumed = axiscal("resume", out, "--json", timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    for name, lines in kept.items():  # append-only: everything recorded before the kill is still there
        assert _lines(out / name)[:len(lines)] == lines, name
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    resume = next(e for e in events if e["kind"] == "resume")
    assert resume["data"]["first_point"] == 2  # pass 2's up sweep: a resumed scan measures whole passes
    sweeps = [line.split(",")[:3] for line in (out / "sweeps.csv").read_text().splitlines()[1:]]
    assert sweeps == [["0", "1", "+"], ["1", "1", "-"], ["2", "2", "+"], ["2", "2", "+"], ["3", "2", "-"]]

    table = read_points(out / "points.csv")
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 2 * 2 * 7
    assert "pass 2" in table.meta["left_out_1"] and "segments" in table.meta  # each run aligned by itself
    model = sim_model(parse_config(SCAN.format(**d), "scan.toml").sim)
    errors = [float(np.mean(table.deviation[(table.direction == s) & (table.target == t)]))
              - float(model.deviation_um(np.array([t]), s, 0.0, np.inf)[0])
              for s in (1, -1) for t in sorted(set(table.target.tolist()))]
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.35, errors

    # replay: the recorded streams give the same table, and another one with other settings
    same = json.loads(axiscal("replay", out, "--json").stdout)
    assert same["identical"] and same["points"] == len(table)
    # without the rest reference every value moves by its segment's rest step in its direction, exactly
    # (this axis does not settle: a step can be below the table's 1e-4 µm, so no count of changed values)
    from campaign.measure.scan import analyse_recorded_scan
    from campaign.record import open_campaign

    recorded = open_campaign(out)
    steps = {run: {d: r.step for d, r in result.rest.items()}
             for segment, result in analyse_recorded_scan(out, recorded.config(), recorded.plan_for(recorded.config())).segments
             for run in segment.runs}
    moving = json.loads(axiscal("replay", out, "--json", "--moving").stdout)
    changed = {(x["run"], 1 if x["direction"] == "+" else -1, round(x["target"], 6)): x["difference"]
               for x in moving["differences"]}
    assert moving["points"] == len(table) and sorted(steps) == [1, 2]
    for run, s, t in zip(table.run, table.direction, table.target):
        assert abs(changed.get((int(run), int(s), round(float(t), 6)), 0.0) - steps[int(run)].get(int(s), 0.0)) < 1.5e-4
    other = json.loads(axiscal("replay", out, "--json", "--scan-window", "3", "--moving").stdout)
    assert not other["identical"] and other["window"] == 3 and other["rest_reference"] is False
    assert other["points"] == len(table) and all(x["recorded"] is not None and x["replayed"] is not None
                                                 for x in other["differences"])
    for bad in ("11", "0.01"):  # wider than the targets' spacing (offsets included), shorter than the samples'
        refused = axiscal("replay", out, "--scan-window", bad)
        assert refused.returncode == 2 and refused.stderr.startswith("error: --scan-window: ") \
            and len(refused.stderr.strip().splitlines()) == 1, refused.stderr
    offset_only = json.loads(axiscal("replay", out, "--json", "--offset-only").stdout)  # what the rate estimate buys:
    assert offset_only["rate"] is False and not offset_only["identical"]  # tens of ppm over a pass are µm here
    assert max(abs(x["difference"]) for x in offset_only["differences"]) > 0.5

    # the report says what it is: a scan, its clocks, its speed limit, what was left out, no verdict
    assert axiscal("report", out, "-o", tmp_path / "r.html").returncode == 0
    html = (tmp_path / "r.html").read_text()
    for words in ("NOT JUDGED", "captured with the scan method, not an ISO 230-2 test", "Clock offset, ms",
                  "Speed limit", "Left out", "pass 2"):
        assert words in html, words


DIE = """
import os, sys
from campaign.cli import main
from campaign.record.recorder import Recorder

batches, flush = int(sys.argv[3]), sys.argv[4]
seen = {"sweeps": 0, "batches": 0}
sweep, positions = Recorder.sweep, Recorder.positions

def counted(self, *a, **k):
    sweep(self, *a, **k)
    seen["sweeps"] += 1

def dying(self, *a, **k):  # kill -9 at a chosen controller batch after pass 2's up sweep: no buffer flushed
    positions(self, *a, **k)
    seen["batches"] += seen["sweeps"] >= 3
    if seen["batches"] >= batches:
        if flush in ("positions", "torn"):
            self._positions.write("" if flush == "positions" else "12.5,3,17")  # a line cut mid-way
            self._positions.flush()
        if flush == "raw":
            self._raw.flush()
        os._exit(9)

Recorder.sweep, Recorder.positions = counted, dying
main(["run", sys.argv[1], "--out", sys.argv[2]])
"""


@pytest.mark.machine
@pytest.mark.parametrize(("batches", "flush"), [(120, "positions"), (60, "raw"), (60, "torn"), (20, "positions")])
def test_a_kill_at_any_point_of_a_pass_leaves_what_resume_needs_and_no_stream_overlaps(tmp_path, batches, flush):
    """Killed at a chosen controller batch (about 50 ms each) after pass 2's up sweep, with one stream's
    buffer written just before (the two streams are buffered apart: either can be ahead on disk, or end
    in a torn line): the resumed run's campaign time starts after every sample recorded, so no segment
    takes the killed run's last samples; the table is whole and is reproduced from the files."""
    import subprocess
    import sys

    from campaign.measure import resume_campaign
    from campaign.measure.scan import analyse_recorded_scan
    from campaign.plan import build_plan
    from tests.conftest import ROOT

    d = draw(4)
    (tmp_path / "scan.toml").write_text(SCAN.format(**d))
    out = tmp_path / "k"
    died = subprocess.run([sys.executable, "-c", DIE, str(tmp_path / "scan.toml"), str(out), str(batches), flush],
                          cwd=ROOT, capture_output=True, text=True, timeout=300, check=False,
                          env={**os.environ, "AXISCAL_DB": "none"})
    assert died.returncode == 9, died.stderr
    ends = [float(_lines(out / name)[-1].split(b",")[0]) for name in ("raw.csv", "positions.csv")]
    assert len(_lines(out / "sweeps.csv")) == 4
    config = parse_config(SCAN.format(**d), "scan.toml")
    assert resume_campaign(out, opener=open_hardware).status == "completed"
    starts = [json.loads(line)["t_s"] for line in (out / "runs.jsonl").read_text().splitlines()
              if json.loads(line)["record"] == "start"]
    assert len(starts) == 2 and starts[1] >= max(ends) - 1e-3, (starts, ends)
    for name in ("raw.csv", "positions.csv"):  # campaign time never runs back: no two runs share a stretch
        t_s = np.loadtxt(out / name, delimiter=",", skiprows=1, usecols=0)
        assert np.all(np.diff(t_s) >= 0), name
    table = read_points(out / "points.csv")
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 2 * 2 * 7 and "pass 2" in table.meta["left_out_1"]
    again = analyse_recorded_scan(out, config, build_plan(config)).table
    assert np.allclose(again.deviation, table.deviation, atol=1e-4) and np.array_equal(again.target, table.target)
    model = sim_model(config.sim)
    errors = [float(np.mean(table.deviation[(table.direction == s) & (table.target == t)]))
              - float(model.deviation_um(np.array([t]), s, 0.0, np.inf)[0])
              for s in (1, -1) for t in sorted(set(table.target.tolist()))]
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.35, errors


@pytest.mark.machine
def test_a_fault_during_a_sweep_measures_the_pass_again_and_aligns_the_rest_by_itself(tmp_path):
    d = {**draw(5), "velocity": 10.0}
    # the drive faults during the first move after 14 s: the down sweep of pass 1 (it starts at about 12.4 s)
    config = parse_config(SCAN.format(**d) + "[sim.faults.axis_error]\nat_s = 14.0\n", "scan.toml")
    out = start_campaign(config, tmp_path / "c", opener=open_hardware)
    assert out.status == "completed" and out.points == out.planned == 4
    sweeps = [line.split(",")[:3] for line in (tmp_path / "c" / "sweeps.csv").read_text().splitlines()[1:]]
    assert sweeps == [["0", "1", "+"], ["0", "1", "+"], ["1", "1", "-"], ["2", "2", "+"], ["3", "2", "-"]]
    table = read_points(tmp_path / "c" / "points.csv")
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 2 * 2 * 7
    assert "pass 1" in table.meta["left_out_1"]
    model = sim_model(config.sim)
    errors = [float(np.mean(table.deviation[(table.direction == s) & (table.target == t)]))
              - float(model.deviation_um(np.array([t]), s, 0.0, np.inf)[0])
              for s in (1, -1) for t in sorted(set(table.target.tolist()))]
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.35, errors


@pytest.mark.machine
@pytest.mark.parametrize("break_s", [0.5, 5.5])
def test_a_beam_break_during_a_sweep_measures_the_pass_again(tmp_path, break_s):
    d = {**draw(6), "velocity": 10.0}
    # the up sweep of pass 1 runs from about 3 s to 10 s: the beam breaks in it
    config = parse_config(SCAN.format(**d) + f"[sim.faults.beam_break]\nat_s = 6.0\nduration_s = {break_s}\n",
                          "scan.toml")
    out = start_campaign(config, tmp_path / "c", opener=open_hardware)
    assert out.status == "completed" and out.points == out.planned == 4
    events = [json.loads(line) for line in (tmp_path / "c" / "events.jsonl").read_text().splitlines()]
    faults = [e for e in events if e["kind"] == "fault"]
    assert len(faults) == 1 and faults[0]["data"]["error"] == "BeamLost" and faults[0]["point"] == 0
    sweeps = [line.split(",")[:3] for line in (tmp_path / "c" / "sweeps.csv").read_text().splitlines()[1:]]
    assert sweeps == [["0", "1", "+"], ["1", "1", "-"], ["2", "2", "+"], ["3", "2", "-"]]
    table = read_points(tmp_path / "c" / "points.csv")
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 2 * 2 * 7  # every target, every pass


@pytest.mark.machine
def test_a_pass_that_cannot_be_aligned_is_left_out_and_the_others_kept(tmp_path):
    import pandas as pd

    from campaign.measure.scan import analyse_recorded_scan
    from campaign.plan import build_plan

    d = {**draw(7), "velocity": 10.0}
    config = parse_config(SCAN.format(**d), "scan.toml")
    out = start_campaign(config, tmp_path / "c", opener=open_hardware)
    assert out.status == "completed"
    # a hole of 5.5 s in the instrument's stream from the start of pass 2's up sweep (a beam break the
    # old executor let through): that pass cannot be aligned; pass 1, in the same run, can
    sweeps = [line.split(",") for line in (tmp_path / "c" / "sweeps.csv").read_text().splitlines()[1:]]
    start = float(sweeps[1][4]) + 0.5
    raw = pd.read_csv(tmp_path / "c" / "raw.csv")
    raw.loc[(raw.t_s >= start) & (raw.t_s < start + 5.5), "signal_ok"] = 0
    raw.to_csv(tmp_path / "c" / "raw.csv", index=False)
    result = analyse_recorded_scan(tmp_path / "c", config, build_plan(config))
    assert sorted(set(result.table.run.tolist())) == [1] and len(result.table) == 2 * 7
    assert any(why.startswith("pass 2:") for why in result.left_out), result.left_out


@pytest.mark.machine
def test_a_resume_right_after_a_sweep_record_keeps_every_pass_recorded_whole(tmp_path):
    from campaign.errors import CampaignInterrupted
    from campaign.measure import Control, Observer, resume_campaign

    d = {**draw(8), "velocity": 15.0}
    config = parse_config(SCAN.format(**d), "scan.toml")
    control = Control()

    class AbortAfterPass1(Observer):  # the operator's abort, taken between points: no tick after the record
        def emit(self, event):
            if event.kind == "sweep" and event.point == 1:
                control.request_abort("key a")

    with pytest.raises(CampaignInterrupted):
        start_campaign(config, tmp_path / "c", opener=open_hardware, observer=AbortAfterPass1(), control=control)
    runs = [json.loads(line) for line in (tmp_path / "c" / "runs.jsonl").read_text().splitlines()]
    last_sweep_s = float((tmp_path / "c" / "sweeps.csv").read_text().splitlines()[-1].split(",")[4])
    out = resume_campaign(tmp_path / "c", opener=open_hardware)
    assert out.status == "completed"
    starts = [json.loads(line)["t_s"] for line in (tmp_path / "c" / "runs.jsonl").read_text().splitlines()
              if json.loads(line)["record"] == "start"]
    assert len(runs) == 2 and starts[1] == pytest.approx(last_sweep_s, abs=1e-6)  # the case the split got wrong
    table = read_points(tmp_path / "c" / "points.csv")
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 2 * 2 * 7  # pass 1 recorded whole, kept
    assert not any(k.startswith("left_out") for k in table.meta)


@pytest.mark.machine
def test_skip_after_a_fault_during_a_scan_stops_naming_the_pass_and_resume_finishes_it(tmp_path):
    from campaign.measure import resume_campaign

    d = {**draw(5), "velocity": 10.0}
    config = parse_config(SCAN.format(**d).replace("[axis]", "on_fault = \"skip\"\n[axis]", 1)
                          + "[sim.faults.axis_error]\nat_s = 10.0\n", "scan.toml")
    out = start_campaign(config, tmp_path / "c", opener=open_hardware)
    assert out.status == "interrupted" and "pass 1" in out.message and "axiscal resume" in out.message
    assert not (tmp_path / "c" / "points.csv").read_text().strip()  # no table from a scan missing a sweep
    again = resume_campaign(tmp_path / "c", opener=open_hardware)
    assert again.status == "completed" and again.points == again.planned == 4
    table = read_points(tmp_path / "c" / "points.csv")
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 2 * 2 * 7  # every pass recorded whole


@pytest.mark.machine
def test_axiscal_run_with_on_fault_skip_during_a_scan_says_interrupted_and_resume(tmp_path):
    from tests.test_demo_e2e import axiscal

    d = {**draw(5), "velocity": 10.0}
    (tmp_path / "scan.toml").write_text(SCAN.format(**d) + "[sim.faults.axis_error]\nat_s = 10.0\n")
    proc = axiscal("run", tmp_path / "scan.toml", "--out", tmp_path / "c", "--on-fault", "skip")
    assert proc.returncode == 3, (proc.stdout, proc.stderr)
    assert "error:" not in proc.stderr and "campaign interrupted" in proc.stdout
    assert "pass 1" in proc.stdout and "Continue with: axiscal resume" in " ".join(proc.stdout.split())
    assert re.search(r"campaign interrupted: \d/4 sweeps in", proc.stdout), proc.stdout  # a scan's points are sweeps

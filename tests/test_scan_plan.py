"""`axiscal plan` of a scan says the speed that keeps the timing within capture.scan_wanted_u and
warns when capture.scan_velocity is above it (issue 33: "a scan planned faster is warned about"),
from the same timing budget a scan states after it ran (campaign.stream.scan.timing_speed_limit)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import ROOT

DEMO = (ROOT / "data/configs/scan-demo.toml").read_text()


def config_text(rate_hz: float, velocity: float, wanted_u: float, rotary: bool) -> str:
    text = DEMO.replace("rate_hz = 500.0", f"rate_hz = {rate_hz}").replace("scan_velocity = 10.0",
                                                                        f"scan_velocity = {velocity}")
    text = text.replace("[capture]\n", f"[capture]\nscan_wanted_u = {wanted_u}\n")
    if rotary:
        text = (text.replace('kind = "linear"', 'kind = "rotary"').replace('unit = "mm"', 'unit = "deg"')
                .replace("soft_limit_max = 610.0", "soft_limit_max = 350.0").replace("length = 600.0", "length = 300.0"))
    return text


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_plan_states_the_speed_limit_and_warns_a_faster_scan(cli, tmp_path, seed):
    rng = np.random.default_rng([seed, 33])
    rate, wanted = round(float(rng.uniform(100, 1000)), 1), round(float(rng.uniform(0.05, 1.0)), 3)
    rotary = bool(seed % 2)
    scale = 3600.0 if rotary else 1000.0  # deviation unit per axis unit: arcsec/deg, µm/mm
    # before a scan ran, the timing is speed × the 25 µs the simulated machine's scans left at worst,
    # whatever the laser's rate (the clock's wander, not the sample interval, sets it)
    limit = wanted / (25e-6 * scale)
    for velocity, warned in ((round(limit * 0.8, 4), False), (round(limit * 1.3, 4), True)):
        if velocity > 50.0:  # axis.max_velocity
            continue
        path = tmp_path / f"scan-{velocity}.toml"
        path.write_text(config_text(rate, velocity, wanted, rotary))
        got = cli("plan", str(path), "--json")
        assert got.code == 0, got.err
        scan = json.loads(got.out)["scan"]
        assert scan["speed_limit"] == pytest.approx(limit, rel=1e-6, abs=2e-6)
        assert scan["timing_u"] == pytest.approx(velocity * 25e-6 * scale, rel=1e-6, abs=2e-6)
        assert (scan["warning"] is not None) == warned, scan
        text = cli("plan", str(path))
        assert text.code == 0 and f"{limit:.3g} {'deg' if rotary else 'mm'}/s keeps the timing" in " ".join(text.out.split())
        assert ("warning: capture.scan_velocity" in text.out) == warned


def test_the_run_time_limit_is_the_same_budget():
    """A scan's own limit and the planned one are one function of the alignment's uncertainty and
    the jitter: with no jitter, speed × alignment = wanted."""
    from campaign.plan import timing_speed_limit, timing_u

    for alignment_s, rate in ((20e-6, 500.0), (3e-6, 1000.0), (1e-4, 100.0)):
        limit = timing_speed_limit(alignment_s, 0.0, rate, 1.0, 0.2)
        assert limit * alignment_s * 1000 == pytest.approx(0.2, rel=1e-9)
        jittered = timing_speed_limit(alignment_s, 50e-6, rate, 1.0, 0.2)  # jitter only lowers it
        assert jittered < limit and timing_u(jittered, alignment_s, 50e-6, rate, 1.0)[0] == pytest.approx(0.2, rel=1e-6)


def test_the_progress_of_a_scan_counts_sweeps_and_passes():
    """A scan's plan points are its sweeps, two per pass: the bars say so, not points and runs."""
    import io
    import re

    from rich.console import Console

    from campaign.config import parse_config
    from campaign.measure.progress import RichProgress
    from campaign.plan import build_plan
    from campaign.record import Event

    shown = RichProgress("mm")
    shown.console = Console(file=io.StringIO(), width=100, force_terminal=True, color_system=None)
    shown.progress.live.console = shown.console
    plan = build_plan(parse_config(DEMO, "scan-demo.toml"))  # 3 passes: 6 sweeps
    shown.started(plan, list(range(len(plan.points))))
    for p in plan.points[:3]:
        shown.emit(Event(10.0 * (p.index + 1), "sweep", f"sweep {p.index + 1}", p.index,
                         {"run": p.run, "direction": p.direction, "end": p.target, "samples": 10, "positions": 10}))
    shown.progress.refresh()
    shown.progress.stop()
    screen = re.sub(r"\x1b\[[0-9;?]*[a-zA-Z]", "", shown.console.file.getvalue()).replace("\r", "\n")
    last = screen.strip().splitlines()[-2:]
    assert last[0].split()[0] == "sweeps" and "3/6" in last[0], screen
    assert last[1].startswith("pass 2/3") and "1/2" in last[1], screen
    assert "campaign" not in screen and "run " not in screen


def test_resume_takes_the_later_streams_last_sample_as_the_axis_state(tmp_path):
    """A kill leaves raw.csv and positions.csv buffered apart: the resumed run starts from the later
    stream's last whole sample, its time and its position (a torn last line is not read; a last line
    that is not a sample is an error naming the file)."""
    from campaign.errors import InputError
    from campaign.record.directory import POSITION_COLUMNS, last_raw_state
    from campaign.record.recorder import RAW_COLUMNS

    raw = ",".join(RAW_COLUMNS) + "\n" + "12.0,3,,100.5,0.1,1,99" + "," * (len(RAW_COLUMNS) - 7) + "\n"
    (tmp_path / "raw.csv").write_text(raw)
    assert last_raw_state(tmp_path) == (12.0, 100.5)  # no positions.csv: raw's
    header = ",".join(POSITION_COLUMNS) + "\n"
    (tmp_path / "positions.csv").write_text(header)
    assert last_raw_state(tmp_path) == (12.0, 100.5)  # the header alone
    (tmp_path / "positions.csv").write_text(header + "11.9,3,5.0,100.4\n12.2,3,5.3,103.5\n12.25,3,5")
    assert last_raw_state(tmp_path) == (12.2, 103.5)  # positions ahead; its torn line left out
    (tmp_path / "positions.csv").write_text(header + "11.5,3,5.0,95.0\n")
    assert last_raw_state(tmp_path) == (12.0, 100.5)  # raw ahead
    (tmp_path / "positions.csv").write_text(header + "11.5,3,5.0,95.0\nabc\n")
    with pytest.raises(InputError, match="positions.csv"):
        last_raw_state(tmp_path)

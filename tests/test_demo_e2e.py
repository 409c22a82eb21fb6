"""End to end: `axiscal demo` and `axiscal run` on the simulated machine, through the real pyads
client against the loopback ADS test server and the real pyserial over a pty."""

import json
import subprocess
import sys

import numpy as np
import pytest

from campaign.pointtable import read_points
from tests.conftest import ROOT, status

AXISCAL = [sys.executable, "-m", "campaign"]


def axiscal(*args, timeout=120):
    return subprocess.run([*AXISCAL, *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT, check=False)


@pytest.fixture(scope="module")
def demo(demo_campaign):
    """The demo with its fixed 4 s dwell: (its --json result, its directory, the plot)."""
    return demo_campaign()


@pytest.mark.machine
def test_demo_runs_the_paper_campaign(demo):
    data, out, plot = demo
    assert data["dir"] == str(out) and data["status"] == "completed"
    assert data["points"] == 110
    assert 1100 < data["duration_s"] < 1400  # about 20 simulated minutes
    for key in ("A", "E", "M", "B", "R", "A_up", "A_down"):
        assert isinstance(data[key], float), key
    # the same verdict and budget as `analyze` (campaign/assess.py), in the script's own result
    assert data["verdict"] == "pass" and data["uncertainty"]["U_A_um"] > 0
    # Li et al. 2022's horizontal model: about -12.4 um/m over 600 mm, scatter 0.34 um
    assert 5.0 < data["E"] < 10.0 and data["R"] < 3.0
    table = read_points(out / "points.csv")
    assert len(table) == 110 and sorted(set(table.run)) == [1, 2, 3, 4, 5]
    meta = json.loads((out / "meta.json").read_text())
    assert status(out) == "completed" and meta["plan_seed"] == 1 and meta["format_version"] == 2
    assert (out / "config.toml").read_text().startswith("# The embedded demo")
    raw_lines = (out / "raw.csv").read_text().splitlines()
    assert len(raw_lines) > 10000  # every sample of 20 minutes at 10 Hz
    assert plot.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.machine
def test_the_complete_demo_passes_with_its_uncertainty_and_a_tight_tolerance_is_not_judged(demo, cli):
    _, out, _ = demo
    data = json.loads(cli("analyze", out, "--json").out)
    assert data["verdict"] == "pass" and data["uncertainty"]["U_A_um"] > 0
    a, u = data["A"], data["uncertainty"]["U_A_um"]
    tight = json.loads(cli("analyze", out, "--json", "--tolerance", f"{a + u / 2:.3f}").out)
    assert tight["verdict"] == "not judged" and "cannot decide" in tight["reasons"][0]


@pytest.mark.machine
def test_stable_capture_agrees_with_the_dwell_and_waits_at_most_half(demo, demo_campaign):
    data, stable, _ = demo_campaign("--capture", "stable")
    assert data["points"] == 110
    assert data["A"] == pytest.approx(demo[0]["A"], rel=0.05)  # the same axis, the same scatter per approach
    waits = read_points(stable / "points.csv").extra["capture_wait_s"]
    assert np.mean(waits) <= 0.5 * 4.0 and min(waits) >= 0.7  # half the 4 s dwell; never before the window


@pytest.mark.machine
def test_run_refuses_plan_outside_limits_before_moving(tmp_path):
    config = (ROOT / "data/configs/vertical-sim.toml").read_text().replace("overrun = 5.0", "overrun = 50.0")
    path = tmp_path / "c.toml"
    path.write_text(config.replace('model = "../models/', f'model = "{ROOT}/data/models/'))
    proc = axiscal("run", path, "--out", tmp_path / "never")
    assert proc.returncode == 2 and proc.stderr.startswith("error: ") and "soft limits" in proc.stderr
    assert not (tmp_path / "never").exists()


@pytest.mark.machine
@pytest.mark.parametrize("name", ["rotary-sim.toml", "vertical-sim.toml"])
def test_run_example_configs(tmp_path, name):
    proc = axiscal("run", ROOT / "data/configs" / name, "--out", tmp_path / "r", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["status"] == "completed" and data["points"] == data["planned"]
    if name == "vertical-sim.toml":
        assert data["B"] > 350  # the vertical axis' large reversal
        assert data["unit"] == "um"
    else:
        assert data["unit"] == "arcsec"

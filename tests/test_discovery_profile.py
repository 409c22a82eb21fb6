"""Discovery reads a scan's dense profile (issue 33 item 4): `axiscal discover profile.csv` averages
the samples over narrow bins per pass and direction and resolves a screw lead's period from the
dense positions. The scan comes from the simulated streams (drivers/sim/scan_streams.py) with an
instrument clock drawn at random (offset, rate error, wander, jitter, latency), aligned and
profiled by campaign/stream/scan.py as a real scan would be."""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.cli import main
from campaign.discovery.data import PROFILE_BIN, read_profile
from campaign.errors import InputError
from campaign.model import ErrorModel
from campaign.stream.align import ControllerStream, InstrumentStream
from campaign.stream.scan import analyse_scan, write_profile
from drivers.sim.scan_streams import InstrumentClock, scan_machine


def _clock(rng: np.random.Generator) -> InstrumentClock:
    sign = rng.choice([-1.0, 1.0], 2)
    return InstrumentClock(offset_s=float(sign[0] * rng.uniform(0.01, 0.08)),
                           rate_error_ppm=float(sign[1] * rng.uniform(10, 80)),
                           wander_ppm=float(rng.uniform(0, 0.2)), wander_period_s=float(rng.uniform(60, 600)),
                           sample_jitter_s=float(rng.uniform(0, 30e-6)),
                           latency_s=float(rng.uniform(0.002, 0.03)), latency_jitter_s=float(rng.uniform(0, 0.005)))


def _lead_profile(seed: int, path) -> None:
    """profile.csv of a 60 mm scan at 2 mm/s (one bidirectional pass, 500 Hz) of an axis with a 1 µm,
    10 mm screw lead, a scale error and a backlash drawn at random."""
    rng = np.random.default_rng(seed)
    model = ErrorModel({"linear_scale": {"ppm": float(rng.uniform(-15, 15))},
                        "periodic_lead": {"amplitude_um": 1.0, "period_mm": 10.0, "phase_rad": float(rng.uniform(0, 6.28))},
                        "backlash": {"b_um": float(rng.uniform(0, 3))},
                        "noise": {"sigma_um": 0.3, "reading_sigma_um": float(rng.uniform(0.02, 0.2))}})
    machine = scan_machine(model, "mm", 50.0, 200.0, -2.0, _clock(rng), 500.0, seed=seed)
    rec = machine.scan(-2.0, 62.0, 2.0, 1)
    res = analyse_scan(ControllerStream(rec.controller_time_s, rec.controller_position),
                       InstrumentStream(rec.instrument_time_s, rec.instrument_reading), [0.0, 30.0, 60.0], 500.0)
    write_profile(str(path), res)


@pytest.mark.machine
@pytest.mark.parametrize("seed", [71, 72, 73, 74])
def test_discover_resolves_a_screw_lead_from_a_scan_profile(seed, tmp_path, capsys):
    """Issue 33: a 1 µm, 10 mm lead, a 60 mm scan at 2 mm/s: discovery on the profile names the lead
    with its period within 0.5 % and its amplitude within 10 %."""
    path = tmp_path / "profile.csv"
    _lead_profile(seed, path)
    assert main(["discover", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    named = {s["effect"]: s["params"] for s in out["steps"]}
    assert "periodic_lead" in named, out
    assert named["periodic_lead"]["period_mm"] == pytest.approx(10.0, rel=0.005)
    assert named["periodic_lead"]["amplitude_um"] == pytest.approx(1.0, rel=0.10)
    assert any("a scan's profile" in n for n in out["notes"])


def test_a_profile_is_binned_per_pass_and_direction(tmp_path):
    """Bins PROFILE_BIN wide centred on its multiples, the mean of each (a line's mean is its value
    at the centre), only the positions every pass and direction cover, time since the start."""
    rng = np.random.default_rng(5)
    lines = ["# purpose: diagnostic", "position_mm,direction,pass,deviation_um,time_s"]
    t = 100.0
    for p in (1, 2):
        for d, (lo, hi) in ((1, (0.0, 3.0)), (-1, (3.2, -0.1))):
            x = np.arange(lo, hi, 0.004 * np.sign(hi - lo))
            for xi in x:
                t += 0.002
                lines.append(f"{xi:.6f},{'+' if d > 0 else '-'},{p},{2 * xi + d + rng.normal(0, 1e-3):.4f},{t:.6f}")
    path = tmp_path / "profile.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    table, said = read_profile(path)
    targets = np.unique(table.target)
    assert np.allclose(np.diff(targets), PROFILE_BIN)
    assert 0.0 <= targets[0] <= PROFILE_BIN and 3.0 - PROFILE_BIN <= targets[-1] <= 3.0  # the ends half filled or more
    assert sorted(set(table.run.tolist())) == [1, 2] and len(table) == 4 * len(targets)
    assert np.allclose(table.deviation, 2 * table.target + table.direction, atol=0.01)
    assert table.optional["time_s"].min() >= 0 and np.all(np.diff(table.optional["time_s"]) > 0)
    assert table.meta["purpose"] == "diagnostic" and "profile" in said


@pytest.mark.parametrize("text, said", [
    ("position_mm,direction,pass,deviation_um,time_s\n1.0,x,1,0.5,0.1\n", "is not a profile row"),
    ("position_mm,direction,pass,deviation_um,time_s\n1.0,+,1,nan,0.1\n", "not a finite number"),
    ("position_mm,direction,pass,deviation_um,time_s\n1.0,+,1\n", "3 columns"),
    ("position_mm,pass,direction,deviation_um,time_s\n1.0,1,+,0.5,0.1\n", "not a scan profile's header"),
    ("position_mm,direction,pass,deviation_um,time_s\n", "no profile rows"),
])
def test_a_bad_profile_is_one_error_line(tmp_path, capsys, text, said):
    path = tmp_path / "profile.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match=said):
        read_profile(path)
    assert main(["discover", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and said in err and len(err.strip().splitlines()) == 1

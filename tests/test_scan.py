"""The scan's core: two streams on two clocks from the simulated machine (drivers/sim/scan_streams.py),
aligned from the data (campaign/stream/align.py), then the profile, the point table and the timing
budget (campaign/stream/scan.py). Every case is a random draw of clock offset, rate error, latency,
speed, instrument rate and noise; the truth is the simulated axis's own error model."""

from __future__ import annotations

import numpy as np
import pytest

from campaign.assess import assess
from campaign.errors import InputError
from campaign.iso230 import evaluate
from campaign.model import ErrorModel
from campaign.pointtable import parse_points
from campaign.stream.align import ControllerStream, InstrumentStream, align
from campaign.stream.scan import analyse_scan, table_text
from drivers.sim.scan_streams import InstrumentClock, ScanRecord, scan_machine


def _draw(seed: int, speeds: tuple[float, float] = (5.0, 25.0)) -> dict:
    rng = np.random.default_rng(seed)
    sign = rng.choice([-1.0, 1.0], 2)
    return {
        "clock": InstrumentClock(offset_s=float(sign[0] * rng.uniform(0.01, 0.08)),
                                 rate_error_ppm=float(sign[1] * rng.uniform(10, 80)),
                                 wander_ppm=float(rng.uniform(0, 0.2)), wander_period_s=float(rng.uniform(60, 600)),
                                 sample_jitter_s=float(rng.uniform(0, 30e-6)),
                                 latency_s=float(rng.uniform(0.002, 0.03)), latency_jitter_s=float(rng.uniform(0, 0.005))),
        "speed": float(rng.uniform(*speeds)),
        "rate_hz": float(rng.choice([250.0, 500.0, 1000.0])),
        "noise_um": float(rng.uniform(0.02, 0.2)),
        "accel": float(rng.uniform(100.0, 500.0)),
        "model": ErrorModel({"linear_scale": {"ppm": float(rng.uniform(-20, 20))},
                             "backlash": {"b_um": float(rng.uniform(0, 4))},
                             "periodic_lead": {"amplitude_um": float(rng.uniform(0, 1)), "period_mm": 10.0,
                                               "phase_rad": float(rng.uniform(0, 6.28))},
                             "noise": {"sigma_um": 0.3, "reading_sigma_um": 0.0}}),
    }


def _scan(draw: dict, low: float, high: float, passes: int, seed: int) -> ScanRecord:
    draw["model"].effects["noise"]["reading_sigma_um"] = draw["noise_um"]
    machine = scan_machine(draw["model"], "mm", 50.0, draw["accel"], low, draw["clock"], draw["rate_hz"], seed=seed)
    return machine.scan(low, high, draw["speed"], passes)


def _streams(rec: ScanRecord) -> tuple[ControllerStream, InstrumentStream]:
    return (ControllerStream(rec.controller_time_s, rec.controller_position),
            InstrumentStream(rec.instrument_time_s, rec.instrument_reading))


@pytest.mark.parametrize("seed", [11, 12, 13, 14])
def test_the_clocks_are_aligned_from_the_passes_within_their_stated_uncertainty(seed):
    draw = _draw(seed)
    rec = _scan(draw, -3.0, 33.0, 2, seed)
    ctrl, inst = _streams(rec)
    al = align(ctrl, inst)
    clock = draw["clock"]
    true_offset = float(clock.reading(al.t_ref_s)) - al.t_ref_s
    u = float(al.timing_uncertainty_s(al.t_ref_s))
    assert abs(al.offset_s - true_offset) <= max(4 * u, 2e-6), (al.as_dict(), true_offset)
    assert abs(al.offset_s - true_offset) < 20e-6  # a few µs of tens of ms
    assert abs(al.rate_error_ppm - clock.rate_error_ppm) <= 4 * al.rate_uncertainty_ppm + clock.wander_ppm + 0.05
    # every stamp mapped to controller time, over the whole record, within its stated uncertainty
    t_true = clock.controller_time(rec.instrument_time_s)
    error = al.controller_time(rec.instrument_time_s) - t_true
    assert np.all(np.abs(error) <= 4 * al.timing_uncertainty_s(t_true) + 2e-6)
    # and each sample's own instant is off by its jitter only
    jitter = rec.true_time_s - t_true
    assert float(np.std(jitter)) == pytest.approx(clock.sample_jitter_s, rel=0.1, abs=1e-7)


@pytest.mark.parametrize("seed", [21, 22, 23])
def test_the_scan_table_is_the_moving_axis_error_at_the_targets(seed):
    draw = _draw(seed)
    rec = _scan(draw, -3.0, 33.0, 2, seed)
    targets = [0.0, 7.3, 15.1, 22.9, 30.0]
    res = analyse_scan(*_streams(rec), targets, draw["rate_hz"], window=1.0, noise=draw["noise_um"])
    t = res.table
    truth = draw["model"].deviation_um(t.target, t.direction, 0.0, 0.0)  # on the move: no wait, no scatter
    error = t.deviation - truth
    assert len(t) == 2 * 2 * len(targets)
    assert float(np.sqrt(np.mean(error**2))) < 0.1 + 2 * res.budget.deviation_u, res.alignment.as_dict()
    # without the alignment the same data are tens of µm off: the test can fail
    naive = (rec.instrument_reading - np.interp(rec.instrument_time_s, rec.controller_time_s, rec.controller_position))
    assert float(np.max(np.abs(naive))) * 1e3 > 50 * float(np.sqrt(np.mean(error**2)))


def test_the_scan_table_reads_back_and_is_not_judged():
    draw = _draw(31, speeds=(10.0, 10.0))
    rec = _scan(draw, -3.0, 33.0, 2, 31)
    res = analyse_scan(*_streams(rec), [0.0, 10.0, 20.0, 30.0], draw["rate_hz"], noise=draw["noise_um"])
    table = parse_points(table_text(res), "scan.csv")
    assert table.meta["purpose"] == "diagnostic" and table.meta["capture"] == "scan"
    assert np.allclose(table.deviation, res.table.deviation, atol=1e-3)
    a = assess(table, tolerance=100.0)
    assert a.verdict.verdict == "not judged"
    assert any("not an acceptance test" in r for r in a.verdict.reasons)
    assert evaluate(table).summary["A"] is not None


def test_a_scan_too_fast_for_the_wanted_uncertainty_is_warned_about():
    draw = _draw(41, speeds=(25.0, 25.0))
    draw["clock"] = InstrumentClock(offset_s=0.03, rate_error_ppm=30, sample_jitter_s=100e-6)
    draw["rate_hz"] = 250.0
    rec = _scan(draw, -3.0, 33.0, 2, 41)
    res = analyse_scan(*_streams(rec), [0.0, 15.0, 30.0], draw["rate_hz"], wanted_u=0.1, noise=draw["noise_um"])
    assert res.budget.jitter_s == pytest.approx(100e-6, rel=0.3)
    assert res.speed_limit < 25.0
    assert any(w.startswith("too fast") for w in res.warnings)
    slow = analyse_scan(*_streams(rec), [0.0, 15.0, 30.0], draw["rate_hz"], wanted_u=5.0, noise=draw["noise_um"])
    assert not any(w.startswith("too fast") for w in slow.warnings)


def test_streams_without_motion_are_refused():
    t = np.arange(0, 1, 1e-3)
    with pytest.raises(InputError, match="no motion"):
        align(ControllerStream(t, np.zeros_like(t)), InstrumentStream(t, np.zeros_like(t)))

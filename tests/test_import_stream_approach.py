"""import-stream on logs whose axis creeps into each dwell, as a real controller's log showed (a
slow final approach at 0.2 mm/s into 2 s dwells): a dwell's capture starts where the reading stops
approaching, whatever --still-tolerance says, and a capture window that still trends is named
(issue 26 item 1).

The logs: 5 runs over 5 targets (0 to 40 mm), 2 s dwells captured over their last 0.5 s, 1 kHz,
a scale error of -60 ppm and 8 µm of reversal (A about 12.5 µm, B about 8 µm). At 1 kHz a reading
noise of 1 µm moves A and B by up to about 1 % (at 250 Hz, by up to 2.6 % whatever the capture:
the noise alone would fail the 2 %). Each move stops 50 or 100 µm short and creeps in at
0.2 mm/s, decaying (time constants 0.25 and 0.5 s); the controller's dwell begins when the creep is
within 1 µm. The truth is the synthetic machine's own error at each point.
"""

import functools

import numpy as np
import pytest

from campaign.config import parse_config
from campaign.iso230 import evaluate
from campaign.plan import build_plan
from campaign.pointtable import PointTable, read_points
from campaign.stream.importer import StreamImport, extract_points
from campaign.stream.reader import Stream
from campaign.stream.synth import synthetic_stream
from tests.test_import_stream import SMALL

RATE_HZ = 1000.0
APPROACH_SPEED = 0.2  # mm/s
IN_POSITION = 1e-3  # mm
MACHINE = {"ppm": -60.0, "backlash": 8e-3}
APPROACHES = [0.05, 0.1]  # mm crept in at the end of each move
NOISES = [0.3e-3, 1e-3]  # mm
SEEDS = (1, 2, 3)
TOLERANCES = [5, 10, 20, 30]  # µm


def five_runs(kind="linear", unit="mm"):
    text = SMALL.format(kind=kind, unit=unit).replace("cycles = 2", "cycles = 5")
    config = parse_config(text, "five-runs.toml")
    return text, config, build_plan(config)


def creeping_log(config, plan, seed, noise, approach=0.05, rate_hz=RATE_HZ):
    """A fresh copy of the log (each is made once: the tests read it at several tolerances)."""
    frame, truth = _creeping_log(config.text, seed, noise, approach, rate_hz)
    return frame.copy(), truth


@functools.lru_cache(maxsize=16)
def _creeping_log(text, seed, noise, approach, rate_hz):
    config = parse_config(text, "five-runs.toml")
    return synthetic_stream(build_plan(config), config, rate_hz=rate_hz, seed=seed, noise=noise, approach=approach,
                            approach_speed=APPROACH_SPEED, in_position=IN_POSITION, **MACHINE)


def imported(config, plan, frame, still_tolerance) -> StreamImport:
    stream = Stream("log.csv", "reading_mm", frame.time_s.to_numpy(), frame.reading_mm.to_numpy(), {}, [])
    return extract_points(stream, plan, config, still_tolerance)


def true_summary(table: PointTable, truth: np.ndarray) -> dict:
    true = PointTable(kind=table.kind, run=table.run, direction=table.direction, target=table.target,
                      deviation=truth * 1000)
    return evaluate(true).summary


@pytest.mark.machine
@pytest.mark.parametrize("still_tolerance", TOLERANCES)
@pytest.mark.parametrize("noise", NOISES)
@pytest.mark.parametrize("approach", APPROACHES)
def test_a_slow_final_approach_leaves_a_and_b_within_2_percent_at_any_tolerance(approach, noise, still_tolerance):
    """The acceptance point: A and B within 2 % of the truth at every tolerance from 5 to 30 µm
    (over these 12 logs: A -1.7 to +0.6 %, B -1.6 to +0.1 %, the same at every tolerance; the
    100 µm creep leaves about 0.03 µm in the log's own capture windows, -0.8 % of A and -0.9 % of B).
    Before, the level a dwell's end was judged against was taken while the axis still crept in,
    and the creep that followed was taken for the next move: A from -57 to +1 % at 5 µm, -54 to
    +41 % at 10 µm, +22 to +199 % at 20 µm, +106 to +368 % at 30 µm (B -96 to +543 %)."""
    _, config, plan = five_runs()
    tau = approach / APPROACH_SPEED  # s
    creep_left_um = IN_POSITION * np.exp(-(2.0 - 0.5) / tau) * 1000  # at the controller's own capture
    for seed in SEEDS:
        frame, truth = creeping_log(config, plan, seed, noise, approach)
        result = imported(config, plan, frame, still_tolerance)
        got, true = evaluate(result.table).summary, true_summary(result.table, truth)
        for key in ("A", "B"):
            assert got[key] == pytest.approx(true[key], rel=0.02), (seed, key, got[key], true[key])
        # each point within 5 standard errors of its truth, plus the creep the log itself still holds
        se_um = noise * 1000 / np.sqrt(result.table.optional["samples"])
        assert np.all(np.abs(result.table.deviation - truth * 1000) < 5 * se_um + creep_left_um), seed
        assert np.all(result.table.optional["capture_still"] == 1), seed
        assert not result.warnings, seed


@pytest.mark.parametrize("rate_hz", [10.0, RATE_HZ])
def test_the_capture_does_not_move_with_the_still_tolerance(rate_hz):
    """A loose tolerance widens the search, never the capture: the same capture windows (to two
    samples) and the same deviations (to half a standard error) at every tolerance, at 1 kHz and at
    10 Hz (5 samples per capture window: a window whose last sample has begun the next move must
    not pass for still; it did when the window's own scatter was the noise, A +30 % at 30 µm)."""
    _, config, plan = five_runs()
    frame, _ = creeping_log(config, plan, seed=1, noise=0.3e-3, approach=0.1, rate_hz=rate_hz)
    tables = [imported(config, plan, frame, tolerance).table for tolerance in TOLERANCES]
    se_um = 0.3 / np.sqrt(tables[0].optional["samples"])
    for tolerance, table in zip(TOLERANCES, tables, strict=True):
        assert np.max(np.abs(table.optional["time_s"] - tables[0].optional["time_s"])) <= 2 / rate_hz, tolerance
        assert np.all(np.abs(table.deviation - tables[0].deviation) <= se_um / 2), tolerance
        assert np.all(table.optional["capture_still"] == 1), tolerance


def test_a_dwell_that_never_settles_is_named_and_its_trend_reported():
    """One dwell (point 8) arrives 6 µm short and creeps in at a steady 3 µm/s over the whole
    dwell, on a log that is otherwise still: that point alone is flagged, with its trend (about
    1.5 µm over the 0.5 s window, in the approach direction), and the warning says its value is
    biased."""
    _, config, plan = five_runs()
    frame, truth = creeping_log(config, plan, seed=2, noise=0.3e-3)
    ends_s = imported(config, plan, frame, 5).table.optional["time_s"]
    end_s, direction = ends_s[7], plan.points[7].direction
    t = frame.time_s.to_numpy()
    short = 6e-3 * np.clip((end_s - t) / 2.0, 0, 1) * (t > ends_s[6] + 0.1)  # mm, from during the move
    frame["reading_mm"] -= direction * short
    for tolerance in TOLERANCES:
        result = imported(config, plan, frame, tolerance)
        still = result.table.optional["capture_still"]
        assert list(np.flatnonzero(still == 0)) == [7], tolerance
        trend = result.table.optional["capture_trend_um"][7]
        assert direction * trend == pytest.approx(1.5, abs=0.3), tolerance
        assert len(result.warnings) == 1, result.warnings
        warning = result.warnings[0]
        sign = "+" if direction > 0 else "-"
        for fragment in ("1 of 50 points were captured while the reading still moved", f"points 8 {sign}1.5 µm",
                         "1 of them still approaching", "biased by the approach", "capture_still"):
            assert fragment in warning, (fragment, warning)
        others = np.delete(np.arange(len(truth)), 7)
        se_um = 0.3 / np.sqrt(result.table.optional["samples"][others])
        assert np.all(np.abs(result.table.deviation[others] - truth[others] * 1000) < 5 * se_um + 0.01)


def test_the_stillness_columns_and_summary_line(tmp_path, cli):
    """The point table carries each capture window's trend and scatter (µm, or arcsec on a rotary
    axis), whether it was still, and the reading noise it was judged against; the command says how
    many were still."""
    text, config, plan = five_runs()
    (tmp_path / "c.toml").write_text(text)
    frame, _ = creeping_log(config, plan, seed=3, noise=0.5e-3, rate_hz=250.0)
    frame.to_csv(tmp_path / "log.csv", index=False)
    result = cli("import-stream", tmp_path / "log.csv", "--config", tmp_path / "c.toml", "-o", tmp_path / "p.csv",
                 "--still-tolerance", "30")
    assert result.code == 0, result.err
    assert "capture windows: 50 of 50 still (no trend beyond the reading noise, 0.5" in result.out
    table = read_points(tmp_path / "p.csv")
    assert set(table.extra) >= {"capture_trend_um", "capture_scatter_um", "capture_still"}
    assert float(table.meta["reading_noise_um"]) == pytest.approx(0.5, rel=0.1)
    assert np.median(table.extra["capture_scatter_um"]) == pytest.approx(0.5, rel=0.1)
    assert np.all(table.extra["capture_still"] == 1)

    text, config, plan = five_runs("rotary", "deg")
    (tmp_path / "r.toml").write_text(text)
    frame, _ = synthetic_stream(plan, config, rate_hz=250.0, seed=3, noise=1e-5)
    frame.to_csv(tmp_path / "rot.csv", index=False)
    result = cli("import-stream", tmp_path / "rot.csv", "--config", tmp_path / "r.toml", "-o", tmp_path / "r.csv")
    assert result.code == 0, result.err
    assert "arcsec" in result.out.split("capture windows:")[1]
    table = read_points(tmp_path / "r.csv")
    assert np.median(table.extra["capture_scatter_arcsec"]) == pytest.approx(1e-5 * 3600, rel=0.1)
    assert float(table.meta["reading_noise_arcsec"]) == pytest.approx(1e-5 * 3600, rel=0.1)

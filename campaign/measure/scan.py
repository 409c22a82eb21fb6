"""A recorded scan's results: its two streams read back from the campaign directory, aligned and
turned into the profile and the point table at the plan's targets (campaign.stream.scan), with the
scan's settings or others (replay).

The streams: raw.csv holds the instrument's readings with the instrument's own stamps
(`instrument_time_s`); positions.csv the controller's actual position with the controller's own
stamps (`controller_time_s`, s since 1970 from the PLC's FILETIME). A resumed scan holds one
segment per run of the executor (runs.jsonl): after a restart neither clock need continue where
it stopped, so each segment is aligned by itself and its passes numbered on from the last
segment's. Times in s, positions in the axis unit, deviations in µm (arcsec on a rotary axis).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from campaign.config import Config
from campaign.errors import InputError
from campaign.plan import Plan
from campaign.record import Recorder, load_raw, read_json_lines
from campaign.stream.align import ControllerStream, InstrumentStream
from campaign.stream.scan import ScanResult, analyse_scan, table_text

POSITIONS_FILE = "positions.csv"


@dataclass(frozen=True)
class ScanSettings:
    """How a recorded scan is evaluated: the window about each target (axis unit), the wanted
    timing uncertainty (deviation unit), and whether the rest steps are removed."""

    window: float
    wanted_u: float
    rest_reference: bool = True


def settings_of(config: Config) -> ScanSettings:
    return ScanSettings(config.capture.scan_window, config.capture.scan_wanted_u)


def scan_streams(directory: Path) -> tuple[ControllerStream, InstrumentStream]:
    """Both recorded streams of a scan (the whole record, every segment)."""
    import pandas as pd

    path = directory / POSITIONS_FILE
    if not path.is_file():
        raise InputError(f"{directory}: not a recorded scan (no {POSITIONS_FILE})")
    try:
        ctrl = pd.read_csv(path)
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(f"{path}: cannot read the controller's stream ({exc})") from None
    ctrl = ctrl.drop_duplicates("controller_time_s").sort_values("controller_time_s")
    raw = load_raw(directory)
    good = raw[(raw.signal_ok == 1) & raw.reading.notna() & raw.instrument_time_s.notna()]
    return (ControllerStream(ctrl.controller_time_s.to_numpy(float), ctrl.actual_position.to_numpy(float)),
            InstrumentStream(good.instrument_time_s.to_numpy(float), good.reading.to_numpy(float)))


def analyse_recorded_scan(directory: str | Path, config: Config, plan: Plan,
                          settings: ScanSettings | None = None) -> ScanResult:
    """Align, profile and tabulate the scan recorded in `directory` (`settings`: the config's, or
    others). InputError when the streams do not hold a scan that can be aligned."""
    path = Path(directory)
    s = settings or settings_of(config)
    ctrl, inst = scan_streams(path)
    if len(ctrl.time_s) < 10 or len(inst.time_s) < 10:
        raise InputError(f"{path}: the scan's streams hold too few samples to align")
    t0 = float(ctrl.time_s[0])  # the controller's stamps are s since 1970: referred to its first
    ctrl = ControllerStream(ctrl.time_s - t0, ctrl.position)
    try:
        return analyse_scan(ctrl, inst, plan.targets, config.instrument.rate_hz, window=s.window,
                            wanted_u=s.wanted_u, kind=config.axis.kind, rest_reference=s.rest_reference,
                            average_s=config.capture.average_s)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise InputError(f"{path}: the scan could not be aligned ({exc})") from None


def finish_scan(recorder: Recorder, config: Config, plan: Plan) -> ScanResult:
    """Every sweep recorded: the point table and the profile, written into the campaign directory."""
    result = analyse_recorded_scan(recorder.dir, config, plan)
    recorder.scan_results(table_text(result), result.profile.csv_text())
    return result


def run_starts(directory: Path) -> list[float]:
    """Campaign times (s) at which the executor started, from runs.jsonl."""
    return [float(r["t_s"]) for r in read_json_lines(directory / "runs.jsonl") if r.get("record") == "start"]

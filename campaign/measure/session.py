"""One campaign from config to recorded directory: plan, limit check, hardware, recording, run.

Used by `run`, `demo`, `resume` and `guide`. The limits are checked before any hardware is opened.
The hardware factory is imported lazily: `campaign/` itself never imports pyads or serial.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from pathlib import Path

from campaign.config import Config
from campaign.errors import InputError
from campaign.iso230 import Evaluation, evaluate
from campaign.measure.executor import CampaignStopped, Control, Executor, Observer
from campaign.model import ErrorModel
from campaign.plan import Move, Plan, build_plan, check_plan
from campaign.pointtable import read_points
from campaign.record.recorder import Recorder


@dataclass
class Outcome:
    """How a campaign ended. duration_s: campaign time (simulated on the simulated machine), s."""

    dir: Path
    status: str
    points: int
    planned: int
    duration_s: float
    message: str = ""


def default_out_dir(config: Config) -> Path:
    stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{config['campaign']['machine']}-{config['axis']['name']}-{stamp}"


def campaign_meta(config: Config, plan: Plan) -> dict:
    c, a = config["campaign"], config["axis"]
    return {"machine": c["machine"], "axis": a["name"], "operator": c["operator"], "kind": a["kind"],
            "unit": a["unit"], "plan_seed": plan.seed, "points_planned": len(plan.points),
            "targets": list(plan.targets), "offsets": list(plan.offsets),
            "capture": config["capture"]["method"], "driver": config["axis_driver"]["type"]}


def open_hardware(config: Config, speed: float | None = None, model: ErrorModel | None = None,
                  start: float | None = None, start_time: float = 0.0):
    """The config's hardware: (Hardware, SimParts or None). Lazy import: see the module docstring.
    `start` (axis unit) and `start_time` (s): where and when a simulated machine starts."""
    from drivers.factory import open_hardware as factory_open

    return factory_open(config, speed=speed, model=model, start_position=start, start_time=start_time)


def execute(config: Config, plan: Plan, recorder: Recorder, first_point: int, *, speed=None, model=None,
            observer: Observer | None = None, t_offset: float = 0.0, start: float | None = None,
            on_open=None, control: Control | None = None, opened=None) -> Outcome:
    """Run `plan` from `first_point` into `recorder`, then mark the directory completed or
    interrupted. Re-raises KeyboardInterrupt after the axis is halted and the recording flushed.
    `opened`: a (Hardware, SimParts | None) pair from `open_hardware` to use instead of opening
    new hardware (it is closed at the end either way)."""
    hardware, sim = opened if opened is not None else open_hardware(config, speed, model, start, t_offset)
    executor = Executor(plan, config, hardware, recorder, observer, t0=hardware.clock.now() - t_offset,
                        control=control)
    if sim is not None and sim.faults is not None:
        sim.faults.on_disk_full = recorder.inject_disk_full
    if on_open:
        on_open(hardware, sim, executor)
    status, message = "failed", "stopped by an unexpected error"
    try:
        executor.run(first_point)
        status, message = "completed", ""
    except CampaignStopped as exc:
        status, message = "interrupted", str(exc)
    except KeyboardInterrupt:
        status, message = "interrupted", "Ctrl-C"
        raise
    except InputError as exc:  # e.g. a SafetyError: a motion refused before it was sent
        status, message = "interrupted", str(exc)
        raise
    finally:
        duration = executor.now()
        for failure in hardware.close():
            message = f"{message}; closing: {failure}"
        try:
            recorder.set_status(status, duration_s=round(duration, 3), message=message)
        except OSError as exc:  # e.g. the disk is full: the directory stays "running", resumable
            message = f"{message}; could not update meta.json: {exc}"
        try:
            recorder.close()
        except OSError as exc:
            message = f"{message}; could not flush the recording: {exc}"
    return Outcome(recorder.dir, status, recorder.points_written, len(plan.points), duration, message)


SIM_MODEL_FILE = "sim-model.toml"
"""The simulated machine's effective error model, kept in the campaign directory for resume."""


def start_campaign(config: Config, out: str | Path | None = None, meta_extra: dict | None = None,
                   on_created=None, **kwargs) -> Outcome:
    """A new campaign from `config` into `out` (a new directory); `meta_extra` goes into meta.json."""
    plan = build_plan(config)
    check_plan(plan, config)
    if config["axis_driver"]["type"] == "sim" and kwargs.get("model") is None:
        from drivers.factory import sim_model

        kwargs["model"] = sim_model(config)
    directory = Path(out) if out else default_out_dir(config)
    meta = {**campaign_meta(config, plan), **(meta_extra or {})}
    try:
        recorder = Recorder.create(directory, config.text, meta, config["axis"]["kind"])
    except BaseException:
        if kwargs.get("opened") is not None:
            kwargs["opened"][0].close()
        raise
    if kwargs.get("model") is not None:
        (directory / SIM_MODEL_FILE).write_text(kwargs["model"].to_toml(), encoding="utf-8")
    if on_created is not None:
        on_created(directory)
    return execute(config, plan, recorder, 0, **kwargs)


def last_raw_state(directory: Path) -> tuple[float, float | None]:
    """(campaign time of the last raw sample in s, last known axis position or None)."""
    from campaign.measure.replay import load_raw

    raw = load_raw(directory)
    if raw.empty:
        return 0.0, None
    positions = raw.axis_position.dropna()
    return float(raw.t_s.iloc[-1]), float(positions.iloc[-1]) if len(positions) else None


def resume_campaign(directory: str | Path, faults: dict | None = None, **kwargs) -> Outcome:
    """Continue an interrupted campaign in `directory` from the point after the last recorded one,
    re-approaching it from the overrun in its own direction, appending to the same files.
    `faults`: a [sim.faults] table to rehearse in the resumed part (the config's own faults are not
    injected again)."""
    from campaign.config import load_config
    from campaign.errors import InputError
    from campaign.model import read_model

    path = Path(directory)
    if not (path / "meta.json").is_file() or not (path / "config.toml").is_file():
        raise InputError(f"{path}: not a campaign directory (no meta.json / config.toml)")
    config = load_config(path / "config.toml")
    config.sections["sim"].pop("faults", None)  # rehearsed faults are not injected again on resume
    if faults:
        config.sections["sim"]["faults"] = faults
    if json.loads((path / "meta.json").read_text(encoding="utf-8")).get("status") == "completed":
        raise InputError(f"{path}: the campaign is already completed")
    plan = build_plan(config)
    check_plan(plan, config)  # before anything is touched
    recorder = Recorder.reopen(path)
    if recorder.meta.get("points_planned") != len(plan.points):
        recorder.close()
        raise InputError(f"{path}: config.toml no longer gives the recorded plan")
    done = recorded_point_indices(path)
    first = max(done) + 1 if done else 0
    skipped = sorted(set(range(first)) - set(done))
    if first >= len(plan.points):
        recorder.set_status("completed")
        recorder.close()
        return Outcome(path, "completed", len(done), len(plan.points), 0.0, "nothing left to measure")
    t_last, position = last_raw_state(path)
    if (path / SIM_MODEL_FILE).exists() and kwargs.get("model") is None:
        kwargs["model"] = read_model(path / SIM_MODEL_FILE)
    from campaign.measure.verify import load_comp, open_compensated

    comp = load_comp(path)
    if comp is not None:  # a verification campaign: the PLC gets its table again first
        kwargs["opened"] = open_compensated(config, comp, kwargs.get("speed"), kwargs.get("model"), position,
                                            t_last)
    recorder.event(t_last, "resume", f"resumed at point {first} of {len(plan.points)}")
    if skipped:  # skipped by the operator: they stay missing (a follow-up campaign can fill them)
        recorder.event(t_last, "resume", f"points skipped earlier stay missing: {skipped}")
    return execute(config, plan, recorder, first, t_offset=t_last, start=position, **kwargs)


def recorded_point_indices(directory: Path) -> list[int]:
    """The plan indices of the points recorded in points.csv (its `point` column); none while the
    file holds no row yet."""
    if not any(ln[:1].isdigit() for ln in (directory / "points.csv").read_text(encoding="utf-8").splitlines()):
        return []
    return [int(i) for i in read_points(directory / "points.csv", partial=True).extra["point"]]


def analyse_dir(directory: str | Path) -> tuple[object, Evaluation]:
    """Read a campaign directory's point table and evaluate it to ISO 230-2:2014."""
    table = read_points(Path(directory) / "points.csv")
    return table, evaluate(table)


def dry_run(config: Config, ticks: int = 10, opened=None) -> dict:
    """Talk to the controller read-only and walk the plan: nothing is commanded.

    Reads the axis status, checks every move of the plan against the limits, and reads `ticks`
    sample periods of the interferometer. Returns what it saw (positions in axis unit).
    `opened`: hardware already opened read-only (tests inspect the simulated PLC afterwards)."""
    from campaign.plan import estimate_duration_s

    plan = build_plan(config)
    check_plan(plan, config)
    config.sections["axis_driver"] = {**config["axis_driver"], "read_only": True}
    hardware, _ = opened if opened is not None else open_hardware(config)
    try:
        status = hardware.axis.status()
        readings = []
        for _ in range(ticks):
            hardware.clock.sleep(1.0 / config["instrument"]["rate_hz"])
            readings.extend(hardware.interferometer.poll())
    finally:
        hardware.close()
    last = readings[-1] if readings else None
    return {"read_only": True, "axis_enabled": status.enabled, "axis_homed": status.homed,
            "axis_error": status.error, "axis_error_id": status.error_id,
            "axis_position": status.actual_position, "readings": len(readings),
            "beam_ok": bool(last and last.signal_ok), "reading": last.position if last else None,
            "points": len(plan.points), "moves": sum(isinstance(s, Move) for s in plan.steps),
            "travel": plan.travel(), "estimated_duration_s": estimate_duration_s(plan, config),
            "plan_within_limits": True}

"""One campaign from config to recorded directory: plan, limit check, hardware, recording, run.

Used by `run`, `demo`, `resume` and `guide`. The limits are checked before any hardware is opened.
The hardware factory is imported lazily: `campaign/` itself never imports pyads or serial.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path

from campaign.config import Config
from campaign.executor import CampaignStopped, Executor, Observer
from campaign.iso230 import Evaluation, evaluate
from campaign.model import ErrorModel
from campaign.plan import Plan, build_plan, check_plan
from campaign.pointtable import read_points
from campaign.recording import Recorder


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


def _open(config: Config, speed: float | None, model: ErrorModel | None, start: float | None):
    from drivers.factory import open_hardware

    return open_hardware(config, speed=speed, model=model, start_position=start)


def execute(config: Config, plan: Plan, recorder: Recorder, first_point: int, *, speed=None, model=None,
            observer: Observer | None = None, t_offset: float = 0.0, start: float | None = None,
            on_open=None) -> Outcome:
    """Run `plan` from `first_point` into `recorder`, then mark the directory completed or
    interrupted. Re-raises KeyboardInterrupt after the axis is halted and the recording flushed."""
    hardware, sim = _open(config, speed, model, start)
    executor = Executor(plan, config, hardware, recorder, observer, t0=hardware.clock.now() - t_offset)
    if on_open:
        on_open(hardware, sim, executor)
    status, message = "completed", ""
    try:
        executor.run(first_point)
    except CampaignStopped as exc:
        status, message = "interrupted", str(exc)
    except KeyboardInterrupt:
        status, message = "interrupted", "Ctrl-C"
        raise
    finally:
        duration = executor.now()
        hardware.close()
        recorder.set_status(status, duration_s=round(duration, 3), message=message)
        recorder.close()
    return Outcome(recorder.dir, status, recorder.points_written, len(plan.points), duration, message)


def start_campaign(config: Config, out: str | Path | None = None, **kwargs) -> Outcome:
    """A new campaign from `config` into `out` (a new directory)."""
    plan = build_plan(config)
    check_plan(plan, config)
    directory = Path(out) if out else default_out_dir(config)
    recorder = Recorder.create(directory, config.text, campaign_meta(config, plan), config["axis"]["kind"])
    return execute(config, plan, recorder, 0, **kwargs)


def analyse_dir(directory: str | Path) -> tuple[object, Evaluation]:
    """Read a campaign directory's point table and evaluate it to ISO 230-2:2014."""
    table = read_points(Path(directory) / "points.csv")
    return table, evaluate(table)

"""A simulated history of one axis, for the demo and the tests: the demo's axis (the horizontal
axis of Li et al. 2022, campaign/demo.toml) re-checked N times over some years while its lead
error grows at a known rate and its reversal value jumps once (a crash, say).

Each re-check is a full ISO 230-2 campaign of the demo's plan (11 targets × 2 directions × 5
runs), simulated by the fast simulator (campaign/discovery/simulate.py: the same error model and
noise as the simulated machine, without the ADS server, the pty and the executor's ticks; a
campaign in milliseconds instead of seconds), and written as a real campaign directory by the
campaign recorder (campaign.record), so that everything that reads campaign directories reads it.
meta.json marks it simulated, names the simulator, and holds the truth of that re-check
(`simulated_history`); its `created` is the simulated date of the re-check, not when it was
written (`written` says that).

Units: the lead error in µm/m (ppm) of travel, its growth in µm/m per year, the reversal in µm.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from campaign.config import Config, config_toml, config_with, parse_config, plain, recorded_sections
from campaign.discovery.simulate import simulate_campaign
from campaign.model import sim_model
from campaign.plan import build_plan, plan_records
from campaign.record import Event, Recorder, RunState, StateData

SIMULATOR = "fast simulator (campaign/discovery/simulate.py): the simulated machine's error model and noise, no ADS or pty"
DAY = dt.timedelta(days=1)
TOLERANCE_UM = 15.0
"""The tolerance on A the simulated re-checks state, µm. With the lead error growing from −1 to
−11 µm/m over two years (5 µm/m a year over 600 mm: A grows about 2 µm a year), A + U is about
11.5 µm at the last re-check and reaches 15 µm about a year and a half later."""
ROOM: dict[str, float | None] = {"air_temp_c": 20.0, "air_pressure_hpa": 1013.25, "humidity_pct": 50.0,
                                 "material_temp_c": 20.0}
"""The environment each simulated point records: the simulated machine's room at its set values
(drivers/sim/machine.py, without its slow 30-minute swing), so the uncertainty budget is complete
and a re-check gets a verdict, as a campaign on the simulated machine does. At 20 °C the material
correction is zero, and the instrument reports air-compensated lengths as on the demo."""


@dataclass(frozen=True)
class HistoryTruth:
    """What the simulated axis really did. lead_ppm_end: the linear lead error at the last
    re-check, µm/m; growth_ppm_per_year: how fast its magnitude grows, µm/m per year;
    backlash_um: the reversal after the jump (0 before); jump_after: the re-check (1-based) after
    which it jumped (0: no jump); span_mm: the travel measured; tolerance_um: the tolerance on A
    the re-checks' config states."""

    campaigns: int
    years: float
    lead_ppm_end: float
    growth_ppm_per_year: float
    backlash_um: float
    jump_after: int
    span_mm: float
    seed: int
    tolerance_um: float

    @property
    def lead_growth_um_per_year(self) -> float:
        """The growth of the lead error over the travel, µm per year: the drift of E and A."""
        return self.growth_ppm_per_year * self.span_mm / 1000.0

    def lead_ppm(self, years_before_end: float) -> float:
        """The (negative) lead error at a time before the last re-check, µm/m."""
        return self.lead_ppm_end + self.growth_ppm_per_year * years_before_end

    def as_json(self) -> dict:
        return {"campaigns": self.campaigns, "years": self.years, "lead_ppm_end": self.lead_ppm_end,
                "growth_ppm_per_year": self.growth_ppm_per_year,
                "lead_growth_um_per_year": round(self.lead_growth_um_per_year, 6),
                "backlash_um_after_jump": self.backlash_um, "jump_after_campaign": self.jump_after,
                "span_mm": self.span_mm, "seed": self.seed, "tolerance_um": self.tolerance_um}


def demo_text() -> str:
    return resources.files("campaign").joinpath("demo.toml").read_text(encoding="utf-8")


def demo_config() -> Config:
    """The demo's config (campaign/demo.toml), which every re-check changes (recheck_config)."""
    return parse_config(demo_text(), "demo.toml (simulated history)")


def recheck_config(base: Config, lead_ppm: float, backlash_um: float, seed: int, machine: str = "",
                   tolerance_um: float = TOLERANCE_UM) -> Config:
    """The demo's config with the lead error (µm/m), the reversal (µm), the noise seed and the
    tolerance on A (µm) of one re-check, and another machine name when given (validated again)."""
    effects = plain(base.sim.effects or {})
    effects["linear_scale"] = {**effects.get("linear_scale", {}), "ppm": lead_ppm}
    if backlash_um:
        effects["backlash"] = {"b_um": backlash_um}
    campaign: dict[str, object] = {"tolerance": tolerance_um}
    if machine:
        campaign["machine"] = machine
    return config_with(base, {"campaign": campaign, "sim": {"seed": seed, "effects": effects}})


def recheck_dates(count: int, years: float, end: dt.datetime, rng: np.random.Generator) -> list[dt.datetime]:
    """`count` dates from `years` before `end` to `end`, evenly spread, each but the first and last
    moved by up to ±10 days (re-checks are not kept to the day)."""
    if count == 1:
        return [end]
    span = dt.timedelta(days=365.25 * years)
    dates = [end - span + span * i / (count - 1) for i in range(count)]
    return [d if i in (0, count - 1) else d + DAY * float(rng.uniform(-10, 10)) for i, d in enumerate(dates)]


def write_campaign(directory: Path, config: Config, created: dt.datetime, truth: dict, seed: int) -> Path:
    """Simulate one campaign of `config` and write it as a campaign directory dated `created`."""
    plan = build_plan(config)
    table = simulate_campaign(config, sim_model(config.sim), seed=seed)
    sections = recorded_sections(config)
    c, a = config.campaign, config.axis
    meta = {"machine": c.machine, "axis": a.name, "operator": c.operator, "kind": a.kind, "unit": a.unit,
            "plan_seed": plan.seed, "points_planned": len(plan.points), "targets": list(plan.targets),
            "offsets": list(plan.offsets), "capture": config.capture.method, "driver": config.controller.type,
            "simulated": True, "simulator": SIMULATOR, "simulated_history": truth,
            "created": created.isoformat(timespec="seconds"),
            "written": dt.datetime.now(dt.UTC).isoformat(timespec="seconds")}
    recorder = Recorder.create(directory, config_toml(config.data), sections, plan_records(plan, sections), meta, a.kind)
    try:
        recorder.start(0.0, 0, len(plan.points))
        times = table.optional["time_s"]
        for i in range(len(table)):
            target, deviation = float(table.target[i]), float(table.deviation[i])
            recorder.point(int(table.run[i]), int(table.direction[i]), target, deviation, float(times[i]), ROOM,
                           {"point": i, "reading": target + deviation / 1000.0, "air_correction_um": 0.0,
                            "material_correction_um": 0.0, "capture_wait_s": float(table.optional["capture_wait_s"][i]),
                            "samples": float(table.optional["samples"][i])})
        end = float(times[-1])
        recorder.emit(Event(end, "state", "idle -> stopped: completed (simulated re-check)", None,
                            StateData(state=RunState.STOPPED, previous=RunState.IDLE, reason="completed")))
        recorder.emit(Event(end, "stop", f"simulated re-check: {len(table)} points", data={
            "status": "completed", "points": len(table)}))
        recorder.stop(end, "completed", "all points measured (simulated re-check)")
    finally:
        recorder.close()
    return directory


def simulate_history(out: str | Path, campaigns: int = 12, years: float = 2.0, lead_ppm_end: float = -11.0,
                     growth_ppm_per_year: float = 5.0, backlash_um: float = 2.5, seed: int = 1,
                     end: dt.datetime | None = None, machine: str = "",
                     tolerance_um: float = TOLERANCE_UM) -> tuple[HistoryTruth, list[Path]]:
    """Write `campaigns` re-checks of the demo axis into `out`/recheck-NN-DATE, the last at `end`
    (default now, UTC): the lead error's magnitude grows by `growth_ppm_per_year` and reaches
    `lead_ppm_end` at the last; the reversal jumps from 0 to `backlash_um` after re-check
    round(0.6·N) (none for fewer than 3). Each re-check has its own noise (seed + its number)."""
    rng = np.random.default_rng(seed)
    end = end or dt.datetime.now(dt.UTC).replace(microsecond=0, tzinfo=None)
    base = demo_config()
    jump_after = round(0.6 * campaigns) if campaigns >= 3 else 0
    targets = build_plan(base).targets  # the same in every re-check
    span = float(max(targets) - min(targets))
    truth = HistoryTruth(campaigns, years, lead_ppm_end, growth_ppm_per_year, backlash_um, jump_after, span, seed,
                         tolerance_um)
    dates = recheck_dates(campaigns, years, end, rng)
    root = Path(out)
    written = []
    for number, when in enumerate(dates, start=1):
        before_end = (end - when).total_seconds() / (365.25 * 86400)
        lead = truth.lead_ppm(before_end)
        reversal = backlash_um if jump_after and number > jump_after else 0.0
        config = recheck_config(base, round(lead, 6), reversal, seed + number, machine, tolerance_um)
        this = {**truth.as_json(), "recheck": number, "lead_ppm": round(lead, 6), "backlash_um": reversal}
        directory = root / f"recheck-{number:02d}-{when.date().isoformat()}"
        written.append(write_campaign(directory, config, when.replace(tzinfo=dt.UTC), this, seed + number))
    return truth, written

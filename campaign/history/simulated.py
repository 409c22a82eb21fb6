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
from typing import TYPE_CHECKING

import numpy as np

from campaign.config import Config, config_toml, config_with, parse_config, plain, recorded_sections
from campaign.discovery.simulate import simulate_campaign
from campaign.model import sim_model
from campaign.plan import build_plan, plan_records
from campaign.record import Event, Recorder, RunState, StateData

if TYPE_CHECKING:
    from campaign.history.entry import Entry
    from campaign.history.store import Store

SIMULATOR = "fast simulator (campaign/discovery/simulate.py): the simulated machine's error model and noise, no ADS or pty"
DAY = dt.timedelta(days=1)
TOLERANCE_UM = 15.0
"""The tolerance on A the simulated re-checks state, µm. With the lead error growing from −5 to
−11 µm/m over two years (3 µm/m a year over 600 mm: A grows about 1.8 µm a year), A + U is about
11.5 µm at the last re-check and reaches 15 µm about two years later."""
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
                     growth_ppm_per_year: float = 3.0, backlash_um: float = 2.5, seed: int = 1,
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


# --- histories drawn at random (the trend's validation: tests/test_history_drawn.py, bench/history_drawn.py)

@dataclass(frozen=True)
class DrawnHistory:
    """One axis's history drawn at random the way plants make them (issue 30): a linear axis of
    `span_mm` with `targets` targets every span/(targets − 1), 5 runs, its lead error's magnitude
    growing by `growth_ppm_per_year` µm/m a year from `lead_ppm_start` (one sign throughout, so that
    A grows as a straight line), the per-approach scatter `noise_um`, `dates` at irregular
    intervals, and the reversal jumping once from 0 to `jump_um` before re-check `jump_at`
    (0-based). The other errors are the demo axis's (campaign/demo.toml), scaled to the span."""

    span_mm: float
    targets: int
    growth_ppm_per_year: float
    lead_ppm_start: float
    noise_um: float
    dates: tuple[dt.datetime, ...]
    jump_um: float
    jump_at: int
    seed: int

    @property
    def years(self) -> float:
        return (self.dates[-1] - self.dates[0]).total_seconds() / (365.25 * 86400)

    def lead_ppm(self, when: dt.datetime) -> float:
        sign = 1.0 if self.lead_ppm_start >= 0 else -1.0
        years = (when - self.dates[0]).total_seconds() / (365.25 * 86400)
        return self.lead_ppm_start + sign * self.growth_ppm_per_year * years

    def config(self, when: dt.datetime, backlash_um: float, noise: bool = True) -> Config:
        """The re-check's config: the demo's, on this axis, with this lead error and reversal."""
        base = demo_config()
        effects = plain(base.sim.effects or {})
        effects["linear_scale"] = {"ppm": round(self.lead_ppm(when), 6)}
        effects["nonlinear_lead"] = {**effects["nonlinear_lead"], "end_mm": self.span_mm}
        effects["noise"] = {"sigma_um": self.noise_um if noise else 0.0,
                            "reading_sigma_um": effects["noise"]["reading_sigma_um"] if noise else 0.0}
        if backlash_um:
            effects["backlash"] = {"b_um": backlash_um}
        return config_with(base, {"axis": {"soft_limit_max": self.span_mm + 10.0},
                                  "plan": {"length": self.span_mm, "count": self.targets},
                                  "campaign": {"tolerance": 0.0},
                                  "sim": {"seed": self.seed, "effects": effects}})

    def true_rate_a(self) -> float:
        """The true drift of A, µm/year: how fast the noise-free A of the axis (the reversal after
        the jump in place) grows between the first and the last re-check. The noise adds to A
        about the same at every re-check (its k·s terms), so it does not change the rate."""
        from campaign.iso230 import evaluate

        ends = []
        for when in (self.dates[0], self.dates[-1]):
            config = self.config(when, self.jump_um, noise=False)
            ends.append(evaluate(simulate_campaign(config, sim_model(config.sim), seed=1)).summary["A"] or 0.0)
        return (ends[1] - ends[0]) / self.years

    def as_json(self) -> dict:
        return {"span_mm": self.span_mm, "targets": self.targets, "growth_ppm_per_year": self.growth_ppm_per_year,
                "lead_ppm_start": self.lead_ppm_start, "noise_um": self.noise_um, "rechecks": len(self.dates),
                "years": round(self.years, 3), "jump_um": self.jump_um, "jump_at": self.jump_at, "seed": self.seed}


def draw_history(rng: np.random.Generator, end: dt.datetime, rechecks: tuple[int, int] = (11, 14),
                 years: tuple[float, float] = (1.5, 2.5), growth: tuple[float, float] = (1.0, 5.0),
                 span: tuple[float, float] = (300.0, 1000.0), jump: tuple[float, float] = (2.0, 5.0)) -> DrawnHistory:
    """One history as issue 30 draws them: drift 1–5 µm/m a year, 300–1000 mm, 11–21 targets,
    noise 0.3–1 µm, 11–14 re-checks over 1.5–2.5 years at irregular intervals (each gap 0.4 to 1.6
    times the mean), a lead error of 4–10 µm/m at the first (either sign), and one reversal jump
    of 2–5 µm somewhere in the middle third to two thirds. Each range can be narrowed (a fixed
    scenario: `rechecks=(12, 12)`; no jump: `jump=(0, 0)`)."""
    n = int(rng.integers(rechecks[0], rechecks[1] + 1))
    gaps = rng.uniform(0.4, 1.6, n - 1)
    total_days = float(rng.uniform(*years)) * 365.25
    offsets = np.concatenate([[0.0], np.cumsum(gaps)]) / np.sum(gaps) * total_days
    dates = tuple(end - dt.timedelta(days=total_days - float(o)) for o in offsets)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    return DrawnHistory(span_mm=round(float(rng.uniform(*span)), 1), targets=int(rng.integers(11, 22)),
                        growth_ppm_per_year=round(float(rng.uniform(*growth)), 3),
                        lead_ppm_start=round(sign * float(rng.uniform(4.0, 10.0)), 3),
                        noise_um=round(float(rng.uniform(0.3, 1.0)), 3), dates=dates,
                        jump_um=round(float(rng.uniform(*jump)), 3),
                        jump_at=int(rng.integers(round(n / 3), round(2 * n / 3) + 1)), seed=int(rng.integers(1, 10**6)))


def drawn_entries(history: DrawnHistory, machine: str, axis: str = "X", tolerance_um: float = 0.0) -> list[Entry]:
    """Every re-check of `history` simulated (the fast simulator, each with its own noise) and
    assessed as the store records it: machine `machine`, axis `axis`, each stating the tolerance
    `tolerance_um` on A (0: none); no campaign directory (a re-check's location is a name,
    drawn-MACHINE-AXIS-NN)."""
    from campaign.assess import assess
    from campaign.discovery.simulate import Environment
    from campaign.history.entry import assessed_entry

    room = Environment(material_temp_c=(20.0, 20.0))
    entries = []
    for number, when in enumerate(history.dates):
        backlash = history.jump_um if number >= history.jump_at else 0.0
        config = config_with(history.config(when, backlash), {"campaign": {"machine": machine, "tolerance": tolerance_um},
                                                              "axis": {"name": axis}})
        table = simulate_campaign(config, sim_model(config.sim), seed=history.seed + number, environment=room)
        a = assess(table, config, meta={"simulated": True})
        key = f"drawn-{machine}-{axis}-{number}-{history.seed}"
        entries.append(assessed_entry(a, key, f"drawn-{machine}-{axis}-{number + 1:02d}", when, "demo",
                                      {"machine": machine, "axis": axis}))
    return entries


def record_drawn(store: Store, history: DrawnHistory, machine: str, axis: str = "X", tolerance_um: float = 0.0) -> int:
    """Record every re-check of `history` (drawn_entries) straight into `store`. Returns the
    campaigns recorded."""
    entries = drawn_entries(history, machine, axis, tolerance_um)
    for entry in entries:
        store.put(entry)
    return len(entries)

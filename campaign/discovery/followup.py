"""The follow-up campaign: a campaign config for the same axis that would separate every group
discovery left unresolved, within the axis's limits and as short as it can be.

Each unresolved group (and each located region) asks for one part of the plan (`Part`); parts of
one kind (`_kind`: the wait ladder, repeated runs, targets measured once) are merged into one
campaign (its targets, capture and cycles), parts of different kinds are campaigns of their own,
so that each keeps its cycles and waits and their machine times add up. The part an effect asks for is its module's
`follow_up` (campaign/effects/): a group gets the first of these that one of its effects asks for
("travel" only when all do):
- settling against backlash (or position-dependent backlash): waits before capture that vary over
  a decade (the dwell method with a short window and `dwell_jitter`), at a few targets close
  together, with as many points as the reversal's size against the noise needs;
- a periodic error whose period is not identifiable (or that rivals the bow): a cluster of targets
  at most a quarter of the shortest candidate period apart, over a few of the longest candidate
  periods, in the middle of the travel measured; or, when the controller streams its position
  (campaign.specs.STREAMING_CONTROLLERS) and every part measured once beside it is the cluster or a region where a
  local error rivals the period (the wait ladder and repeated runs are campaigns of their own), a slow scan over their span (`_scan`: one sweep each way, its speed from the timing
  budget and the period to resolve), whose dense profile the joint fit reads;
- thermal drift against linear scale (or the environment): twice the first campaign's runs at its
  targets over the whole travel (a slope is seen over the travel), so about twice its time;
- a growing against a constant reversal: both directions at targets over the whole travel;
- a linear against an exponential growth in time (linear_drift or thermal_drift): not planned, with
  how long one campaign would have to last (each campaign's time starts again in the joint fit).
Parts of one campaign that ask for different targets get the union of them.
A group none of these fits is said, not planned.

Units: positions in the axis unit (mm or deg), times s, deviations µm.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from campaign.config import Config, config_toml, config_with, parse_config
from campaign.discovery.data import CampaignData
from campaign.discovery.effects import HELD_PREFIX
from campaign.discovery.fit import Fit, Term, linear_fit
from campaign.discovery.local import Zone, zones
from campaign.discovery.naming import RIVAL_MARGIN
from campaign.discovery.records import LocalRival, Unresolved
from campaign.discovery.result import Discovery
from campaign.effects import REGISTRY
from campaign.effects.base import stop_waits
from campaign.model import is_model_name
from campaign.plan import EXPECTED_TIMING_U_S, build_plan, check_plan, estimate_duration_s, planned_timing
from campaign.specs import STREAMING_CONTROLLERS
from protocols.units import UNITS, unit_label

WAITS_S = (0.5, 5.0)
"""The waits before capture of the dwell part, s: a decade (stretched upwards to include the first
campaign's longest wait)."""
DWELL_WINDOW_S = 0.2
"""The capture window of the dwell part, s: short, so that the wait is what varies."""
FEW_TARGETS = 5
FEW_SPACING = 0.025
"""Targets (and their spacing, a fraction of the travel) when no cluster is asked for."""
SEPARATION = 5.0
"""How clearly (in standard errors) a part should tell its rivals apart: the closest candidate
periods (sets the cluster's length from the wave's amplitude and the noise, computed); settling
from backlash (sets the dwell part's points by a rule of thumb, `_dwell_points`)."""
MAX_CLUSTER_TARGETS = 121
"""The most targets a cluster gets: a longer span than that allows is cut, and the why says so."""

DENSE_ENOUGH = 1.5
"""A region whose measured targets are nowhere more than this many times the step a follow-up would
take apart is not measured again (a follow-up already measured it: the loop ends there)."""

CLUSTER_LEADS = 3.0
"""The cluster spans at least this many of the longest plausible candidate periods."""
CLUSTER_STEP = 5
"""Nominal targets per shortest candidate period in the cluster; with golden offsets of
CLUSTER_OFFSET of the spacing no two targets are more than a quarter of that period apart."""
CLUSTER_OFFSET = 0.2
SCAN_RATE_HZ = 500.0
"""The laser's rate a follow-up scan asks for at least ([instrument] rate_hz, axiscal's tick), Hz."""
SCAN_SAMPLES_PER_PERIOD = 20
"""A scan takes at least this many laser samples per shortest candidate period."""
MAX_CYCLES = 1000
"""The most cycles a plan may have ([plan] cycles)."""


@dataclass
class Part:
    """One part of the follow-up: the unresolved effects it separates and why it looks as it does."""

    effects: list[str]
    why: str


@dataclass
class Campaign:
    """One campaign of the follow-up: its config, the TOML text, where it is written, its parts and
    its machine time (the project's estimate, s)."""

    config: Config
    text: str
    path: Path
    parts: list[Part]
    duration_s: float

    def as_dict(self) -> dict[str, Any]:
        return {"file": str(self.path), "effects": [p.effects for p in self.parts],
                "duration_s": round(self.duration_s, 1), "points": len(build_plan(self.config).points),
                "targets": list(build_plan(self.config).targets), "cycles": self.config.plan.cycles,
                "capture": self.config.capture.method}


@dataclass
class FollowUp:
    """The follow-up campaign: its config (validated, within the limits), the TOML text to write,
    the parts and why each is there, the groups it cannot plan for, and the machine time of the
    follow-up and of the first campaign (the project's estimate, s). With no parts nothing is written
    (config is the first campaign's, text empty): only `unplanned` says anything."""

    config: Config
    text: str
    parts: list[Part]
    unplanned: list[str] = field(default_factory=list)
    duration_s: float = 0.0
    first_duration_s: float = 0.0
    longer: str | None = None
    """A warning when the follow-up takes longer than the first campaign (None: it does not)."""
    campaigns: list[Campaign] = field(default_factory=list)
    """The campaigns written (config and text above are the first's; duration_s is their sum): parts
    that ask for different cycles or waits are campaigns of their own, so that each keeps them."""

    def as_dict(self) -> dict[str, Any]:
        if not self.parts:  # nothing written: what could not be planned, and why
            return {"campaigns": [], "parts": [], "unplanned": self.unplanned, "duration_s": 0.0,
                    "first_duration_s": round(self.first_duration_s, 1), "longer_warning": None}
        return {"campaigns": [c.as_dict() for c in self.campaigns],
                "parts": [{"effects": p.effects, "why": p.why} for p in self.parts], "unplanned": self.unplanned,
                "duration_s": round(self.duration_s, 1), "first_duration_s": round(self.first_duration_s, 1),
                "longer_warning": self.longer,
                "targets": list(build_plan(self.config).targets), "cycles": self.config.plan.cycles,
                "capture": self.config.capture.method,
                "scan_velocity": self.config.capture.scan_velocity if self.config.capture.method == "scan" else None,
                "rate_hz": self.config.instrument.rate_hz}


def _first_targets(data: CampaignData) -> np.ndarray:
    """The first campaign's targets (of tables fitted together, the first table's: its spacing is
    the one a follow-up refines, not that of a dense follow-up already measured)."""
    if data.campaign is None:
        return data.targets_mm
    return np.unique(np.round(data.x[data.campaign == 0], 6))


def _few(data: CampaignData) -> list[float]:
    """FEW_TARGETS targets FEW_SPACING of the travel apart about the middle of the targets measured:
    where the first campaign already holds the shape along the travel, the follow-up needs only to
    see the reversal, and short moves keep it short."""
    t = _first_targets(data)
    step = FEW_SPACING * float(t[-1] - t[0])
    middle = float(np.median(t)) - step * (FEW_TARGETS - 1) / 2
    return [round(middle + i * step, 3) for i in range(FEW_TARGETS)]


def _amplitude(data: CampaignData, final: Fit, period: float) -> float:
    """The amplitude (µm) of a sine of `period` fitted beside the rest of the final model: without the
    wave the final model may hold for the unresolved period (its best candidate), which a second
    sine at the same or an aliasing period would fight (a reviewer saw 160 µm for a 3 µm wave), whether
    the model holds it as the period's stand-in or as a held unresolved group (HELD_PREFIX)."""
    term = Term("periodic_lead", {"period_mm": period}, False, {"period_mm": period})
    rest = [t for t in final.terms if t.name.removeprefix(HELD_PREFIX) != term.name]
    return float(np.hypot(*linear_fit(data, [*rest, term]).coefs[-1]))


def frequency_error(span: float, step: float, amplitude_um: float, noise_um: float) -> float:
    """The standard error of a sine's frequency (1/mm) fitted to targets `step` apart over `span`,
    each measured once in each direction (the Cramér-Rao bound: √12·σ / (2π·A·√N·L))."""
    n = 2 * (span / step + 1)
    return math.sqrt(12) * noise_um / (2 * math.pi * max(amplitude_um, 1e-6) * math.sqrt(n) * span)


def _cluster(data: CampaignData, final: Fit, periods: list[float], delta_bic: list[float],
             noise_um: float) -> tuple[list[float], str]:
    """A cluster of targets at most a quarter of the shortest candidate period apart (no candidate
    aliases there), over a few of the longest plausible candidate periods (ΔBIC below
    RIVAL_MARGIN), and long enough that the cluster alone tells the two closest plausible
    candidates apart by SEPARATION standard errors of the frequency; and why it looks so."""
    t = data.targets_mm
    plausible = [p for p, d in zip(periods, delta_bic or [0.0] * len(periods)) if d < RIVAL_MARGIN] or periods[:1]
    shortest, longest = min(periods), max(plausible)
    step = shortest / CLUSTER_STEP
    freqs = sorted(1 / p for p in plausible)
    closest = min((b - a for a, b in itertools.pairwise(freqs)), default=1 / longest)
    amplitude = _amplitude(data, final, periods[0])
    travel = float(t[-1] - t[0])
    span = CLUSTER_LEADS * longest
    while frequency_error(span, step, amplitude, noise_um) * SEPARATION > closest and span < travel:
        span *= 1.25
    span = min(span, travel)
    bounded = math.floor(span / step) + 1 > MAX_CLUSTER_TARGETS
    if bounded:
        span = step * (MAX_CLUSTER_TARGETS - 1)
    count = math.floor(span / step) + 1
    middle = float(np.median(t))
    first = min(max(middle - span / 2, float(t[0])), float(t[-1]) - span)
    targets = [round(first + i * step, 4) for i in range(count)]
    shown = ", ".join(f"{p:.4g}" for p in plausible[:6]) + (", ..." if len(plausible) > 6 else "")
    sigma = frequency_error(span, step, amplitude, noise_um)
    why = (f"the period is not identifiable: {len(plausible)} candidate periods fit alike ({shown} mm); "
           f"{len(targets)} targets {step:.3g} mm apart (golden offsets of {CLUSTER_OFFSET:g} of that: no two more "
           f"than a quarter of the shortest candidate, {shortest:.3g} mm, apart) over {span:.4g} mm "
           f"({span / longest:.2g} × the longest plausible candidate): no candidate aliases there, and a "
           f"{amplitude:.2g} µm wave at a noise of {noise_um:.2g} µm gives its frequency to ±{sigma:.2g} per mm, "
           f"{closest / sigma:.0f} times closer than the two closest candidates"
           + (f" (the cluster is bounded to {MAX_CLUSTER_TARGETS} targets)" if bounded else ""))
    return targets, why


def scan_speed(config: Config, shortest: float, what: str = "shortest candidate period") -> tuple[float, float, str]:
    """The speed (axis unit/s) of a follow-up scan resolving periods down to `shortest` (axis unit),
    the laser rate it asks for (Hz) and why: at most SCAN_SAMPLES_PER_PERIOD samples per `shortest`
    at the rate; the timing's share of the deviation (speed × the alignment's expected timing
    uncertainty, campaign.plan.EXPECTED_TIMING_U_S) within capture.scan_wanted_u; the axis's
    velocity; a ramp within half the overrun (the targets' ends at constant velocity)."""
    rate = max(config.instrument.rate_hz, SCAN_RATE_HZ)
    unit = config.axis.unit
    dev_unit = unit_label(UNITS[config.axis.kind][1])
    wanted = config.capture.scan_wanted_u
    by_timing = planned_timing(0.0, wanted, config.axis.kind)[0]
    limits = {"the period": shortest * rate / SCAN_SAMPLES_PER_PERIOD,
              "the timing": by_timing,
              "axis.max_velocity": config.axis.max_velocity,
              "the ramp within half the overrun": math.sqrt(config.axis.max_acceleration * config.plan.overrun)}
    binding = min(limits, key=lambda k: limits[k])
    digits = 10 ** (math.floor(math.log10(limits[binding])) - 1)  # two significant digits, rounded down
    speed = math.floor(limits[binding] / digits) * digits
    why = (f"{speed:.3g} {unit}/s (set by {binding}): the laser at {rate:g} Hz takes {shortest * rate / speed:.0f} "
           f"samples per {what} ({shortest:.3g} {unit}, at least {SCAN_SAMPLES_PER_PERIOD}); the "
           f"expected timing uncertainty, {EXPECTED_TIMING_U_S * 1e6:.0f} µs, costs {planned_timing(speed, wanted, config.axis.kind)[1]:.2g} "
           f"{dev_unit}, within the wanted {wanted:g} {dev_unit} (capture.scan_wanted_u)")
    return speed, rate, why


def _scan(config: Config, stops: _Ask, shortest: float, what: str = "shortest candidate period") -> tuple[_Ask | None, str]:
    """A slow scan over the span of the targets `stops` asks for instead of stopping at them,
    resolving `shortest` (axis unit: a period, a region's width), or None and why not."""
    if not config.controller.streams_position:
        return None, (f"a stop-and-go cluster, not a scan: axis_driver.type = \"{config.controller.type}\" does not "
                      "stream its actual position with the controller's time stamps, which a scan needs (ADS device "
                      f"notifications: {', '.join(sorted(STREAMING_CONTROLLERS))})")
    targets = stops.targets or []
    speed, rate, how = scan_speed(config, shortest, what)
    unit = config.axis.unit
    span = targets[-1] - targets[0]
    why = (f"{stops.part.why}; scanned instead of stopped at (the controller streams its position): a sweep each "
           f"way over {span:.4g} {unit} (and the overrun) at {how}; fit its profile.csv with the first table")
    return _Ask(Part(stops.part.effects, why), targets, 1, {"offsets": "none"},
                {"method": "scan", "scan_velocity": speed}, instrument={"rate_hz": rate}, stops=stops), ""


def _dwell_points(reversal_um: float, noise_um: float) -> int:
    """Points the dwell part needs, a rule of thumb (not a computed separation): a settling that
    explains the reversal at the first campaign's wait is taken to differ from a constant reversal
    by about a quarter of it between the shortest and longest waits, and that quarter should be
    SEPARATION times the noise over the square root of the points."""
    signal = max(abs(reversal_um), 2 * max(noise_um, 1e-3)) / 4  # unknown or small: twice the noise
    return math.ceil((SEPARATION * max(noise_um, 1e-3) / signal) ** 2)


def _with_travel(targets: list[float] | None, data: CampaignData) -> list[float]:
    """The first campaign's targets over the whole travel, with those another part asked for."""
    return sorted({*(targets or []), *(round(float(v), 3) for v in _first_targets(data))})


def _periods_of(group: Unresolved, remaining: list[Any]) -> list[float]:
    if group.periods_mm:
        return [float(p) for p in group.periods_mm]
    for cand in remaining:
        if cand.name == "periodic_lead" and cand.fit is not None:
            if cand.periods:
                return [float(p) for p, _ in cand.periods]
            return [float(cand.fit.params()["periodic_lead"]["period_mm"])]
    return []


def is_drift_shape_group(effects: tuple[str, ...]) -> bool:
    """Whether an unresolved group holds only slopes that change in time (the registered effects that
    need several runs: a linear and an exponential growth), which a follow-up of repeated runs cannot
    tell apart: the joint fit starts each campaign's time again (join_campaigns)."""
    return bool(effects) and all(name in REGISTRY and REGISTRY[name].needs == "runs" for name in effects)


DRIFT_SPANS = 3.0
"""Time constants a campaign must last to show an exponential growth level off."""


def _drift_shape_unplanned(group: Unresolved, remaining: list[Any], data: CampaignData) -> str:
    """Why a group of drifts in time of different shapes (linear, exponential), or a drift the campaign
    does not pin down (Unresolved.not_pinned_down), is not planned, and what would tell them: one campaign
    DRIFT_SPANS of the fitted time constant long (the first `tau_s` fitted among the group's candidates)."""
    taus = [float(p["tau_s"]) for c in remaining if c.name in group.effects and c.fit is not None
            and "tau_s" in (p := c.fit.params()[c.name])]
    tau = taus[0] if taus else math.nan
    span = float(np.nanmax(data.t) - np.nanmin(data.t)) if np.isfinite(data.t).any() else math.nan

    def said(value: float) -> str:
        return _duration(value) if data.time_source == "time_s" else f"{value:.0f} points"

    lasted = f"{'the longest of these campaigns' if data.campaign is not None else 'this campaign'} lasted {said(span)}"
    long = (f"about {said(DRIFT_SPANS * tau)} ({DRIFT_SPANS:g} times the time constant of {said(tau)} fitted; {lasted})"
            if math.isfinite(tau) and tau > 0 else f"several of the drift's time constants ({lasted})")
    what, cannot = ("an exponential growth levels off and a linear one does not", "tell them")
    if group.not_pinned_down:
        what = "a drift in time that this campaign shows and does not pin down (how fast its slope changes and where it pivots)"
        cannot = "pin it down"
        if not (math.isfinite(tau) and tau > 0):  # a linear drift alone: no time constant to count in
            long = f"longer than this one, with more runs ({lasted})"
    return (f"{' or '.join(group.effects)}: {what}, which only one campaign lasting {long} shows, runs at "
            f"{FEW_TARGETS} targets over the travel repeated throughout; a follow-up fitted with this one starts "
            f"its time again, so it cannot {cannot}")


def _duration(seconds: float) -> str:
    """A time in words: '25 s', '8.4 min', '2.1 h'."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.1f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def _moved_paths(config: Config, out_dir: Path) -> dict[str, dict[str, Any]]:
    """The paths in the config (the sim model, a LinuxCNC comp file) made relative to where the
    follow-up config is written, as config changes."""
    changes: dict[str, dict[str, Any]] = {}
    for section, key, value in (("sim", "model", config.sim.model),
                                ("axis_driver", "comp_file", config.controller.comp_file)):
        if value and not (section == "sim" and is_model_name(value)):  # a shipped model's name is found anywhere
            changes[section] = {key: os.path.relpath((config.base_dir / value).resolve(), out_dir.resolve())}
    return changes


@dataclass
class _Ask:
    """What one part asks of the follow-up plan: its targets (None: any few), cycles, the plan and
    capture keys it sets, the points it needs, and why."""

    part: Part
    targets: list[float] | None
    cycles: int = 1
    plan: dict[str, Any] = field(default_factory=dict)
    capture: dict[str, Any] = field(default_factory=dict)
    points: int = 0
    instrument: dict[str, Any] = field(default_factory=dict)
    stops: _Ask | None = None
    """A scan's stop-and-go alternative (the cluster), planned when the scan cannot be merged."""


def _spread(data: CampaignData) -> list[float]:
    """FEW_TARGETS of the first campaign's targets spread over its whole travel (a slope is seen
    over the travel; few targets keep the campaign short)."""
    t = _first_targets(data)
    picks = np.unique(np.round(np.linspace(0, len(t) - 1, min(FEW_TARGETS, len(t)))).astype(int))
    return [round(float(t[i]), 3) for i in picks]


def part_of(name: str) -> str | None:
    """The part of a follow-up that an effect asks for (its module's `follow_up`,
    campaign/effects/); None for a name that is no registered effect."""
    found = REGISTRY.get(name)
    return None if found is None else found.follow_up


def _asks(unresolved: list[Unresolved], remaining: list[Any], data: CampaignData, final: Fit,
          config: Config, reversal_um: float | None, noise_um: float,
          regions: list[tuple[float, float]]) -> tuple[list[_Ask], list[str]]:
    """What each unresolved group (and each located region) asks of the follow-up; the groups none
    of the parts fits."""
    asks: list[_Ask] = []
    unplanned: list[str] = []
    only_rivals: list[Unresolved] = []  # groups told apart only by denser targets over their rivals
    first_cycles = config.plan.cycles
    for group in unresolved:
        names = set(group.effects)
        parts = {part_of(name) for name in names}
        if "dwells" in parts:
            waits = stop_waits(data) if len(stop_waits(data)) else np.array([config.plan.dwell_s])
            high = max(WAITS_S[1], 1.25 * float(np.max(waits)), group.waits_s or 0.0)
            low = max(high / 10, WAITS_S[0] * high / WAITS_S[1])
            points = _dwell_points(reversal_um or 0.0, noise_um)
            asks.append(_Ask(Part(sorted(names), (
                (f"a reversal{'' if reversal_um is None else f' of {abs(reversal_um):.2g} µm'} that backlash and "
                 "settling explain alike" if not group.not_excluded else
                 f"{' beside '.join(group.effects[::-1])}, not excluded: waits long enough for a settling of the time "
                 "constant fitted to fade")
                + f": waits before capture from {low:.2g} to {high:.2g} s (a decade, the dwell "
                f"method with a {DWELL_WINDOW_S:g} s window) at {FEW_TARGETS} targets close together: settling fades "
                f"with the wait, backlash does not; at least {points} points (a rule of thumb: a quarter of the "
                f"reversal {SEPARATION:g} times the noise of {noise_um:.2g} µm over √points)")),
                None, 2, {"dwell_s": round((low + high) / 2, 3), "dwell_jitter": round((high - low) / (high + low), 3)},
                {"method": "dwell", "average_s": DWELL_WINDOW_S}, points))
        elif "cluster" in parts:
            periods = _periods_of(group, remaining)
            if not periods:
                unplanned.append(f"{' or '.join(group.effects)}: no candidate period to plan for")
                continue
            targets, why = _cluster(data, final, periods, list(group.period_delta_bic), noise_um)
            cluster = _Ask(Part(sorted(names), why), targets, 1, {"offsets": "golden", "offset_fraction": CLUSTER_OFFSET})
            scan, refused = _scan(config, cluster, min(periods))
            if scan is None:
                cluster.part.why += f"; {refused}"
            asks.append(scan or cluster)
        elif is_drift_shape_group(group.effects):
            unplanned.append(_drift_shape_unplanned(group, remaining, data))
        elif "runs" in parts:
            asks.append(_Ask(Part(sorted(names), (
                f"a slope that changes from run to run or not at all: {2 * first_cycles} runs (the first campaign "
                f"had {first_cycles}) at {FEW_TARGETS} targets over the whole travel; a drift changes the slope from "
                "run to run, a scale does not")), _spread(data), 2 * first_cycles))
        elif parts == {"travel"}:
            asks.append(_Ask(Part(sorted(names), "a reversal that may grow along the travel: both directions at "
                                                 f"{FEW_TARGETS} targets over the whole travel"), _spread(data), 1))
        elif group.local_rivals:  # an effect or local errors there: denser targets over them tell
            regions = [*regions, *(rival_region(r) for r in group.local_rivals)]
            only_rivals.append(group)
        else:
            unplanned.append(f"{' or '.join(group.effects)}: {group.how_to_tell}")
    rivals = [rival_region(r) for group in unresolved for r in group.local_rivals]
    first_t = _first_targets(data)
    spacing = float(np.median(np.diff(first_t))) if len(first_t) > 1 else 1.0
    lo, hi = float(data.targets_mm[0]), float(data.targets_mm[-1])
    every = data.targets_mm
    dense_already: list[tuple[float, float]] = []
    for start, end in _joined(regions):
        step = max(min(spacing / 4, (end - start) / 8), 1e-3)
        a, b = max(start - step, lo), min(end + step, hi)
        count = min(int((b - a) / step) + 1, MAX_CLUSTER_TARGETS)
        inside = every[(every >= start) & (every <= end)]
        if len(inside) >= 2 and float(np.max(np.diff(inside))) <= DENSE_ENOUGH * (b - a) / max(count - 1, 1):
            dense_already.append((start, end))
            continue  # already measured as densely as a follow-up would: the tables hold its shape
        targets = [round(a + (b - a) * i / max(count - 1, 1), 4) for i in range(count)]
        dense = _Ask(Part(["local error"], (
            f"where measurement and model disagree beyond the noise, {start:.4g} to {end:.4g} mm: {count} targets "
            f"{(b - a) / max(count - 1, 1):.3g} mm apart over it (the first campaign's are {spacing:.3g} mm apart"
            + (f"; a quarter of that would take more than {MAX_CLUSTER_TARGETS} targets" if count == MAX_CLUSTER_TARGETS
               and (b - a) / (count - 1) > step * 1.001 else "") + "), to see its shape")), targets, 1)
        # scanned only where a local error rivals a period (its cluster is scanned too): a located local
        # error of its own keeps its stops (its scan's profile, fitted with the first table, named
        # effects the machine lacked: docs/scan.md)
        rival = any(r0 < end and start < r1 for r0, r1 in rivals)
        scanned = _scan(config, dense, max(b - a, step), "region")[0] if rival else None
        asks.append(scanned or dense)
    for group in only_rivals:  # measured as densely as a follow-up would, and still not told apart
        if all(any(a <= r.region_mm[0] and r.region_mm[1] <= b for a, b in dense_already) for r in group.local_rivals):
            unplanned.append(f"{' or '.join(group.effects)}: the tables already measure densely over its rivals, and "
                             "they still cannot tell it from a local error there")
    return asks, unplanned


def regions_to_measure(result: Discovery) -> list[tuple[float, float]]:
    """Where a follow-up should measure densely: the located local errors' regions, those where a
    local error rivals an unresolved effect, where a located one's other shape would lie (its
    shape_rival), and what the final model leaves unexplained along the
    axis (but a reversal over the travel). A region the
    tables already measure densely is left out by the planner (the loop ends there)."""
    rivals = [rival_region(r) for u in result.unresolved for r in u.local_rivals]
    left = [(r.start, r.end) for r in (result.located_after.along if result.located_after else [])
            if r.direction != "opposite"]
    shapes = [rival_region(e.shape_rival) for e in result.local_errors if e.shape_rival is not None]
    return [with_its_place_uncertain(zone) for zone in zones(result.local_errors)] + rivals + shapes + left


def with_its_place_uncertain(zone: Zone) -> tuple[float, float]:
    """A zone's region widened by twice the standard error of its members' centres: where it may be,
    not only where it was fitted (a step fitted at 337 ± 18 mm lay at 300 mm, and the follow-up over
    309-365 mm never measured its rise). A step placed between two targets is widened by half the gap
    between them on each side: what it says is that the two targets read different levels, and an error
    that ends at one of them reads the same (a wave over 136-280 mm on 11 golden targets was said as a
    step between the targets at 277.9 and 371.3 mm, and the follow-up over that gap never measured it)."""
    low, high = zone.region_mm
    errors = [m.errors.get("centre_mm", 0.0) for m in zone.members if m.between_mm is None]
    sigma = max((e for e in errors if math.isfinite(e)), default=0.0)
    gaps = [m.between_mm[1] - m.between_mm[0] for m in zone.members if m.between_mm is not None]
    widen = max(2 * sigma, max(gaps, default=0.0) / 2)
    return low - widen, high + widen


def rival_region(rival: LocalRival) -> tuple[float, float]:
    """Where a follow-up measures a local error that rivals an unresolved effect: its region, and for a
    step placed only between two targets half their gap beyond it on each side, as
    with_its_place_uncertain widens a located one."""
    low, high = rival.region_mm
    half = (rival.between_mm[1] - rival.between_mm[0]) / 2 if rival.between_mm is not None else 0.0
    return low - half, high + half


def measured_stable_wait_s(data: CampaignData, config: Config) -> float:
    """What a stable capture takes at a target beyond its stability window, as the first campaign
    measured it, s per point (0 when it did not capture with the stable method or recorded no
    waits): the median wait before its samples (their middle, so plus half the window) less the
    window the project's estimate counts. On a machine that settles slowly it is seconds a point
    (a follow-up of 300 stable captures took four times its estimate when it was left out)."""
    if config.capture.method != "stable" or data.w is None:
        return 0.0
    first = data.w if data.campaign is None else data.w[data.campaign == 0]
    waits = np.nanmean(first, axis=1) if first.size else np.array([])
    waits = waits[np.isfinite(waits)]  # a scan profile's bins: captured moving
    if not len(waits):
        return 0.0
    return max(0.0, float(np.median(waits)) - config.capture.stable_window_s / 2)


def _joined(regions: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The regions with those that overlap (or touch) joined into one: each place is measured once."""
    out: list[list[float]] = []
    for start, end in sorted((min(r), max(r)) for r in regions):
        if out and start <= out[-1][1]:
            out[-1][1] = max(out[-1][1], end)
        else:
            out.append([start, end])
    return [(a, b) for a, b in out]


def _merged(asks: list[_Ask], data: CampaignData) -> tuple[list[float], int, dict[str, Any], dict[str, Any],
                                                          dict[str, Any]]:
    """One plan for several parts: the union of their targets, the most cycles (and enough for the
    points a part needs), their plan, capture and instrument keys."""
    plan: dict[str, Any] = {"offsets": "none"}  # the targets written are where to measure (the first
    # campaign's measured targets already hold its offsets); a cluster sets its own
    capture: dict[str, Any] = {}
    instrument: dict[str, Any] = {}
    wanted = [a.targets for a in asks if a.targets is not None]
    targets = sorted({v for t in wanted for v in t}) if wanted else _few(data)
    cycles = max(a.cycles for a in asks)
    for a in asks:
        plan.update(a.plan)
        speed = min(capture.get("scan_velocity", math.inf), a.capture.get("scan_velocity", math.inf))
        capture.update(a.capture)
        if math.isfinite(speed):  # scans merged: the slowest
            capture["scan_velocity"] = speed
        if a.instrument:  # the fastest laser rate asked for
            instrument["rate_hz"] = max(instrument.get("rate_hz", 0.0), a.instrument["rate_hz"])
        if a.points:
            cycles = min(max(cycles, math.ceil(a.points / (2 * len(targets)))), MAX_CYCLES)
    return targets, cycles, plan, capture, instrument


BESIDE_STOPS = "the other parts stop at targets, and one campaign has one capture method"


def _stopped(ask: _Ask) -> _Ask:
    """A scan's stop-and-go cluster, saying why it is not scanned; any other part as it is."""
    if ask.stops is None:
        return ask
    cluster = ask.stops
    cluster.part.why += f"; a stop-and-go cluster, not a scan: {BESIDE_STOPS}"
    return cluster


def _kind(ask: _Ask) -> str:
    """Which campaign of the follow-up a part goes to: the waits varied over a decade ("waits"), runs
    repeated ("runs") or targets measured once, stopped at or scanned ("targets"). Parts of one kind
    are merged; parts of different kinds are campaigns of their own, so that the waits vary only at
    the wait ladder's targets and a cluster is measured once with the first campaign's capture."""
    if ask.capture.get("method") == "dwell":
        return "waits"
    return "runs" if ask.cycles > 1 else "targets"


def _campaigns(chosen: list[_Ask]) -> list[list[_Ask]]:
    kinds: dict[str, list[_Ask]] = {}
    for ask in chosen:
        kinds.setdefault(_kind(ask), []).append(ask)
    return list(kinds.values())


def _path(out: Path, index: int) -> Path:
    """Where the follow-up's campaign `index` (0, 1, ...) is written: -o FOLLOW.toml, FOLLOW-2.toml, ..."""
    return out if index == 0 else out.with_name(f"{out.stem}-{index + 1}{out.suffix}")


def _thinned(targets: list[float], gap: float) -> list[float]:
    """The targets with any closer than `gap` to the one kept before it left out (a union of parts'
    targets may hold two a hair apart, which a scan's windows cannot tell apart)."""
    kept: list[float] = []
    for v in targets:
        if not kept or v - kept[-1] >= gap:
            kept.append(v)
    return kept


def next_noise_seed(seed: int, followed: int, index: int) -> int:
    """The simulated machine's noise seed for campaign `index` (0, 1, ...) of a follow-up of `followed`
    tables first measured at `seed`: one on for every campaign before it, so that no two campaigns of
    the loop draw the same scatter (with the first's seed, the k-th approach of both drew the same,
    and the tables fitted together were not independent)."""
    return seed + max(followed, 1) + index


def plan_follow_up(unresolved: list[Unresolved], remaining: list[Any], data: CampaignData, final: Fit,
                   config: Config, reversal_um: float | None, noise_um: float, out: Path,
                   sources: list[str], regions: list[tuple[float, float]] | None = None,
                   budget_s: float | None = None) -> FollowUp | None:
    """The follow-up campaign for the `unresolved` groups of a discovery on `data` (and denser
    targets over the located `regions`, (from, to) mm, where the model and the measurement disagree
    beyond the noise), from the first campaign's `config` (written to `out`), `final` the model
    fitted; None when there is nothing to plan for (a FollowUp with no parts when no group could be
    planned, each said in `unplanned`). `reversal_um`: the size of a reversal kept as a
    stand-in or named rival (sets the dwell part's points).

    Parts of different kinds (`_kind`: the wait ladder, repeated runs, targets measured once) are
    campaigns of their own, written to `out` and beside it (FOLLOW-2.toml, ...), each with its own
    cycles, capture and waits. Their machine time together is at most `budget_s` by construction
    (default: the first campaign's): the parts are taken cheapest first while the campaigns stay
    within it; a part that does not fit is said, with what it alone would take. Each config is
    marked `[campaign] purpose = "follow-up"`, `follows` the first campaign's directory, so that it
    is never taken for an acceptance test."""
    asks, unplanned = _asks(unresolved, remaining, data, final, config, reversal_um, noise_um, regions or [])
    if not asks and not unplanned:
        return None
    if any(a.stops is None for a in asks if _kind(a) == "targets"):  # one campaign has one capture method:
        asks = [_stopped(a) if _kind(a) == "targets" else a for a in asks]  # a scan does not stop where the others do
    stable_wait = measured_stable_wait_s(data, config)
    first_plan = build_plan(config)
    first = estimate_duration_s(first_plan, config.axis) + stable_wait * len(first_plan.points)
    home = first_plan.stops()[0].position  # a follow-up starts with the move from where the first campaign began
    budget = first if budget_s is None else budget_s
    follows = str(Path(sources[0]).parent) if sources else ""

    def build(chosen: list[_Ask], path: Path = out, index: int = 0) -> tuple[Config, float]:
        targets, cycles, plan, capture, instrument = _merged(chosen, data)
        if "scan_velocity" in capture:  # a target's window never takes its neighbour's samples, and
            # holds at least two of the laser's samples
            rate = instrument.get("rate_hz", config.instrument.rate_hz)
            targets = _thinned(targets, 2 * capture["scan_velocity"] / rate)
            gaps = [b - a for a, b in itertools.pairwise(targets)]
            if gaps:
                capture["scan_window"] = min(config.capture.scan_window, min(gaps))
        else:
            targets = _thinned(targets, 1e-3)
        plan.update(targets=targets, cycles=cycles, length=None, count=None)
        said = "; ".join(" or ".join(a.part.effects) for a in chosen)
        moved = _moved_paths(config, path.parent)
        if config.instrument.type == "sim":  # the same simulated machine measured again, on new noise
            moved["sim"] = {**moved.get("sim", {}), "seed": next_noise_seed(config.sim.seed, len(sources), index)}
        changed = config_with(config, {"plan": plan, "capture": capture, "instrument": instrument, **moved,
                                       "campaign": {"description": f"follow-up of {', '.join(sources)}: to tell {said}",
                                                    "purpose": "follow-up", "follows": follows}})
        followed = parse_config(config_toml(changed.data), str(path))  # as it will be read from where it is written
        plan_built = build_plan(followed)
        check_plan(plan_built, followed.axis)
        waited = stable_wait if followed.capture.method == "stable" else 0.0
        return followed, estimate_duration_s(plan_built, followed.axis, home) + waited * len(plan_built.points)

    def cost(chosen: list[_Ask]) -> float:
        return sum(build(group)[1] for group in _campaigns(chosen))

    alone = [(a, build([a])[1]) for a in asks]
    chosen: list[_Ask] = []
    for ask, alone_s in sorted(alone, key=lambda pair: pair[1]):
        if cost([*chosen, ask]) <= budget:
            chosen.append(ask)
        else:
            unplanned.append(f"{' or '.join(ask.part.effects)}: not within the budget of {budget / 60:.1f} min of "
                             f"machine time (the first campaign took {first / 60:.1f} min); it alone would take "
                             f"{alone_s / 60:.1f} min: measure it as a follow-up of its own (--budget-min to allow it)")
    if not chosen:
        return FollowUp(config, "", [], unplanned, 0.0, first, None)
    chosen.sort(key=asks.index)
    groups = _campaigns(chosen)
    paths = [_path(out, i) for i in range(len(groups))]
    built = [build(group, path, index) for index, (group, path) in enumerate(zip(groups, paths))]
    tables = [f"NEW{i + 1 if len(groups) > 1 else ''}/{'profile.csv' if c.capture.method == 'scan' else 'points.csv'}"
              for i, (c, _) in enumerate(built)]  # a scan's dense profile
    duration = sum(d for _, d in built)
    campaigns = []
    for i, (group, path, (followed, took)) in enumerate(zip(groups, paths, built)):
        parts = [a.part for a in group]
        measured = (f"# Measure it on the same axis (axiscal run {path.name} --out {tables[i].split('/')[0]}), then fit"
                    if len(groups) == 1 else
                    f"# It is campaign {i + 1} of {len(groups)} of the follow-up ({', '.join(p.name for p in paths)}: their "
                    "parts ask for different cycles or waits); measure each on the same axis (axiscal run "
                    f"{path.name} --out {tables[i].split('/')[0]}), then fit")
        header = [f"# Follow-up campaign written by `axiscal discover {' '.join(sources)} --follow-up`.",
                  "# It would separate what the first campaign left unresolved.",
                  measured,
                  f"# all together: axiscal discover {' '.join(sources)} {' '.join(tables)}",
                  "# It is a follow-up ([campaign] purpose), not an acceptance test: it gets no pass/fail.",
                  *(f"# - {', '.join(p.effects)}: {p.why}" for p in parts),
                  *(f"# - not planned: {u}" for u in unplanned),
                  (f"# Machine time (estimate): {took / 60:.1f} min"
                   + (f", {duration / 60:.1f} min with the other campaigns" if len(groups) > 1 else "")
                   + f"; the first campaign's: {first / 60:.1f} min (budget {budget / 60:.1f} min)"
                   + (f"; a stable capture counted with the {stable_wait:.2g} s it waited a point in the first "
                      "campaign" if stable_wait > 0.05 and followed.capture.method == "stable" else "") + "."), ""]
        campaigns.append(Campaign(followed, "\n".join(header) + "\n" + config_toml(followed.data), path, parts, took))
    return FollowUp(campaigns[0].config, campaigns[0].text, [a.part for a in chosen], unplanned, duration, first, None,
                    campaigns)

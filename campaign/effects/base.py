"""What every effect module is made of: the `Effect` (its parameters, its simulated deviation, its
least-squares form, its rivals and its part of a follow-up) and the helpers several effects share.

An effect module (one file of this package, `campaign/effects/NAME.py`) defines `EFFECT`, one
`Effect`; the package's registry (campaign/effects/__init__.py) finds it. The simulated machine
reads `Effect.deviation` (through campaign.model), discovery reads `Effect.form` and the rest.

Units: x mm, deviations µm, t s (or point order), w s; ppm = µm/m.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np


class Samples(Protocol):
    """What a least-squares form reads of a campaign (campaign.discovery.data.CampaignData is one):
    per point the target x (mm), direction d (±1), sample times t (s, points × samples) and sample
    waits since arrival w (s; None when not recorded), the time's source ("time_s" or the point
    order), the environment columns and the air's refractive-index change (None without an air
    log)."""

    @property
    def x(self) -> np.ndarray: ...
    @property
    def d(self) -> np.ndarray: ...
    @property
    def t(self) -> np.ndarray: ...
    @property
    def w(self) -> np.ndarray | None: ...
    @property
    def time_source(self) -> str: ...
    @property
    def env(self) -> dict[str, np.ndarray]: ...
    @property
    def air_index_change(self) -> np.ndarray | None: ...
    def __len__(self) -> int: ...


Shape = dict[str, float]
"""Shape parameters (or held parameters) of an effect by name: period_mm, tau_s, pivot_mm, ..."""
Deviation = Callable[[dict[str, float], np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""An effect's deviation, µm: (its parameters, x mm, d ±1, t s, w s) -> e, broadcast."""
Ranges = dict[str, tuple[float, float]]


@dataclass(frozen=True)
class EffectForm:
    """One effect's least-squares form. coefficients: names of the linear coefficients (model
    parameter names where they are one). shape: the shape parameters that may be searched.
    group: "target" (spatial: cross-validated leaving one target out) or "run" (time: one run
    out)."""

    name: str
    coefficients: tuple[str, ...]
    shape: tuple[str, ...]
    group: str
    columns: Callable[[Samples, Shape, Shape], np.ndarray]
    to_params: Callable[[np.ndarray, Shape, Shape], dict[str, float]] | None = None
    shape_grid: Callable[[Samples, Shape], list[Shape]] | None = None
    sizes: tuple[str, ...] = ()
    """The parameters (or derived quantities, campaign.discovery.fit.DERIVED) that say how large the
    effect is: each must be at least SIZE_SIGMAS standard errors for the effect to be named."""
    ranges: Callable[[Samples], Ranges] | None = None
    """Each parameter's documented physical range on this campaign (docs/error-model.md): an effect
    with a parameter outside is not named, however well it fits."""
    fixed_shape: Callable[[Samples, Shape], Shape] | None = None
    """Shape parameters that are not searched but set from the campaign (the bow's span: the
    targets' range unless the model holds one)."""

    def physical_ranges(self, data: Samples) -> Ranges:
        return {} if self.ranges is None else self.ranges(data)

    def grid(self, data: Samples, held: Shape) -> list[Shape]:
        """The starting values of the searched shape parameters; ValueError for an effect with none."""
        if self.shape_grid is None:
            raise ValueError(f"{self.name} has no shape parameters to search")
        return self.shape_grid(data, held)

    def params(self, coefs: np.ndarray, shape: dict, held: dict) -> dict[str, float]:
        if self.to_params is not None:
            return self.to_params(coefs, shape, held)
        return {**{k: float(v) for k, v in zip(self.coefficients, coefs)}, **shape}


Needs = Literal["wait", "log", "runs"]
"""What a campaign must have for discovery to look for an effect (Effect.needs)."""
FollowUpPart = Literal["dwells", "cluster", "runs", "travel"]
"""The part of a follow-up campaign that tells an effect from its rivals
(campaign.discovery.followup): "dwells" waits before capture varied over a decade at a few
targets; "cluster" a cluster of targets closer than the candidate periods; "runs" twice the runs
over the whole travel; "travel" both directions at a few targets over the whole travel (only when
every effect of the group asks for it)."""


@dataclass(frozen=True, eq=False)
class Effect:
    """One effect an axis can have, everything about it in one place.

    name: its key in a model file ([effects.NAME]). order: where it is listed among the effects
    (the order discovery tries its candidates). params: parameter name -> meaning with its unit
    after the last comma ("cumulative lead error, µm/m"). deviation: what it adds to the
    deviation, µm (None: the simulator does not have it; `environment` follows a campaign's log).
    form: its least-squares form (None: discovery does not have it in its vocabulary, on purpose:
    an error it must locate without a name). defaults: the parameters that may be left out.
    choices, limits, positive: what a model file may give (checked when it is read); check: any
    other rule over its parameters (name, parameters -> the message, or None). rivals: effect -> how to tell the two
    apart (one side of the pair is enough). nested_in: the simpler effect it contains (its special
    case); tends_to: the effect it becomes at the edge of its range (a growth whose time constant
    is far beyond the campaign is a linear drift). derived: quantities computed from its
    parameters and reported beside them. follow_up: its part of a follow-up campaign. may_soak:
    a local error may hide behind it when it is named (a period fitted to a bump, a reversal to a
    bump in one direction), so discovery looks for local errors again without it. period: its shape
    parameter that is a period along the travel (periodic_lead's period_mm), searched over the
    periodogram's peaks, whose aliases at few targets are candidates that stay unresolved. needs:
    what a campaign must have for discovery to look for it ("wait": a capture_wait_s column whose
    waits vary, at a constant wait it is a reversal; "log": an air or material log that varies;
    "runs": two runs or more, to show a run-to-run change). reversal: its column is a reversal
    constant along the travel (backlash's −d/2): what a local term split by direction must beat
    (campaign.discovery.local), since backlash, settling at one wait or their stand-in all look so. One object per
    effect: two are the same only when they are one (compared by identity)."""

    name: str
    order: int
    params: dict[str, str]
    deviation: Deviation | None
    form: EffectForm | None = None
    defaults: dict[str, float] = field(default_factory=dict)
    choices: dict[str, tuple[float, ...]] = field(default_factory=dict)
    limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    positive: tuple[str, ...] = ()
    check: Callable[[str, dict[str, float]], str | None] | None = None
    rivals: dict[str, str] = field(default_factory=dict)
    nested_in: str | None = None
    tends_to: str | None = None
    derived: Callable[[dict[str, float]], dict[str, float]] | None = None
    follow_up: FollowUpPart | None = None
    may_soak: bool = False
    period: str | None = None
    needs: Needs | None = None
    reversal: bool = False

    def __post_init__(self) -> None:
        if self.form is not None and self.form.name != self.name:
            raise ValueError(f"effect {self.name}: its form is named {self.form.name}")
        if self.period is not None and (self.form is None or self.period not in self.form.shape):
            raise ValueError(f"effect {self.name}: its period {self.period} is not a shape parameter of its form")
        if self.deviation is None and self.form is None:
            raise ValueError(f"effect {self.name}: neither simulated nor discovered")

    @property
    def simulated(self) -> bool:
        """Whether the simulated machine has it (and a model file may give it)."""
        return self.deviation is not None

    @property
    def simulator_only(self) -> bool:
        """Whether discovery lacks it (no least-squares form): an error it must locate unnamed."""
        return self.form is None

    def errors(self, params: dict[str, float]) -> str | None:
        """What is wrong with these parameters as a model file gives them (None: nothing), the
        message after "where: "; parameters left out are not checked."""
        name = self.name
        for key, allowed in self.choices.items():
            if key in params and params[key] not in allowed:
                said = [f"{v:g}" for v in allowed]
                return f"'effects.{name}.{key}' must be {', '.join(said[:-1])} or {said[-1]}"
        for key, (low, high) in self.limits.items():
            if key in params and not low <= params[key] <= high:
                return f"'effects.{name}.{key}' must be between {low:g} and {high:g}"
        for key in self.positive:
            if key in params and params[key] <= 0:
                return f"'effects.{name}.{key}' must be > 0"
        return None if self.check is None else self.check(name, params)


LASER_DATUM_MM = 0.0
"""Where the laser reading is zero: the table's positions are the laser's, so an air
refractive-index error (and the material normalisation) pivots at x = 0."""
SIZE_SIGMAS = 2.0
"""An effect is named only when each of its sizes is at least this many of its standard errors."""
SCALE_PPM = 2000.0
"""The largest slope of a scale or of a reversal along the travel, µm/m (the vertical axis of Li et
al. 2022 has -1147 µm/m of scale and -641 µm/m of backlash growth)."""
GROWTH_PPM = 500.0
"""The largest thermal growth (or slope change over a campaign), µm/m: a steel screw 20 K warm grows
230 µm/m."""
SIZE_UM = 1000.0
"""The largest reversal, settling, periodic amplitude or bow coefficient, µm."""
PERIOD_RANGE_MM = (2.0, 100.0)
"""Plausible screw leads searched for a periodic error, mm (at most half the travel)."""
NYQUIST_MARGIN = 1.02
"""On evenly spaced targets the shortest period looked for is this many times twice the spacing (at
exactly twice the spacing a sine can sit on its zeros at every target)."""


def mean_samples(values: np.ndarray) -> np.ndarray:
    return np.nanmean(values, axis=1)


def duration(data: Samples) -> float:
    """The campaign's length in its time (s, or points)."""
    return float(np.nanmax(data.t) - np.nanmin(data.t)) or 1.0


def travel(data: Samples) -> float:
    return float(np.ptp(data.x)) or 1.0


def dwell(data: Samples) -> float:
    """The typical wait before a capture, s (in points without a time column: one point)."""
    if data.time_source != "time_s":
        return 1.0
    if len(stopped := stop_waits(data)):
        return float(np.median(stopped))
    ends = np.sort(np.nanmax(data.t, axis=1))
    return float(np.median(np.diff(ends))) / 2 if len(ends) > 1 else 0.0


def hours(data: Samples) -> np.ndarray:
    """Each capture's time, h (per 3600 points without a time column), averaged over its samples."""
    return mean_samples(data.t) / 3600


def stop_waits(data: Samples) -> np.ndarray:
    """Each point's wait since arrival before its capture (the mean over its samples), s, for the
    points captured at a stop; empty when no wait is recorded. A scan profile's bins, captured
    while moving at constant velocity, have an infinite wait (long settled) and are left out."""
    if data.w is None:
        return np.array([])
    per_point = np.nanmean(data.w, axis=1)
    return per_point[np.isfinite(per_point)]


def waits(data: Samples) -> np.ndarray:
    """The sample waits since arrival, s; ValueError when the table has no capture_wait_s (settling
    is never a candidate then)."""
    if data.w is None:
        raise ValueError("settling needs the waits since arrival (capture_wait_s)")
    return data.w


def tau_grid(low: float, high: float, count: int = 24) -> list[Shape]:
    return [{"tau_s": float(v)} for v in np.geomspace(low, high, count)]


def side(p: dict[str, float], d: np.ndarray) -> np.ndarray | float:
    """1 where the effect acts: both directions (direction 0) or only the one approached from."""
    return 1.0 if p.get("direction", 0.0) == 0 else (d == np.sign(p["direction"])).astype(float)


def legendre(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Legendre polynomials P2 and P3 at u (-1 to 1)."""
    return (3 * u**2 - 1) / 2, (5 * u**3 - 3 * u) / 2


def span_ends(name: str, p: dict[str, float]) -> str | None:
    """The rule of an effect over a span start_mm to end_mm: it must end after it starts."""
    if {"start_mm", "end_mm"} <= set(p) and p["end_mm"] <= p["start_mm"]:
        return f"'effects.{name}.end_mm' must be > start_mm"
    return None


def even_spacing(data: Samples) -> float | None:
    """The spacing of evenly spaced targets, mm (None when they are not evenly spaced: any
    pattern of offsets breaks the aliases of a regular grid, which the period search then lists)."""
    targets = np.unique(np.round(data.x, 6))
    if len(targets) < 3:
        return None
    steps = np.diff(targets)
    return float(np.mean(steps)) if np.ptp(steps) < 1e-3 * np.ptp(targets) else None


def period_limits(data: Samples) -> tuple[float, float]:
    """The range of periods searched, mm: the plausible screw leads (PERIOD_RANGE_MM), at most half
    the travel, and on evenly spaced targets above twice their spacing (shorter periods alias onto
    longer ones there). The low end may be above the high one: nothing is looked for."""
    length = float(np.ptp(data.x)) or 1.0
    spacing = even_spacing(data)
    low = PERIOD_RANGE_MM[0] if spacing is None else max(PERIOD_RANGE_MM[0], 2 * NYQUIST_MARGIN * spacing)
    return low, min(PERIOD_RANGE_MM[1], length / 2)


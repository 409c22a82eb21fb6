"""Random machines with errors discovery has no name for (issue 34 item 8), drawn the way real axes
make them, beside effects of its vocabulary; and how discovery did on each.

`draw(rng, shape, config)` returns the true model (campaign.model effects, the out-of-vocabulary one
among them) and the truth to check against: where the error is (its centre and half-width, or the
step's position), which vocabulary effects the machine has. `judge(result, truth)` says whether
the error was located, whether an effect the machine lacks was named, and the gap against the
noise. Used by tests/test_discovery_draws.py and bench/discovery_draws.py.

Units: mm, µm, s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from campaign.config import Config, parse_config
from campaign.discovery.data import CampaignData
from campaign.discovery.followup import is_drift_shape_group
from campaign.discovery.local import zones
from campaign.discovery.records import LocalRival
from campaign.discovery.result import Discovery
from campaign.plan import build_plan

SHAPES = ("step", "bump", "skewed_bump", "two_regions", "partial_wave", "linear_growth")
"""The out-of-vocabulary shapes drawn ("null": none, the vocabulary part alone)."""

PLAN = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 610.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 600.0
count = {count}
overrun = 5.0
cycles = 5
dwell_s = 2.0
dwell_jitter = 0.8
velocity = 20.0
offsets = "{offsets}"
offset_fraction = 0.45

[capture]
method = "dwell"
average_s = 0.5
"""


def plan_config(count: int, offsets: str) -> Config:
    """The tests' 600 mm axis, `count` targets, golden or uniform ("none") offsets, 5 runs."""
    return parse_config(PLAN.format(count=count, offsets=offsets))


@dataclass
class Truth:
    """What the machine has: shape, the out-of-vocabulary regions (centre, half-width mm; a step's
    position with half-width 0), its size (µm), the vocabulary effects it has, and whether the
    targets can see it at all (some target's deviation from it above twice the noise)."""

    shape: str
    regions: list[tuple[float, float]]
    size_um: float
    vocabulary: set[str]
    noise_um: float
    visible: bool = True
    model: dict = field(default_factory=dict)


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]))


def draw(rng: np.random.Generator, shape: str, config: Config) -> Truth:
    """A machine with one out-of-vocabulary error of `shape` (2-4 µm, width 1-150 mm), a random
    part of the vocabulary (a bow, a backlash, a scale), noise 0.3-0.8 µm."""
    targets = np.array(build_plan(config).targets)
    lo, hi = float(targets.min()), float(targets.max())
    travel = hi - lo
    size = float(rng.uniform(2.0, 4.0)) * _sign(rng)
    width = float(math.exp(rng.uniform(math.log(1.0), math.log(150.0))))
    centre = float(rng.uniform(lo + 0.1 * travel, hi - 0.1 * travel))
    noise = float(rng.uniform(0.3, 0.8))
    effects: dict[str, dict[str, float]] = {"linear_scale": {"ppm": float(rng.uniform(-15, 15))},
                                            "noise": {"sigma_um": noise}}
    vocabulary = set()
    if rng.random() < 0.5:
        effects["nonlinear_lead"] = {"p2_um": float(rng.uniform(-1.5, 1.5)), "p3_um": float(rng.uniform(-1, 1)),
                                     "start_mm": lo, "end_mm": hi}
        vocabulary.add("nonlinear_lead")
    if rng.random() < 0.5:
        effects["backlash"] = {"b_um": float(rng.uniform(1.0, 4.0))}
        vocabulary.add("backlash")
    regions = [(centre, width / 2)]
    if shape == "step":
        effects["local_step"] = {"height_um": size, "at_mm": centre, "rise_mm": width}
        regions = [(centre, max(width / 2, 10.0))]
    elif shape in ("bump", "skewed_bump"):
        skew = float(rng.uniform(0.5, 0.8)) * _sign(rng) if shape == "skewed_bump" else 0.0
        effects["local_defect"] = {"amplitude_um": size, "centre_mm": centre, "width_mm": width, "skew": skew}
    elif shape == "two_regions":
        other = float(rng.uniform(lo + 0.1 * travel, hi - 0.1 * travel))
        while abs(other - centre) < 1.5 * width + 20:
            other = float(rng.uniform(lo + 0.1 * travel, hi - 0.1 * travel))
        width2 = float(math.exp(rng.uniform(math.log(1.0), math.log(150.0))))
        effects["local_defect"] = {"amplitude_um": size, "centre_mm": centre, "width_mm": width}
        effects["second_local_defect"] = {"amplitude_um": float(rng.uniform(2.0, 4.0)) * _sign(rng),
                                          "centre_mm": other, "width_mm": width2}
        regions.append((other, width2 / 2))
    elif shape == "partial_wave":
        length = float(rng.uniform(60.0, 200.0))
        start = float(np.clip(centre - length / 2, lo, hi - length))
        effects["partial_wave"] = {"amplitude_um": abs(size), "period_mm": float(rng.uniform(8.0, 40.0)),
                                   "phase_rad": float(rng.uniform(0, 2 * math.pi)), "start_mm": start,
                                   "end_mm": start + length}
        regions = [(start + length / 2, length / 2)]
    elif shape == "linear_growth":
        hours = 0.21  # the campaign's length, about 12.5 min
        pivot = float(rng.uniform(lo, hi))
        reach = max(abs(hi - pivot), abs(lo - pivot)) * 1e-3
        effects["linear_drift"] = {"rate_ppm_per_h": size / reach / hours, "pivot_mm": pivot}
        regions = [((lo + hi) / 2, travel / 2)]
        vocabulary.add("linear_drift")  # in discovery's vocabulary since issue 34
    elif shape == "null":
        regions = []
    else:
        raise ValueError(shape)
    truth = Truth(shape, regions, abs(size), vocabulary, noise, model=effects)
    truth.visible = bool(regions) and _visible(effects, targets, noise)
    return truth


def _visible(effects: dict, targets: np.ndarray, noise: float) -> bool:
    """Whether some target sees the out-of-vocabulary error above twice the noise."""
    from campaign.model import EFFECTS, effect_um

    total = np.zeros(len(targets))
    for name, p in effects.items():
        if EFFECTS[name].simulator_only or name == "linear_drift":
            params = {**EFFECTS[name].defaults, **p}
            values = effect_um(name, params, targets, 1.0, 750.0, 2.0)
            total = total + values - (values.mean() if name == "linear_drift" else 0.0)
    return bool(np.max(np.abs(total)) > 2 * noise)


@dataclass
class Judged:
    """How discovery did on one draw: located (an out-of-vocabulary region found within its
    width, a step within 10 mm, by a local term of the final model), false names (vocabulary
    effects named that the machine lacks), the gap after against the noise estimate; stated: located
    by a local term, or said as unexplained structure (a region the locator finds in what the final
    model leaves) or as a local error an unresolved effect cannot be told from (its `local_rivals`)
    or as the other shape a local error may have (its `shape_rival`) within the same tolerance (a linear growth: the slope along the travel departing in time, in what
    the final model leaves, or an unresolved group of drifts in time with linear_drift among them: the
    growth is said, its shape in time left open), or bracketed (below); seen: a region the locator finds before anything is named
    within it."""

    located: bool
    false_names: list[str]
    gap_ratio: float
    said: str
    stated: bool = False
    seen: bool = False
    bracketed: bool = False
    """Stated only as lying between two targets with no target between them, as finely as the plan
    lets it be placed when that is coarser than the tolerance (not `located`): a step said between the
    targets that hold it (LocalError.between_mm; or so said as an unresolved period's rival,
    LocalRival.between_mm), or what one target alone shows, said between its
    neighbours (a one-target region in what the final model leaves). Counted in `stated`."""


def _near(truth: Truth, centres: list[float]) -> bool:
    """Is one of `centres` within the truth's tolerance of one of its regions (a step within 10 mm, a
    region within its half-width or 10 mm)?"""
    for centre, half in truth.regions:
        tolerance = 10.0 if truth.shape == "step" else max(half, 10.0)
        if any(abs(c - centre) <= tolerance for c in centres):
            return True
    return False


def every_rival(result: Discovery) -> list[LocalRival]:
    """The local errors said to fit as well as what is in the model: an unresolved effect's
    (`local_rivals`) and a local error's other shape (LocalError.shape_rival)."""
    return [r for u in result.unresolved for r in u.local_rivals] + [
        e.shape_rival for e in result.local_errors if e.shape_rival is not None]


def judge(result: Discovery, truth: Truth) -> Judged:
    found = [(z.centre_mm, (z.region_mm[1] - z.region_mm[0]) / 2) for z in zones(result.local_errors)]
    # a departure at one target says where between its neighbours it lies, not where: bracketed (below)
    found += [(e.params["centre_mm"], e.params["width_mm"] / 2) for e in result.local_errors if e.kind != "target"]
    located = truth.shape == "linear_growth" and "linear_drift" in result.added
    for centre, half in truth.regions:
        tolerance = 10.0 if truth.shape == "step" else max(half, 10.0)
        if any(abs(c - centre) <= tolerance or (truth.shape == "partial_wave" and abs(c - centre) <= half)
               for c, _ in found):
            located = True
    false = [name for name in result.added if name not in truth.vocabulary and name != "linear_scale"]
    gap_ratio = result.gap_after_um / max(result.noise_um, 1e-9)
    said = f"added {result.added}, local {[e.sentence() for e in result.local_errors]}"
    after = result.located_after.along if result.located_after is not None else []
    before = result.located_before.along if result.located_before is not None else []
    if truth.shape == "linear_growth":  # said as the slope along the travel departing in time, not a place
        timed = result.located_after.regions if result.located_after is not None else []
        stated = located or any(r.over == "time" and r.what == "slope" for r in timed) or any(
            "linear_drift" in u.effects and is_drift_shape_group(u.effects) for u in result.unresolved)
    else:
        rivals = [(lo + hi) / 2 for lo, hi in (r.region_mm for r in every_rival(result))]
        stated = located or _near(truth, [r.centre for r in after]) or _near(truth, rivals)
    seen = _near(truth, [r.centre for r in before]) or (truth.shape == "linear_growth" and result.located_before
                                                          is not None and any(r.over == "time"
                                                                              for r in result.located_before.regions))
    brackets = [e.between_mm for e in result.local_errors] + [r.between_mm for r in every_rival(result)]
    bracketed = not stated and truth.shape != "linear_growth" and (truth.shape == "step" and any(
        between is not None and between[0] <= centre <= between[1]
        for between in brackets for centre, _ in truth.regions) or any(
        r.one_target and r.start <= centre <= r.end for r in after for centre, _ in truth.regions) or any(
        e.kind == "target" and e.region_mm[0] <= centre <= e.region_mm[1]  # one target's departure, in the model
        for e in result.local_errors for centre, _ in truth.regions))
    return Judged(located, false, gap_ratio, said, stated or bracketed, seen, bracketed)


def named_out_of_gates(data: CampaignData, result: Discovery) -> list[str]:
    """The named effects of the final model whose size is under 2σ or a parameter outside its physical
    range (campaign.discovery.naming.gate_failures), each with why."""
    from campaign.discovery.naming import gate_failures

    return [f"{name}: {'; '.join(why)}" for name in result.added if name in {t.name for t in result.final.terms}
            and (why := gate_failures(data, result.final, name))]


def oracle_p(data: CampaignData, truth: Truth) -> float:
    """What the campaign can show of the out-of-vocabulary error at all: the F-test p of its exact
    deviation (the simulator's, at its true place and shape: one column, only its size fitted) beside the
    vocabulary the machine has (a scale, and its bow and backlash, fitted). Discovery must also find the
    place and shape, so a p above its ALPHA (0.001) here is an error no method could name or locate from
    this campaign; 1.0 when the truth has no such error."""
    from dataclasses import replace

    from campaign.discovery.fit import (
        Term,
        f_test_p,
        fixed_deviation,
        linear_fit,
        normal_beside,
        solve_normal,
        weighted,
    )
    from campaign.discovery.naming import try_candidate
    from campaign.model import EFFECTS, effect_um

    hidden = [(name, p) for name, p in truth.model.items()
              if EFFECTS[name].simulator_only or name == "linear_drift"]
    waits = data.w if data.w is not None else np.full(data.t.shape, 2.0)
    column = np.zeros(len(data))
    for name, p in hidden:  # averaged over each point's samples, as the capture averages them
        values = effect_um(name, {**EFFECTS[name].defaults, **p}, data.x[:, None], data.d[:, None], data.t, waits)
        column += np.nanmean(values, axis=1)
    if not np.any(column):  # nothing but noise (its deviation is zero: the simulator scatters it)
        return 1.0
    fit = linear_fit(data, [Term("linear_scale")])  # the starting model every draw is discovered from
    for name in sorted(truth.vocabulary - {"linear_drift"}):
        fit = try_candidate(data, fit, name, []).fitted
    blocks, normal, rhs = normal_beside(data, fit.terms, column[:, None])
    beta = solve_normal(normal, rhs)
    prediction = fixed_deviation(data, fit.terms) + blocks.times(beta[:-1]) + column * beta[-1]
    grown = replace(fit, predicted=prediction, rss=float(np.sum(weighted(data, data.y - prediction) ** 2)),
                    n_params=fit.n_params + 1)
    return f_test_p(fit, grown, len(data))

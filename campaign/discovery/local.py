"""Errors outside the vocabulary: where the residual is not noise and no effect of the model has its
shape (a local defect of the screw, a worn zone, a joint between two scale or screw sections), locate
them and add a local term for each (campaign.discovery.effects.local_shape: a Gaussian bump, width
at half height, or a logistic step, width its 10-90 % rise).

The search: a grid of shapes (bump, step), centres (a quarter of the target spacing apart) and
widths (a bump from twice the target spacing, so that at least three targets see it at half its
height or more, to a quarter of the travel; a step from a fifth of the spacing to an eighth of the travel,
with at least two targets on each side), each fitted beside the model with the model projected out; the best is refined
(scipy.optimize.least_squares on centre and width); each shape is tried in both directions and in the
+ or the − direction alone (SIDES). It is added only when it passes the tests every
effect passes (campaign.discovery.naming.naming_tests: BIC, F-test, leave-one-target-out cross-validation), with
the look-elsewhere factor of its search (look_elsewhere with the sides). Then: one amplitude for both directions, or one per direction when that is significantly better
(F-test; from a one-direction start, of the two shapes each refined from it); and whether it changes with
time (an F-test of a term that grows linearly in time, reported, not added). Up to MAX_REGIONS are
found, each beside the ones before (two worn zones, a bump of either sign on each side of a joint).

Units: positions mm (deg), deviations µm (arcsec), times s (or point order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from campaign.discovery.cv import cv_rms_um
from campaign.discovery.data import CampaignData
from campaign.discovery.effects import STEP_RISE, local_shape
from campaign.discovery.fit import (
    Fit,
    Term,
    bic,
    distinct_rows,
    f_test_p,
    fixed_deviation,
    linear_fit,
    normal_beside,
    reduced_residual,
    refine,
    solve_normal,
    span_at_positions,
    weighted,
)
from campaign.discovery.records import LocalRival
from campaign.effects import effects

ALPHA = 0.001
"""Largest p-value of the F-test (after the look-elsewhere factor), as for the vocabulary."""
BIC_MARGIN = 2.0
WIDTHS = 8
"""Widths tried on the grid, logarithmically spaced."""
KINDS = ("bump", "step")
"""The shapes of a local term."""
MAX_REGIONS = 3
"""The most local errors looked for on one axis."""
MIN_SIDE = 2
"""A step is looked for only where at least this many targets lie on each side of its rise."""
STEP_MIN_SPACINGS = 0.2
"""The sharpest step looked for, in target spacings (its place is then known to about a spacing)."""
MAX_CENTRES = 600
"""The most centres on the grid (a quarter of the target spacing apart, or the travel over this)."""
GRID_CELLS = 1_000_000
"""Rows × centres evaluated at a time by the grid (8 MB per array, as periodogram.PERIODOGRAM_CELLS)."""
GRID_MIN_BLOCK = 32
"""The fewest centres the grid evaluates at a time."""
BUMP_MAX_SHARE = 4.0
"""The widest bump looked for is this share of the travel (wider, it is a bow, not a local error)."""
STEP_MAX_SHARE = 8.0
"""The widest step looked for rises over this share of the travel (wider, it is a slope change that
the scale and the bow hold)."""
MIN_WIDTH_SPACINGS = 2.0
"""The narrowest bump looked for, in target spacings (width at half height): three targets see it."""
HOPELESS = 10.0
"""A local term whose ΔBIC on the grid (with the look-elsewhere factor) is above this is not refined; nor
is a vocabulary candidate whose best start is (campaign.discovery.naming.try_candidate)."""
WINDOW_WIDTHS = 5.0
"""The grid evaluates a bump within this many widths of its centre (beyond, exp(-4·ln 2·25) ≈ 1e-30)."""
STEP_FLAT_Z = 40.0
"""The grid evaluates a step where its logistic's argument is within ±this (beyond, 1/(1 + e^-40) is
1 in double precision, and e^-40 ≈ 4e-18 below)."""
STEPPED_SHARE = 0.5
"""A region term whose level after it is at least this share of its peak is a step (its level goes on)."""
MIN_SEEN = 3
"""A bump is looked for only where at least this many targets see it at half its height or more:
fewer cannot tell its size from its width, nor a bump from one target's odd reading."""
TARGET = "target"
"""The local term of a departure at one target alone (fitted at that target's points only): an error
about as narrow as the targets' spacing there or narrower, or that target's own; where between its
neighbours it lies, how wide and how high it is, the data do not say (its size is the reading there). Looked for at every target but the outer two (a departure at the end
of the travel is a slope's or a bow's end as well)."""


@dataclass(frozen=True)
class LocalError:
    """A local error found: its term (in the final model), parameters (amplitude_um, or plus_um and
    minus_um per direction; centre_mm; width_mm, at half height; in the axis's units whatever the
    keys say: deg and arcsec on a rotary axis), their 1-σ errors, which directions show it ("both",
    "+", "-"), whether it changes with time (time_p: F-test p of a linear growth in time; the change
    that growth makes over the campaign and its 1-σ error), the tests it passed, and the gap
    without it (deviation unit)."""

    term: Term
    params: dict[str, float]
    errors: dict[str, float]
    directions: str
    time_p: float
    time_change_um: float
    explained_pct: float
    delta_bic: float
    p_value: float
    cv_before_um: float
    cv_after_um: float
    gap_without_um: float = 0.0
    time_change_error_um: float = 0.0
    position_unit: str = "mm"
    deviation_unit: str = "µm"
    kind: str = "bump"
    """"bump" (centre_mm its peak, width_mm at half its height) or "step" (centre_mm the middle of
    the rise, width_mm the rise from 10 % to 90 %, amplitude the step's height), "target" (a departure
    at the target centre_mm alone: somewhere between its neighbours from_mm and to_mm), or "region" (a term
    whose shape follows the data from start_mm to end_mm, campaign.discovery.unexplained: amplitude
    its peak, centre_mm the peak or, when its level goes on after the region, where it rises most)."""
    between_mm: tuple[float, float] | None = None
    """A step whose rise holds no target: the two targets it lies between. The data show a step
    there, not where between them nor how sharp (the fitted centre and width are then not said). A
    region whose level goes on after it: the neighbouring targets over which it changes most
    (unexplained.steepest_between)."""
    measured_mm: tuple[float, float] | None = None
    """The first and last position measured: what the data show of it lies between them."""
    shape_rival: LocalRival | None = None
    """A local error of the other shape (a step for a bump, a bump for a step) that fits the campaign as
    well, perhaps with an effect beside it (campaign.discovery.rivals.shape_rivals): which shape it is, the
    campaign does not say."""

    @property
    def region_mm(self) -> tuple[float, float]:
        """Where it acts: a bump from one width below its centre to one above; a step over its
        rise (at least a millimetre either side), or, when no target lies on its rise, between the
        two targets either side of it (where between them the data do not say); within the positions
        measured (a bump near the end of the travel reached beyond it)."""
        if self.kind == "region":
            return self.params["start_mm"], self.params["end_mm"]
        if self.kind == TARGET:
            return self.params["from_mm"], self.params["to_mm"]
        if self.kind == "step" and self.between_mm is not None:
            return self.between_mm
        c, w = self.params["centre_mm"], self.params["width_mm"]
        half = w if self.kind == "bump" else max(w / 2, 1.0)
        low, high = self.measured_mm or (-math.inf, math.inf)
        return max(c - half, low), min(c + half, high)

    @property
    def size_key(self) -> str:
        """The parameter that is its size: amplitude_um, or the larger direction's (plus_um on a tie)."""
        if "amplitude_um" in self.params:
            return "amplitude_um"
        return "plus_um" if abs(self.params["plus_um"]) >= abs(self.params["minus_um"]) else "minus_um"

    @property
    def size_um(self) -> float:
        """The peak of the bump, µm (the larger of the two directions when they differ)."""
        return self.params[self.size_key]

    def _sides(self) -> str:
        """Which directions show it, in words: what was seen in each."""
        p, e, dev = self.params, self.errors, self.deviation_unit
        if self.kind == "region":
            if self.directions not in ("+", "-"):
                return "both directions"
            seen, other = ("+", "−") if self.directions == "+" else ("−", "+")
            below = "below 3σ" if abs(p.get("other_um", 0.0)) < 3 * e.get("other_um", math.inf) else "also"
            return (f"seen in the {seen} direction; in the {other} direction {below} ({p.get('other_um', math.nan):+.2g} "
                    f"± {e.get('other_um', math.nan):.2g} {dev})")
        if "plus_um" not in p:
            return "both directions"
        if self.directions == "both":
            return f"both directions ({p['plus_um']:+.2g} {dev} in +, {p['minus_um']:+.2g} {dev} in −)"
        seen, other = ("+", "−") if self.directions == "+" else ("−", "+")
        key = "minus_um" if self.directions == "+" else "plus_um"
        return (f"seen in the {seen} direction; in the {other} direction below 3σ ({p[key]:+.2g} ± "
                f"{e.get(key, math.nan):.2g} {dev})")

    def sentence(self) -> str:
        """'a local error of +2.4 µm at 214 mm, width 18 mm, both directions' or 'a step of -2.6 µm at
        250 mm, rising over 8 mm, both directions' (the axis's units), and its shape's rival if any."""
        return self.shape_sentence() + self.rival_clause()

    def rival_clause(self) -> str:
        """'; or, fitting as well, a step of … (which shape it is, the campaign does not say: …)', or ''
        without a shape rival."""
        if self.shape_rival is None:
            return ""
        low, high = self.shape_rival.region_mm
        return (f"; or, fitting as well, {self.shape_rival.sentence} (which shape it is, the campaign does not "
                f"say: denser targets over {min(low, self.region_mm[0]):.4g} to {max(high, self.region_mm[1]):.4g} "
                f"{self.position_unit} would tell)")

    def shape_sentence(self) -> str:
        """What it is and where, its shape rival left out (sentence)."""
        p, unit = self.params, self.position_unit
        if self.kind == "region":
            where = (f"between the targets at {self.between_mm[0]:.4g} and {self.between_mm[1]:.4g} {unit}"
                     if self.between_mm is not None else f"at {p['centre_mm']:.4g} {unit}")
            after = (f", and {p['level_after_um']:+.2g} {self.deviation_unit} after it (a step {where})"
                     if abs(p["level_after_um"]) >= STEPPED_SHARE * abs(self.size_um) else "")
            return (f"an unexplained local error of {self.size_um:+.2g} {self.deviation_unit} from {p['start_mm']:.4g} "
                    f"to {p['end_mm']:.4g} {unit}{after}, {self._sides()}")
        if self.kind == "step" and self.between_mm is not None:
            low, high = self.between_mm
            return (f"a step of {self.size_um:+.2g} {self.deviation_unit} between the targets at {low:.4g} and "
                    f"{high:.4g} {unit} (where between them and how sharp: not resolved, targets in between would "
                    f"tell), {self._sides()}")
        if self.kind == TARGET and "last_mm" in p:
            return (f"a departure of {self.size_um:+.2g} {self.deviation_unit} at the targets at {p['centre_mm']:.4g} and "
                    f"{p['last_mm']:.4g} {unit} together (the readings there, not the error's peak: an error somewhere "
                    f"between the targets at {p['from_mm']:.4g} and {p['to_mm']:.4g} {unit} that both see; its peak, "
                    f"place, width and shape are not resolved, targets in between would tell), {self._sides()}")
        if self.kind == TARGET:
            return (f"a departure of {self.size_um:+.2g} {self.deviation_unit} at the target at {p['centre_mm']:.4g} "
                    f"{unit} alone (the reading there, not the error's peak: an error somewhere between the targets at "
                    f"{p['from_mm']:.4g} and {p['to_mm']:.4g} {unit}, about as narrow as their spacing or narrower, or "
                    f"that target's own; its peak, place and width are not resolved, targets in between would tell), "
                    f"{self._sides()}")
        if self.kind == "step":
            return (f"a step of {self.size_um:+.2g} {self.deviation_unit} at {p['centre_mm']:.4g} {unit}, rising over "
                    f"{p['width_mm']:.2g} {unit}, {self._sides()}")
        return (f"a local error of {self.size_um:+.2g} {self.deviation_unit} at {p['centre_mm']:.4g} {unit}, width "
                f"{p['width_mm']:.3g} {unit}, {self._sides()}")

    def time_text(self) -> str:
        change = (f"{self.time_change_um:+.2g} ± {self.time_change_error_um:.2g} {self.deviation_unit} over the "
                  f"campaign, F-test p = {self.time_p:.2g}")
        if self.time_p < ALPHA:
            return f"it changes with time ({change})"
        return f"no change with time detected ({change})"

    def as_dict(self) -> dict:
        return {"sentence": self.sentence(), "effect": self.term.name, "kind": self.kind,
                "region_mm": [round(v, 3) for v in self.region_mm],
                **({"between_targets_mm": [round(v, 3) for v in self.between_mm]} if self.between_mm else {}),
                "params": {k: round(v, 4) for k, v in self.params.items()},
                "standard_errors": {k: float(f"{v:.3g}") for k, v in self.errors.items()},
                "directions": self.directions, "time_p_value": float(f"{self.time_p:.3g}"),
                "changes_with_time": bool(self.time_p < ALPHA),
                "time_change_um": round(self.time_change_um, 4),
                "time_change_error_um": round(self.time_change_error_um, 4),
                "explained_pct": round(self.explained_pct, 2),
                "delta_bic": round(self.delta_bic, 2), "p_value": float(f"{self.p_value:.3g}"),
                "cv_before_um": round(self.cv_before_um, 4), "cv_after_um": round(self.cv_after_um, 4),
                "gap_without_um": round(self.gap_without_um, 4),
                **({"shape_rival": self.shape_rival.as_dict()} if self.shape_rival is not None else {})}


def point_weights(data: CampaignData) -> np.ndarray:
    """Each point's weight in the fit (data.row_scale squared; ones when every point is alike)."""
    scale = data.row_scale
    return np.ones(len(data)) if scale is None else scale**2


def gap_um(data: CampaignData, residual: np.ndarray) -> float:
    """The RMS of the residual (µm) with each point weighed as the fit weighs it (campaign.discovery.fit
    .weighted: 1/u² of its table, relative to the coarsest): the fit's own weighted RSS over the sum
    of the weights. The plain RMS when every point is alike (one table)."""
    w = point_weights(data)
    return float(np.sqrt(np.sum(w * residual**2) / np.sum(w))) if len(residual) else 0.0


def width_range(data: CampaignData, kind: str = "bump") -> tuple[float, float] | None:
    """The widths looked for, mm: a bump's from MIN_WIDTH_SPACINGS target spacings (the median
    spacing), a step's from STEP_MIN_SPACINGS, to half the travel; None when the targets are too
    few for that."""
    targets = data.targets_mm
    if len(targets) < 5:
        return None
    spacing = float(np.median(np.diff(targets)))
    low = (MIN_WIDTH_SPACINGS if kind == "bump" else STEP_MIN_SPACINGS) * spacing
    high = float(np.ptp(targets)) / (BUMP_MAX_SHARE if kind == "bump" else STEP_MAX_SHARE)
    return (low, high) if high > low else None


def seen_at(targets: np.ndarray, centre_mm: np.ndarray, width_mm: float) -> np.ndarray:
    """How many targets (sorted) each bump sees at half its height or more (within width/2 of its
    centre)."""
    c = np.asarray(centre_mm, dtype=float)
    return (np.searchsorted(targets, c + width_mm / 2, side="right")
            - np.searchsorted(targets, c - width_mm / 2, side="left"))


def sides(targets: np.ndarray, centre_mm: np.ndarray, width_mm: float) -> np.ndarray:
    """The fewer of the targets (sorted) below and above each step's rise."""
    c = np.asarray(centre_mm, dtype=float)
    below = np.searchsorted(targets, c - width_mm / 2, side="left")
    above = len(targets) - np.searchsorted(targets, c + width_mm / 2, side="right")
    return np.minimum(below, above)


def _seen(targets: np.ndarray, kind: str, centre_mm: np.ndarray, width_mm: float) -> np.ndarray:
    """Whether the targets can tell each local term (centres) from the rest of the model."""
    if kind == "step":
        return sides(targets, centre_mm, width_mm) >= MIN_SIDE
    return seen_at(targets, centre_mm, width_mm) >= MIN_SEEN


def look_elsewhere(data: CampaignData, sides: int = 1) -> float:
    """About how many independent local terms a search tries: one per target, octave of width and shape,
    one per target for a departure there alone (TARGET) and one for it with the next, times `sides`: the
    grid's (find_local) are len(SIDES), two independent columns of which it takes the best of three
    projections of the residual, about three times as likely by chance as one. The region terms (their
    side is the locator's) and the routes' scores count one."""
    total = 2.0  # a departure at one target (TARGET), and one at it and the next together
    for kind in KINDS:
        widths = width_range(data, kind)
        total += 1.0 if widths is None else 1 + math.log2(widths[1] / widths[0])
    return len(data.targets_mm) * total * sides


def term_kind(term: Term) -> str:
    return "step" if "_step" in term.name else TARGET if "_target" in term.name else "bump"


def local_term(centre_mm: float, width_mm: float, by_direction: bool = False, kind: str = "bump",
               index: int = 1) -> Term:
    """A local term (a bump or a step)."""
    return Term(local_name(kind, by_direction, index), {}, False,
                {"centre_mm": float(centre_mm), "width_mm": float(width_mm)})


def local_name(kind: str, by_direction: bool, index: int) -> str:
    """The name of a local term of `kind` (bump, step, TARGET); the `index`-th on the axis is named with
    "#index" from the second on."""
    suffix = {"step": "_step", TARGET: "_target"}.get(kind, "")
    return "local_error" + suffix + ("_by_direction" if by_direction else "") + (f"#{index}" if index > 1 else "")


def target_term(targets: np.ndarray, at_mm: float, by_direction: bool = False, index: int = 1,
                pair: bool = False) -> Term:
    """The local term of a departure at the inner target `at_mm` of `targets` (sorted) alone (TARGET), or
    with `pair` at it and the next target together (one size: an error between them that both see):
    its shape holds the target (centre_mm), the next one with `pair` (last_mm), and the neighbours
    either side (from_mm, to_mm), between which the error lies; no width: the data do not say one."""
    k = int(np.argmin(np.abs(targets - at_mm)))
    last = min(k + 1, len(targets) - 1) if pair else k
    low, high = float(targets[max(k - 1, 0)]), float(targets[min(last + 1, len(targets) - 1)])
    shape = {"centre_mm": float(targets[k]), "from_mm": low, "to_mm": high}
    if pair:
        shape["last_mm"] = float(targets[last])
    return Term(local_name(TARGET, by_direction, index), {}, False, shape)


def on_sides(term: Term, by_direction: bool) -> Term:
    """The same local term (place, shape, index) with one amplitude per direction, or one for both."""
    return Term(local_name(term_kind(term), by_direction, term_index(term)), {}, False, dict(term.shape))


def is_local(term: Term) -> bool:
    return term.name.startswith("local_error")


SIDES = (0, 1, -1)
"""The grid's local terms: in both directions (0), or in the + or the − direction alone (a joint or a
worn zone that only one approach meets, as a step seen only when the nut bears on one flank)."""


def _grid_best(data: CampaignData, fit: Fit, kinds: tuple[str, ...] = KINDS, directions: tuple[int, ...] = SIDES
               ) -> tuple[str, float, float, int] | None:
    """The (shape, centre, width, side) on the grid whose term explains most of the residual beside the
    model (side: one of `directions`, SIDES); None when the targets can see none. `kinds`: the shapes looked
    for (KINDS, and a departure at one target or two, when all)."""
    targets = data.targets_mm
    step = max(float(np.median(np.diff(targets))) / 4, float(np.ptp(targets)) / MAX_CENTRES)
    centres = np.arange(targets[0], targets[-1] + step / 2, step)
    r = weighted(data, data.y - fit.prediction)
    # a local shape takes one value per distinct position: the sums below are over those, with the
    # residual's and the basis's sums there (exactly the sums over the weighted rows: a row's shape
    # is its weight's square root, `root`, times the shape at its position); a term of one direction
    # is the same shape on that direction's rows alone, so its sums are over those rows (the others go
    # to one more position, dropped)
    first, where = distinct_rows(data)
    xs = data.x[first]
    root = data.row_scale if data.row_scale is not None else np.ones(len(data))
    scanned = []
    for which in directions:
        rows = np.ones(len(data), dtype=bool) if which == 0 else data.d == which
        if not rows.any() or (which != 0 and rows.all()):
            continue
        at = np.where(rows, where, len(xs))
        count = np.bincount(at, root**2, minlength=len(xs) + 1)[:-1]
        # per position: the residual's sum, then the basis's (one product gives both; the basis's from
        # the design's blocks, span_at_positions: no n × p design on a dense table)
        q_at, qr = span_at_positions(data, fit, at, len(xs) + 1)
        sums = np.column_stack([np.bincount(at, root * r, minlength=len(xs) + 1), q_at])[:-1]
        scanned.append(_Side(which, count, sums, qr))
    _grid_scan(data, targets, centres, step, xs, scanned, kinds)
    if kinds == KINDS:
        _target_scan(targets, xs, scanned, NORM_FLOOR * len(data))
    best, power_best = None, -1.0
    for side in scanned:  # in `directions` order, each side's best in the grid's order
        if side.best is not None and side.best[3] > power_best:
            best, power_best = (side.best[0], side.best[1], side.best[2], side.side), side.best[3]
    return best if power_best > 0 else None


@dataclass(eq=False)
class _Side:
    """The sums one side of the grid needs (_grid_best): at each distinct position the weights of the
    rows the term covers (`count`) and the sums of the weighted residual, then of the basis (`sums`),
    those from each position on (for a step), Qᵀ times the weighted residual (`qr`), and the best
    (shape, centre, width, power) found so far."""

    side: int
    count: np.ndarray
    sums: np.ndarray
    qr: np.ndarray
    best: tuple[str, float, float, float] | None = None
    above: np.ndarray = field(init=False)
    count_above: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.above = np.vstack([np.cumsum(self.sums[::-1], axis=0)[::-1], np.zeros((1, self.sums.shape[1]))])
        self.count_above = np.append(np.cumsum(self.count[::-1])[::-1], 0.0)


NORM_FLOOR = 1e-12
"""A grid term whose column outside the model's span has a squared norm below this times the rows holds
nothing the model does not: its power is zero."""


def _target_scan(targets: np.ndarray, xs: np.ndarray, sides: list[_Side], tiny: float) -> None:
    """A departure at one inner target alone (TARGET) for every target at once, and at two neighbouring
    inner targets together: its column is 1 on that target's rows (on the two targets' rows), so its sums
    are that target's own (the two's together); each side's best kept in it when larger, a pair's with
    the spacing to the next target as its width (a single target's: 0)."""
    if len(targets) < 3:
        return
    at = np.searchsorted(targets, np.round(xs, 6))  # the target of each distinct position
    for side in sides:
        sums = np.zeros((len(targets), side.sums.shape[1]))
        np.add.at(sums, at, side.sums)
        count = np.bincount(at, side.count, minlength=len(targets))
        for pair, (these, weights) in enumerate(((sums, count), (sums[:-1] + sums[1:], count[:-1] + count[1:]))):
            qg = these[:, 1:]
            norm = weights - (qg * qg).sum(1)
            rg = these[:, 0] - qg @ side.qr
            power = np.where(norm > tiny, rg**2 / np.maximum(norm, 1e-300), 0.0)
            power[[0, -1]] = 0.0  # never at the outer targets (a pair's last is the next target)
            i = int(np.argmax(power))
            if power[i] > (side.best[3] if side.best is not None else -1.0):
                side.best = (TARGET, float(targets[i]), float(targets[i + 1] - targets[i]) if pair else 0.0,
                             float(power[i]))


def _grid_scan(data: CampaignData, targets: np.ndarray, centres: np.ndarray, step: float, xs: np.ndarray,
               sides: list[_Side], kinds: tuple[str, ...]) -> None:
    """The grid over shapes (`kinds`), widths and centres, each shape's values at the positions computed
    once for every side; each side's best kept in it."""
    for kind in kinds:
        widths = width_range(data, kind)
        if widths is None:
            continue
        for width in np.geomspace(*widths, WIDTHS):
            # only the positions where the shape is not flat are evaluated (a bump is below 1e-30 of
            # its height beyond WINDOW_WIDTHS widths of its centre; a step is exactly 1 in double
            # precision above its window, and below 1e-17 under it): the rest is `above` for a step
            reach = WINDOW_WIDTHS * width if kind == "bump" else STEP_FLAT_Z * width / STEP_RISE
            at, binned = _binned(xs, sides, width / GRID_BINS_PER_WIDTH)
            block = max(GRID_MIN_BLOCK, math.ceil(2 * reach / step))  # centres at a time
            if block * len(at) > GRID_CELLS:  # memory linear in the positions
                block = max(GRID_MIN_BLOCK, GRID_CELLS // max(len(at), 1))
            powers = [np.zeros(len(centres)) for _ in sides]
            for lo in range(0, len(centres), block):
                c = centres[lo:lo + block]
                i0, i1 = np.searchsorted(at, [c[0] - reach, c[-1] + reach], side="left")
                g = local_shape(at[i0:i1, None], c[None, :], width, kind)
                squared = g * g
                for side, (count, sums, above, count_above), power in zip(sides, binned, powers):
                    # r'·(column), then Q'·(column): the part in the model's span (as (columnᵀ·sums)ᵀ:
                    # BLAS is many times faster so than with the few rows first)
                    both = (g.T @ sums[i0:i1]).T
                    norm = count[i0:i1] @ squared
                    if kind == "step":
                        both += above[i1][:, None]
                        norm += count_above[i1]
                    qg = both[1:]
                    norm = norm - (qg * qg).sum(0)
                    rg = both[0] - side.qr @ qg
                    power[lo:lo + block] = np.where(norm > NORM_FLOOR * len(data), rg**2 / np.maximum(norm, 1e-300),
                                                    0.0)
            unseen = ~_seen(targets, kind, centres, width)
            for side, power in zip(sides, powers):
                power[unseen] = 0.0
                i = int(np.argmax(power))
                if power[i] > (side.best[3] if side.best is not None else -1.0):
                    side.best = (kind, float(centres[i]), float(width), float(power[i]))


GRID_BINS_PER_WIDTH = 200
"""On the grid, a shape of width w is evaluated once per bin w/this wide when the positions are denser
(a dense table's wide shapes): their sums added there, the shape taken at the bin's mean position
(within the bin it departs from that value by at most 0.4 % of its height: a bump's steepest slope is
1.43/w, a step's 1.1/w; the search's best is refined by least squares on the rows after)."""


def _binned(xs: np.ndarray, sides: list[_Side], bin_mm: float
            ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]]:
    """The positions (sorted) the grid evaluates a shape at, and each side's count, sums and sums from
    each position on (`above`, `count_above`, one longer) there: the distinct positions themselves,
    or, when bins `bin_mm` wide would hold two or more on average, those bins (sums added, the mean
    position)."""
    whole = [(side.count, side.sums, side.above, side.count_above) for side in sides]
    if len(xs) < 2 or bin_mm * (len(xs) - 1) < 2 * float(xs[-1] - xs[0]):
        return xs, whole
    index = np.floor((xs - xs[0]) / bin_mm).astype(np.int64)
    starts = np.flatnonzero(np.diff(index, prepend=-1))  # xs sorted: each bin's positions together
    ends = np.append(starts, len(xs))
    at = np.add.reduceat(xs, starts) / np.diff(ends)
    return at, [(np.add.reduceat(count, starts), np.add.reduceat(sums, starts, axis=0), above[ends], count_above[ends])
                for count, sums, above, count_above in whole]


def _refine(data: CampaignData, terms: list[Term], start: tuple[float, float], kind: str, by_direction: bool,
            index: int) -> Fit:
    """Centre and width of the local term beside `terms`, by least squares from `start`."""
    from scipy import optimize

    targets = data.targets_mm
    widths = width_range(data, kind) or (start[1], start[1] * 1.001)
    lower, upper = np.array([targets[0], widths[0]]), np.array([targets[-1], widths[1]])

    def fit_at(v: np.ndarray) -> Fit:
        return linear_fit(data, [*terms, local_term(v[0], v[1], by_direction, kind, index)])

    x0 = np.clip(np.array(start, dtype=float), lower + 1e-9, upper - 1e-9)

    def at(v: np.ndarray) -> list[Term]:
        return [*terms, local_term(v[0], v[1], by_direction, kind, index)]

    nearby = np.clip(x0 + widths[0], lower, upper)
    reduced = reduced_residual(data, at(x0), [len(terms)], [at(x0), at(nearby)])  # the same steps, fewer rows

    def residual(v: np.ndarray) -> np.ndarray:
        return reduced(at(v)) if reduced is not None else weighted(data, data.y - fit_at(v).prediction)

    result = optimize.least_squares(residual, x0, bounds=(lower, upper),
                                    x_scale=np.array([widths[0], widths[0]]), diff_step=1e-4)
    best, first = fit_at(result.x), fit_at(x0)
    return best if best.rss <= first.rss else first


def shapes_refined(data: CampaignData, terms: list[Term]) -> list[Term]:
    """`terms` with each local term's centre and width refined beside the others (from their current
    values, one after the other) and then every searched shape of the rest (fit.refine)."""
    terms = list(terms)
    for i, term in enumerate(terms):
        if is_local(term):
            terms[i] = _refine_term(data, terms[:i] + terms[i + 1:], term).terms[-1]
    return refine(data, terms).terms


def term_index(term: Term) -> int:
    """Which local term on the axis it is: the "#index" in its name, 1 for the first."""
    return int(term.name.split("#")[1]) if "#" in term.name else 1


def _refine_term(data: CampaignData, others: list[Term], term: Term) -> Fit:
    """The local `term`'s centre and width refined beside `others`, from its current values (_refine); a
    departure at one target (TARGET) has no shape to refine: refitted."""
    if term_kind(term) == TARGET:
        return linear_fit(data, [*others, term])
    return _refine(data, others, (term.shape["centre_mm"], term.shape["width_mm"]), term_kind(term),
                   "_by_direction" in term.name, term_index(term))


def _index(fit: Fit, name: str) -> int:
    return next(k for k, t in enumerate(fit.terms) if t.name == name)


def _errors(data: CampaignData, fit: Fit, name: str, step: float = 1e-3) -> dict[str, float]:
    """1-σ errors of the local term `name`'s amplitudes, centre and width (cov = s²·(JᵀJ)⁻¹ over every
    coefficient of the fit and the two shape parameters, the other shapes held; a departure at one
    target's amplitudes alone: its place is the target; likewise a step whose rise holds no target or
    one (unresolved_rise): what it says is the difference between the levels of the targets either
    side, not where between them nor how sharp, and its shape moved between them trades its amplitude
    for the fraction of the rise the nearer target reads (a 4.1 µm step between targets 93 mm apart,
    its rise ending 2 mm before one of them: ± 2.7 µm with its shape free, bench seed 53, draw 8314))."""
    i = _index(fit, name)
    term, coefs = fit.terms[i], fit.coefs[i]
    bracketed = term_kind(term) == "step" and unresolved_rise(data, term.shape) is not None
    keys = () if term_kind(term) == TARGET or bracketed else ("centre_mm", "width_mm")
    extra = np.zeros((len(data), len(keys)))
    for j, key in enumerate(keys):
        h = step * term.shape["width_mm"]
        moved = replace(term, shape={**term.shape, key: term.shape[key] + h})
        extra[:, j] = (moved.columns(data) - term.columns(data)) @ coefs / h
    blocks, normal, _ = normal_beside(data, fit.terms, extra)  # JᵀWJ, no n × p design
    n, p = len(data), len(normal)
    if n <= p:
        return {}
    cov = np.linalg.pinv(normal) * fit.rss / (n - p)
    names = ["amplitude_um"] if "_by_direction" not in term.name else ["plus_um", "minus_um"]
    mine = blocks.slice_of(fit.terms, i)
    out = {name: float(math.sqrt(max(cov[j, j], 0.0))) for name, j in zip(names, range(mine.start, mine.stop))}
    for j, key in enumerate(keys):
        out[key] = float(math.sqrt(max(cov[p - len(keys) + j, p - len(keys) + j], 0.0)))
    return out


def _time_test(data: CampaignData, fit: Fit, name: str) -> tuple[float, float, float]:
    """F-test p of the local term `name` growing linearly in time beside `fit` (its shape held), the
    change that growth would have over the campaign and its 1-σ error (deviation unit)."""
    term = fit.terms[_index(fit, name)]
    tm = np.nanmean(data.t, axis=1)
    span = float(np.ptp(tm)) or 1.0
    growth = term.columns(data).sum(axis=1) * (tm - tm.mean()) / span
    base = fixed_deviation(data, fit.terms)
    blocks, normal, rhs = normal_beside(data, fit.terms, growth[:, None])  # no n × p design (dense tables)
    beta = solve_normal(normal, rhs)
    prediction = base + blocks.times(beta[:-1]) + growth * beta[-1]
    grown = replace(fit, predicted=prediction, rss=float(np.sum(weighted(data, data.y - prediction) ** 2)),
                    n_params=fit.n_params + 1)
    n, p = len(data), len(normal)
    cov = np.linalg.pinv(normal) * grown.rss / max(n - p, 1)
    return f_test_p(fit, grown, len(data)), float(beta[-1]), float(math.sqrt(max(cov[-1, -1], 0.0)))


def find_local(data: CampaignData, fit: Fit, index: int = 1) -> LocalError | None:
    """The local error beside `fit`'s model (the `index`-th on the axis), or None when no local term
    passes the tests."""
    if width_range(data) is None or fit.rss <= 0:
        return None
    n = len(data)
    start = _grid_best(data, fit)
    if start is None:
        return None
    kind, centre, width, side = start
    factor = look_elsewhere(data, len(SIDES))
    placed = target_term(data.targets_mm, centre, side != 0, index, pair=width > 0) if kind == TARGET else local_term(
        centre, width, side != 0, kind, index)
    on_grid = linear_fit(data, [*fit.terms, placed])
    if bic(on_grid, n) - bic(fit, n) + 2 * math.log(factor) > HOPELESS:
        return None  # refining the shape would not bring it near the tests
    if kind == TARGET:  # no shape to refine: its place is the target
        best = linear_fit(data, [*fit.terms, on_sides(placed, False)])
        split = on_grid if side != 0 else linear_fit(data, [*fit.terms, on_sides(placed, True)])
        if f_test_p(best, split, n) < ALPHA and _differs_locally(data, fit, split.terms[-1]):
            best = split
    else:
        best = _refine(data, fit.terms, (centre, width), kind, False, index)
        term = best.terms[-1]
        split = _refine(data, fit.terms, (centre, width), kind, True, index) if side != 0 else linear_fit(
            data, [*fit.terms, on_sides(term, True)])
        if f_test_p(best, split, n) < ALPHA and _differs_locally(data, fit, split.terms[-1]):
            best = split if side != 0 else _refine(data, fit.terms, (term.shape["centre_mm"],
                                                                     term.shape["width_mm"]), kind, True, index)
        shape = best.terms[-1].shape
        if not _seen(data.targets_mm, kind, np.array(shape["centre_mm"]), shape["width_mm"]):
            # refined a little past what the targets can tell (a bump 64 mm wide seen at half its height by
            # two targets 30 mm apart, where the grid's 68 mm saw three): the grid's own shape, which they see
            best = linear_fit(data, [*fit.terms, on_sides(placed, "_by_direction" in best.terms[-1].name)])
    delta_bic = bic(best, n) - bic(fit, n) + 2 * math.log(factor)
    p_value = min(1.0, f_test_p(fit, best, n) * factor)
    groups = data.target_index
    cv_before, cv_after = cv_rms_um(data, fit.terms, groups), cv_rms_um(data, best.terms, groups)
    if not (delta_bic < -BIC_MARGIN and p_value < ALPHA and cv_after < cv_before):
        return None
    return describe(data, best, best.terms[-1].name, explained_pct=100 * (1 - best.rss / fit.rss),
                    delta_bic=delta_bic, p_value=p_value, cv_before_um=cv_before, cv_after_um=cv_after,
                    gap_without_um=gap_um(data, data.y - fit.prediction))


def other_shape(data: CampaignData, fit: Fit, kind: str, index: int) -> Fit | None:
    """`fit` with the best local term of `kind` ("bump" or "step", in both directions) beside its model:
    the grid's best of that shape in both directions, its centre and width refined (the grid's own when
    refined past what the targets can tell, as find_local); None when the targets can see none."""
    start = _grid_best(data, fit, (kind,), (0,))
    if start is None:
        return None
    _, centre, width, _ = start
    best = _refine(data, fit.terms, (centre, width), kind, False, index)
    shape = best.terms[-1].shape
    if _seen(data.targets_mm, kind, np.array(shape["centre_mm"]), shape["width_mm"]):
        return best
    return linear_fit(data, [*fit.terms, local_term(centre, width, False, kind, index)])


def reversal_name() -> str | None:
    """The registered effect whose column is a reversal constant along the travel (Effect.reversal):
    what backlash, settling at one wait, or the stand-in for them hold; None when no effect with a form
    says so."""
    return next((e.name for e in effects() if e.reversal and e.form is not None), None)


def _differs_locally(data: CampaignData, fit: Fit, term: Term) -> bool:
    """Do the directions differ over the local term's region more than a reversal constant along the
    whole travel would make them? Beside a model without a reversal, a term split by direction would
    otherwise take a machine's backlash or settling where it happens to lie, and the vocabulary would
    not see it (a reviewer saw +4.3 µm in − and +1.0 µm in + for a 2.5 µm bump beside a 1.8 µm backlash
    and settling)."""
    reversal = reversal_name()
    if reversal is None or any(t.name == reversal for t in fit.terms):
        return True
    beside = [*fit.terms, Term(reversal)]
    both = linear_fit(data, [*beside, on_sides(term, False)])
    split = linear_fit(data, [*beside, on_sides(term, True)])
    return f_test_p(both, split, len(data)) < ALPHA


def find_locals(data: CampaignData, fit: Fit) -> list[LocalError]:
    """Up to MAX_REGIONS local errors beside `fit`'s model, each found beside the ones before."""
    found: list[LocalError] = []
    current = fit
    for index in range(1, MAX_REGIONS + 1):
        local = find_local(data, current, index)
        if local is None:
            break
        found.append(local)
        current = linear_fit(data, [*current.terms, local.term])
    return found


def passes(data: CampaignData, without: Fit, with_local: Fit,
           cv_um: tuple[float, float] | None = None, sides: int = 1) -> bool:
    """Does the local term in `with_local` pass the tests against the same model without it (BIC
    and F-test with the look-elsewhere factor of its search, leave-one-target-out CV)? `sides`: the
    grid's len(SIDES) for a term it found, 1 for a region term (its side is the locator's). `cv_um`: the
    two models' CV RMS (without, with) when already known (campaign.discovery.cv.GrowingFit)."""
    n, factor = len(data), look_elsewhere(data, sides)
    delta_bic = bic(with_local, n) - bic(without, n) + 2 * math.log(factor)
    p_value = min(1.0, f_test_p(without, with_local, n) * factor)
    if not (delta_bic < -BIC_MARGIN and p_value < ALPHA):
        return False
    groups = data.target_index
    before, after = cv_um or (cv_rms_um(data, without.terms, groups), cv_rms_um(data, with_local.terms, groups))
    return bool(after < before)


def describe(data: CampaignData, fit: Fit, name: str, *, explained_pct: float, delta_bic: float, p_value: float,
             cv_before_um: float, cv_after_um: float, gap_without_um: float = 0.0) -> LocalError:
    """The LocalError of the local term `name` in `fit`: parameters, errors, directions, time; the tests
    it passed as given (LocalError's fields of the same names)."""
    term = fit.terms[_index(fit, name)]
    params = fit.params()[term.name]
    errors = _errors(data, fit, name)
    directions = "both"
    if "_by_direction" in term.name:
        shows = {side: abs(params[key]) > 3 * errors.get(key, math.inf) for side, key in (("+", "plus_um"),
                                                                                          ("-", "minus_um"))}
        if shows["+"] != shows["-"]:
            directions = "+" if shows["+"] else "-"
    time_p, change, change_error = _time_test(data, fit, name)
    return LocalError(term, params, errors, directions, time_p, change, explained_pct, delta_bic, p_value,
                      cv_before_um, cv_after_um, gap_without_um=gap_without_um, time_change_error_um=change_error,
                      position_unit=data.position_unit, deviation_unit=data.deviation_unit, kind=term_kind(term),
                      between_mm=unresolved_rise(data, params) if term_kind(term) == "step" else None,
                      measured_mm=(float(np.min(data.x)), float(np.max(data.x))))


def unresolved_rise(data: CampaignData, params: dict[str, float]) -> tuple[float, float] | None:
    """The targets either side of a step's middle when its rise (centre ± width/2) holds no target or
    one: one level partway up says on which side of that target the middle lies (past half the step:
    before it), not where nor how sharp (a step was fitted at 411.8 ± 1.2 mm, rising over 12 mm, from
    targets 55 mm apart). None when two targets or more lie on the rise (or the step is at the end of
    the targets)."""
    targets = np.unique(data.x)
    c, w = params["centre_mm"], params["width_mm"]
    if np.sum(np.abs(targets - c) <= w / 2) >= 2:
        return None
    below, above = targets[targets < c], targets[targets >= c]
    if not len(below) or not len(above):
        return None
    return float(below[-1]), float(above[0])


def refit_local(data: CampaignData, fit: Fit, found: LocalError) -> tuple[Fit, LocalError]:
    """After the vocabulary was searched again beside the local terms: this one's centre and width
    refined beside the final model (the other local terms included), and its description from that
    fit (the tests it passed are kept)."""
    others = [t for t in fit.terms if t.name != found.term.name]
    refined = _refine_term(data, others, found.term)
    best = refined if refined.rss <= fit.rss else fit
    again = describe(data, best, found.term.name, explained_pct=found.explained_pct, delta_bic=found.delta_bic,
                     p_value=found.p_value, cv_before_um=found.cv_before_um, cv_after_um=found.cv_after_um,
                     gap_without_um=gap_um(data, data.y - linear_fit(data, others).prediction))
    return best, again


@dataclass(frozen=True)
class Zone:
    """Where one error outside the vocabulary is, in words: a local term alone, or a step up and a
    step down of about the same size (a raised or sunken zone with a flat top, which two steps
    follow better than one bump). region_mm: from, to; size_um: its height; sentence: what it is."""

    region_mm: tuple[float, float]
    size_um: float
    sentence: str
    members: tuple[LocalError, ...]

    @property
    def centre_mm(self) -> float:
        return (self.region_mm[0] + self.region_mm[1]) / 2


PAIRED_STEPS = 0.5
"""Two neighbouring steps of opposite sign whose heights differ by at most this share of the larger
are one zone."""


def zones(errors: list[LocalError]) -> list[Zone]:
    """The local errors along the axis as zones: neighbouring steps of opposite sign and about the same
    height (PAIRED_STEPS) are one raised or sunken zone; every other local error is its own."""
    ordered = sorted(errors, key=lambda e: e.params["centre_mm"])
    out: list[Zone] = []
    i = 0
    while i < len(ordered):
        a = ordered[i]
        b = ordered[i + 1] if i + 1 < len(ordered) else None
        if (b is not None and a.kind == b.kind == "step" and a.size_um * b.size_um < 0
                and abs(a.size_um + b.size_um) <= PAIRED_STEPS * max(abs(a.size_um), abs(b.size_um))):
            start, end = a.region_mm[0], b.region_mm[1]
            size = (a.size_um - b.size_um) / 2
            unit, dev = a.position_unit, a.deviation_unit
            said = (f"a {'raised' if size > 0 else 'sunken'} zone of {size:+.2g} {dev} from "
                    f"{a.params['centre_mm']:.4g} to {b.params['centre_mm']:.4g} {unit} (a step of {a.size_um:+.2g} "
                    f"{dev} rising over {a.params['width_mm']:.2g} {unit}, one of {b.size_um:+.2g} {dev} over "
                    f"{b.params['width_mm']:.2g} {unit}), {a._sides()}")
            out.append(Zone((start, end), size, said + a.rival_clause() + b.rival_clause(), (a, b)))
            i += 2
            continue
        out.append(Zone(a.region_mm, a.size_um, a.sentence(), (a,)))
        i += 1
    return out

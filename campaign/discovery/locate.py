"""Where the measurement departs from the model, before anything is named (issue 34 item 1): a
model-free smoother of the residual (measured - model, µm) over position, one per direction, and
over time, each with a band; the regions where the smoothed residual leaves its band, with their
shape in words (step, bump, slope change, wave, or a level over the whole travel).

The smoother is a penalised cubic B-spline (a P-spline: at most MAX_BASIS basis functions, a
second-difference penalty). Over position it smooths the residual's mean per target and
direction (weights: the points in each, each weighed by 1/u² when tables of different uncertainty
are fitted together, CampaignData.u), and its flexibility (the penalty) is chosen by
leave-one-target-out cross-validation, which for a linear smoother is exact from the hat matrix's
diagonal. Over time it smooths what the targets' means leave (the change from run to run) as a
level and a slope along the axis that both vary in time (a varying-coefficient P-spline), its
penalty chosen by generalised cross-validation. The band is the smoother's Bayesian standard error
(σ² (BᵀWB + λP)⁻¹, σ the run-to-run scatter pooled over targets and directions) times the normal
quantile that holds a BAND_ALPHA chance of a false region over the curve's effective number of
parameters (Bonferroni). The cost is linear in the rows: sparse B-spline rows (4 per row), a
MAX_BASIS × MAX_BASIS system per penalty; nothing n × n.

Units: positions mm (deg), deviations µm (arcsec), times s (or point order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from campaign.discovery.data import CampaignData, keep_rows

MAX_BASIS = 150
"""The most B-spline basis functions of one smoother (resolution: the travel over about this)."""
PENALTIES = np.geomspace(1e-6, 1e6, 49)
"""Penalties tried, relative to trace(BᵀWB) / trace(P)."""
BAND_ALPHA = 0.01
"""Chance of a false region along one curve (Bonferroni over its effective number of parameters)."""
GRID = 481
"""Points at which each curve is evaluated and reported."""
DIRECTIONS = {1: "+", -1: "-"}


@dataclass(frozen=True)
class Region:
    """One place where the smoothed residual leaves its band. over: "position" (start, end in mm or
    deg) or "time" (s, or points without a time column); what: "deviation" (over position), "level"
    or "slope" (over time: the mean, or the change along the travel from one end to the other);
    peak: the largest smoothed residual there (µm), at peak_at; direction: "both", "+", "-" or
    "opposite" (of opposite sign in the two directions, as a reversal is); shape: step, bump,
    slope change, wave, level."""

    over: str
    what: str
    start: float
    end: float
    peak_um: float
    peak_at: float
    direction: str
    shape: str
    unit: str = "mm"
    deviation_unit: str = "µm"
    one_target: bool = False
    """Shown by one target alone (odd_targets): narrower than the spacing of the targets."""

    @property
    def centre(self) -> float:
        """The middle of the region; a step's place is where it changes most (peak_at); one target's
        departure is at that target (peak_at: the error reaches it, wherever between its neighbours
        it begins and ends)."""
        return self.peak_at if self.shape == "step" or self.one_target else (self.start + self.end) / 2

    def sentence(self) -> str:
        """'a bump of +2.9 µm from 231 to 268 mm (peak at 250 mm), both directions'."""
        dev = self.deviation_unit
        sides = {"both": "both directions", "+": "the + direction only", "-": "the − direction only",
                 "opposite": "opposite in the two directions"}[self.direction]
        where = f"from {self.start:.4g} to {self.end:.4g} {self.unit} (peak at {self.peak_at:.4g} {self.unit})"
        if self.over == "time":
            thing = "the level" if self.what == "level" else "the slope along the travel"
            return f"{thing} departs in time: {_article(self.shape)} {self.shape} of {self.peak_um:+.2g} {dev} {where}"
        return f"{_article(self.shape)} {self.shape} of {self.peak_um:+.2g} {dev} {where}, {sides}"

    def as_dict(self) -> dict:
        return {"over": self.over, "what": self.what, "from": round(self.start, 3), "to": round(self.end, 3),
                "peak_um": round(self.peak_um, 4), "peak_at": round(self.peak_at, 3), "direction": self.direction,
                "shape": self.shape, "unit": self.unit, "sentence": self.sentence(),
                **({"one_target": True} if self.one_target else {})}


def _article(shape: str) -> str:
    return "an" if shape[0] in "aeiou" else "a"


@dataclass
class Curve:
    """One smoother: over "position" (direction "+", "-") or "time" (what "level" or "slope"),
    evaluated at `at`: value and band half-width (µm); the effective number of parameters, the
    penalty chosen and its cross-validated RMS (µm)."""

    over: str
    what: str
    direction: str
    at: np.ndarray
    value_um: np.ndarray
    band_um: np.ndarray
    dof: float
    penalty: float
    cv_rms_um: float

    def as_dict(self, every: int = 8) -> dict:
        pick = slice(None, None, every)
        return {"over": self.over, "what": self.what, "direction": self.direction,
                "at": [round(float(v), 3) for v in self.at[pick]],
                "value_um": [round(float(v), 4) for v in self.value_um[pick]],
                "band_um": [round(float(v), 4) for v in self.band_um[pick]],
                "dof": round(self.dof, 2), "penalty": float(f"{self.penalty:.3g}"),
                "cv_rms_um": round(self.cv_rms_um, 4)}


@dataclass
class Located:
    """What the locator found in one residual: the regions (along the axis, then in time), the curves
    they come from, and the noise the bands are built on (µm per point)."""

    regions: list[Region]
    curves: list[Curve] = field(default_factory=list)
    noise_um: float = 0.0

    @property
    def along(self) -> list[Region]:
        return [r for r in self.regions if r.over == "position"]

    def as_dict(self, curves: bool = False) -> dict:
        out: dict = {"regions": [r.as_dict() for r in self.regions], "noise_um": round(self.noise_um, 4)}
        if curves:
            out["curves"] = [c.as_dict() for c in self.curves]
        return out


class _Smoother:
    """A P-spline over [lo, hi]: `basis` cubic B-splines on equal knots, a second-difference penalty
    (`penalty`; toward a straight line) or a first-difference one (`penalties[1]`; toward a level,
    which lets a step through with less smearing)."""

    def __init__(self, lo: float, hi: float, basis: int):
        self.lo, self.hi = lo, hi if hi > lo else lo + 1.0
        self.k = max(basis, 4)
        h = (self.hi - self.lo) / (self.k - 3)
        self.knots = self.lo + h * np.arange(-3, self.k + 1)
        self.penalties = {}
        for order in (2, 1):
            diff = np.diff(np.eye(self.k), order, axis=0)
            self.penalties[order] = diff.T @ diff
        self.penalty = self.penalties[2]

    def rows(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each point's four nonzero basis values and their columns (n × 4 each)."""
        from scipy.interpolate import BSpline

        u = np.clip(np.asarray(u, dtype=float), self.knots[3], self.knots[-4])
        m = BSpline.design_matrix(u, self.knots, 3).tocsr()
        m.sort_indices()
        nnz = np.diff(m.indptr)
        if np.all(nnz == 4):
            return m.data.reshape(-1, 4), m.indices.reshape(-1, 4)
        dense = np.zeros((len(u), 4))
        cols = np.zeros((len(u), 4), dtype=int)
        for i in range(len(u)):  # a point on a knot has fewer nonzeros: pad with zeros
            s = slice(m.indptr[i], m.indptr[i + 1])
            dense[i, :nnz[i]], cols[i, :nnz[i]] = m.data[s], m.indices[s]
            cols[i, nnz[i]:] = m.indices[s][-1] if nnz[i] else 0
        return dense, cols


def _gram(values: np.ndarray, cols: np.ndarray, weights: np.ndarray, k: int) -> np.ndarray:
    """BᵀWB from the rows' nonzeros (k × k), O(n)."""
    g = np.zeros(k * k)
    for a in range(values.shape[1]):
        for b in range(values.shape[1]):
            g += np.bincount(cols[:, a] * k + cols[:, b], weights * values[:, a] * values[:, b], minlength=k * k)
    return g.reshape(k, k)


def _apply(values: np.ndarray, cols: np.ndarray, coef: np.ndarray) -> np.ndarray:
    return np.sum(values * coef[cols], axis=1)


def _quad(values: np.ndarray, cols: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """bᵢᵀ M bᵢ for every row, from its four nonzeros."""
    block = inverse[cols[:, :, None], cols[:, None, :]]
    return np.einsum("ni,nj,nij->n", values, values, block)


class _Band:
    """Each point's bᵢᵀ M diag(shrink) Mᵀ bᵢ for a point's basis values bᵢ (four nonzeros, on
    neighbouring columns) and any shrink: only the entries of M diag(shrink) Mᵀ within three of its
    diagonal are needed, each a row of `pairs` (Mₐⱼ·Mₐ₊d,ⱼ over j) times the shrink, and each point's
    sixteen products of its values pick theirs: O(k² + n) per shrink, not O(n·k)."""

    def __init__(self, values: np.ndarray, cols: np.ndarray, m: np.ndarray):
        k = m.shape[0]
        width = values.shape[1]
        # entry (a, a + d) of the band at row d·k + a (d = 0 … width − 1; the rows past the end stay zero)
        self.pairs = np.zeros((width * k, m.shape[1]))
        for d in range(width):
            self.pairs[d * k:d * k + k - d] = m[:k - d] * m[d:]
        low = np.minimum(cols[:, :, None], cols[:, None, :])
        self.at = (np.abs(cols[:, :, None] - cols[:, None, :]) * k + low).reshape(len(cols), -1)
        self.products = (values[:, :, None] * values[:, None, :]).reshape(len(values), -1)

    def leverage(self, shrink: np.ndarray) -> np.ndarray:
        """Each point's leverage for each shrink (`shrink`: weights × k): points × weights."""
        band = (self.pairs @ shrink.T)[self.at]  # points × 16 × weights
        return np.einsum("ne,new->nw", self.products, band)


LEVERAGE_BLOCK = 500_000
"""_fit: the most numbers of the points' leverages held at once (points × 16 × weights), so that a curve
over thousands of bins is scored a block of penalty weights at a time, in bounded memory."""


def _fit(values: np.ndarray, cols: np.ndarray, y: np.ndarray, w: np.ndarray, penalty_matrix: np.ndarray,
         k: int, criterion: str, others: tuple[np.ndarray, ...] = ()) -> tuple[np.ndarray, np.ndarray, float, float,
                                                                                float]:
    """The penalised fit whose penalty (its matrix `penalty_matrix` or one of `others`, and its weight)
    minimises leave-one-out CV ("loo") or GCV ("gcv"): coefficients, (BᵀWB + λP)⁻¹, effective
    parameters, the penalty's weight, the CV RMS. Every weight from one eigendecomposition per
    penalty matrix (BᵀWB = RᵀR, R⁻ᵀPR⁻¹ = U diag(s) Uᵀ, so (BᵀWB + λP)⁻¹ = M diag(1/(1 + λs)) Mᵀ with
    M = R⁻¹U): a k × k decomposition, then O(n) per weight."""
    gram = _gram(values, cols, w, k)
    rhs = np.zeros(k)
    for a in range(values.shape[1]):
        rhs += np.bincount(cols[:, a], w * values[:, a] * y, minlength=k)
    jitter = 1e-9 * max(float(np.trace(gram)), 1e-300) / k  # basis functions no point reaches
    root = np.linalg.cholesky(gram + jitter * np.eye(k)).T  # gram = rootᵀ root
    root_inv = np.linalg.inv(root)
    yy = float(np.sum(w * y * y))
    n = len(y)
    best: tuple[float, np.ndarray, np.ndarray, float, float] | None = None
    for matrix in (penalty_matrix, *others):
        s, u = np.linalg.eigh(root_inv.T @ matrix @ root_inv)
        s = np.maximum(s, 0.0)
        m = root_inv @ u
        proj = m.T @ rhs
        band = None
        if criterion == "loo":
            band = _Band(values, cols, m)
        scale = max(float(np.trace(gram)), 1e-300) / max(float(np.trace(matrix)), 1e-300)
        lams = PENALTIES * scale
        shrinks = 1.0 / (1.0 + lams[:, None] * s[None, :])  # weights × k
        coefs = (shrinks * proj) @ m.T  # each weight's coefficients, a row
        dofs = np.sum(shrinks, axis=1)
        if band is not None:
            scores = np.full(len(lams), np.inf)
            step = max(1, LEVERAGE_BLOCK // max(16 * n, 1))
            for i in range(0, len(lams), step):
                block = slice(i, i + step)
                hat = w[:, None] * band.leverage(shrinks[block])
                fitted = np.einsum("nc,ncw->nw", values, coefs[block].T[cols])
                loo = (y[:, None] - fitted) / (1.0 - hat)
                score = np.sum(w[:, None] * loo**2, axis=0) / max(float(np.sum(w)), 1e-300)
                # a point the fit passes through: its fold cannot be predicted
                scores[block] = np.where(np.max(hat, axis=0) > 1.0 - 1e-3, np.inf, score)
        else:
            rss = np.maximum(yy - 2 * coefs @ rhs + np.einsum("wi,ij,wj->w", coefs, gram, coefs), 0.0)
            scores = n * rss / np.maximum(n - dofs, 1e-6) ** 2 / max(float(np.mean(w)), 1e-300)
        scores = np.where(np.isnan(scores), np.inf, scores)
        j = int(np.argmin(scores))
        if np.isfinite(scores[j]) and (best is None or scores[j] < best[0]):
            best = (float(scores[j]), coefs[j], (m * shrinks[j]) @ m.T, float(dofs[j]), float(lams[j]))
    if best is None:  # every weight passes through some point: the stiffest
        lam = PENALTIES[-1] * max(float(np.trace(gram)), 1e-300) / max(float(np.trace(penalty_matrix)), 1e-300)
        inverse = np.linalg.pinv(gram + lam * penalty_matrix, hermitian=True)
        return inverse @ rhs, inverse, float(np.trace(inverse @ gram)), lam, math.inf
    score, coef, inverse, dof, lam = best
    return coef, inverse, dof, lam, math.sqrt(max(score, 0.0))


def _quantile(dof: float) -> float:
    """The band's normal quantile: BAND_ALPHA over the curve's effective parameters, two-sided."""
    from scipy.stats import norm

    return float(norm.isf(BAND_ALPHA / (2 * max(dof, 1.0))))


def pooled_noise_um(data: CampaignData, residual: np.ndarray) -> float:
    """Run-to-run scatter of the residual per point, pooled over (campaign, target, direction), µm;
    of the weighted residual (each point's times data.row_scale: in the coarsest table's unit) when
    the tables fitted together are weighed by their uncertainty."""
    if data.row_scale is not None:
        residual = residual * data.row_scale
    keys = (data.campaign_index * (data.target_index.max() + 1) + data.target_index) * 2 + (data.d > 0)
    _, group = np.unique(keys, return_inverse=True)
    count = np.bincount(group)
    mean = np.bincount(group, residual) / count
    dof = int(np.sum(count - 1))
    if dof <= 0:
        return float(np.std(residual))
    return float(np.sqrt(np.sum((residual - mean[group]) ** 2) / dof))


def _target_means(data: CampaignData, residual: np.ndarray, scale: np.ndarray | None,
                  sign: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One direction's (campaign, target) keys, and per key the mean residual, its position and its count
    (points weighed by `scale`²: data.row_scale of the tables fitted together; None: all alike)."""
    pick = data.d == sign
    keys = data.campaign_index[pick] * (data.target_index.max() + 1) + data.target_index[pick]
    key, group = np.unique(keys, return_inverse=True)
    weight = np.ones(int(pick.sum())) if scale is None else scale[pick] ** 2
    count = np.bincount(group, weight)  # the points in each, each weighed by 1/u² (data.row_scale)
    means = np.bincount(group, weight * residual[pick]) / count
    where = np.bincount(group, weight * data.x[pick]) / count
    return key, means, where, count


def _smoothed(over: str, direction: str, lo: float, hi: float, where: np.ndarray, means: np.ndarray,
              count: np.ndarray, noise_um: float, at: np.ndarray, alike: np.ndarray | None = None) -> list[Curve]:
    """The P-spline through target means (`count`: each one's points, its weight), its penalty chosen by
    leaving targets out, evaluated at `at` with its band; and, given `alike` (other values at the same
    targets), the same smoother applied to them (direction "opposite": its penalty is the first's)."""
    smoother = _Smoother(lo, hi, min(MAX_BASIS, len(np.unique(np.round(where, 6))) + 2))
    values, cols = smoother.rows(where)
    coef, inverse, dof, lam, cv = _fit(values, cols, means, count, smoother.penalty, smoother.k, "loo",
                                       (smoother.penalties[1],))
    grid_values, grid_cols = smoother.rows(at)
    band = _quantile(dof) * noise_um * np.sqrt(np.maximum(_quad(grid_values, grid_cols, inverse), 0.0))
    curves = [Curve(over, "deviation", direction, at, _apply(grid_values, grid_cols, coef), band, dof, lam, cv)]
    if alike is not None:
        rhs = np.zeros(smoother.k)
        for c in range(values.shape[1]):
            rhs += np.bincount(cols[:, c], count * values[:, c] * alike, minlength=smoother.k)
        curves.append(Curve(over, "deviation", "opposite", at, _apply(grid_values, grid_cols, inverse @ rhs), band,
                            dof, lam, math.nan))
    return curves


def position_curves(data: CampaignData, residual: np.ndarray, noise_um: float,
                    scale: np.ndarray | None) -> list[Curve]:
    """One smoother of the residual's target means over position per direction (`scale`: each point's
    weight's square root, data.row_scale of the tables fitted together; None: all alike)."""
    lo, hi = float(np.min(data.x)), float(np.max(data.x))
    at = np.linspace(lo, hi, GRID)
    curves = []
    for sign, name in DIRECTIONS.items():
        if not np.any(data.d == sign):
            continue
        _, means, where, count = _target_means(data, residual, scale, sign)
        if len(means) >= 4:
            curves += _smoothed("position", name, lo, hi, where, means, count, noise_um, at)
    return curves


def paired_curves(data: CampaignData, residual: np.ndarray, noise_um: float,
                  scale: np.ndarray | None) -> tuple[Curve, Curve] | None:
    """The mean of the two directions' target means smoothed as a curve of its own (direction "both"),
    its penalty chosen on it, and half their difference (+ minus −; "opposite") by the same smoother, when
    every target is measured in both directions (a table of stopped targets); None otherwise. An error
    both directions share is held by twice the points there: smoothing each direction apart let each
    one's cross-validation, on half the points, choose a straight line through a dip that two targets
    of eleven show (−0.8 µm at a noise of 0.73 µm: 4σ in the mean of both directions, 2.6σ in one)."""
    lo, hi = float(np.min(data.x)), float(np.max(data.x))
    sides = [_target_means(data, residual, scale, sign) for sign in DIRECTIONS if np.any(data.d == sign)]
    if len(sides) < 2 or len(sides[0][0]) < 4 or not np.array_equal(sides[0][0], sides[1][0]):
        return None
    (_, plus, where_plus, n_plus), (_, minus, where_minus, n_minus) = sides
    if not np.allclose(where_plus, where_minus, rtol=0.0, atol=1e-6 * max(hi - lo, 1.0)):
        return None
    count = 4.0 / (1.0 / n_plus + 1.0 / n_minus)  # half the sum or the difference of two means: its points
    mean, half = _smoothed("position", "both", lo, hi, (where_plus + where_minus) / 2, (plus + minus) / 2, count,
                           noise_um, np.linspace(lo, hi, GRID), (plus - minus) / 2)
    return mean, half


def time_curves(data: CampaignData, residual: np.ndarray, noise_um: float) -> list[Curve]:
    """What the targets' means leave (the change from run to run), smoothed over time as a level and a
    slope along the travel (µm from one end to the other), each a P-spline in time; one campaign."""
    if data.campaigns > 1 or len(np.unique(data.run)) < 2:
        return []
    t = np.nanmean(data.t, axis=1)
    keys = data.target_index * 2 + (data.d > 0)
    _, group = np.unique(keys, return_inverse=True)
    count = np.bincount(group)
    left = residual - (np.bincount(group, residual) / count)[group]
    travel = float(np.ptp(data.x)) or 1.0
    u = (data.x - float(np.mean(data.x))) / travel  # the slope's column: its coefficient is µm over the travel
    lo, hi = float(np.min(t)), float(np.max(t))
    runs = len(np.unique(data.run))
    smoother = _Smoother(lo, hi, min(MAX_BASIS, 4 * runs + 3))
    values, cols = smoother.rows(t)
    k = smoother.k
    both_values = np.hstack([values, values * u[:, None]])
    both_cols = np.hstack([cols, cols + k])
    penalty = np.zeros((2 * k, 2 * k))
    penalty[:k, :k] = penalty[k:, k:] = smoother.penalty
    # the group means took one level per target and direction: the level's mean in time is not free
    coef, inverse, dof, lam, cv = _fit(both_values, both_cols, left, np.ones(len(left)), penalty, 2 * k, "gcv")
    at = np.linspace(lo, hi, GRID)
    grid_values, grid_cols = smoother.rows(at)
    zero = np.zeros_like(grid_values)
    out = []
    for what, vals, offset in (("level", grid_values, 0), ("slope", grid_values, k)):
        full_values = np.hstack([vals, zero]) if offset == 0 else np.hstack([zero, vals])
        full_cols = np.hstack([grid_cols, grid_cols + k])
        se = noise_um * np.sqrt(np.maximum(_quad(full_values, full_cols, inverse), 0.0))
        out.append(Curve("time", what, "both", at, _apply(full_values, full_cols, coef),
                         _quantile(dof / 2) * se, dof / 2, lam, cv))
    return out


EXTENT = 0.25
"""A region reaches on from where the curve leaves its band to where it falls below this share of its
peak (or changes sign): a bump's region is about one width at half height either side."""


SMALLEST = 0.5
"""The smallest departure reported, in the noise of one point: on a dense table the band is so narrow
that a smoother's own ringing beside a sharp feature would pass it."""


def _lobes(curve: Curve, smallest_um: float = 0.0) -> list[tuple[int, int]]:
    """Index ranges [i, j) of `curve.at` of each departure: where the curve is beyond its band, reaching
    on while it keeps its sign and EXTENT of its peak; departures of one sign that meet are one."""
    value = curve.value_um
    out_of_band = np.abs(value) > np.maximum(curve.band_um, smallest_um)
    edges = np.flatnonzero(np.diff(np.r_[0, out_of_band.astype(int), 0]))
    spans: list[tuple[int, int]] = []
    for i, j in zip(edges[::2], edges[1::2]):
        k = i + int(np.argmax(np.abs(value[i:j])))
        keep = (np.sign(value) == np.sign(value[k])) & (np.abs(value) >= EXTENT * abs(value[k]))
        while i > 0 and keep[i - 1]:
            i -= 1
        while j < len(value) and keep[j]:
            j += 1
        if spans and i <= spans[-1][1] and np.sign(value[spans[-1][0]]) == np.sign(value[k]):
            spans[-1] = (spans[-1][0], max(j, spans[-1][1]))
        else:
            spans.append((int(i), int(j)))
    return spans


ROUNDING_OUTSIDE = 1e-18
"""shape_of: the squared norm outside the straight line's span below which a template's column (values of
order one) is rounding, not a shape."""


def shape_of(at: np.ndarray, value: np.ndarray, start: float, end: float, travel: float) -> str:
    """The shape in words of the smoothed residual over a region and half its width either side: the
    template (each beside a straight line) that leaves the least of it: a step (a jump), a bump, a slope
    change (a kink), a wave (a sinusoid of a few periods); "level" when a straight line alone holds it
    over most of the travel."""
    half = max((end - start) / 2, 2 * float(np.median(np.diff(at))))
    pick = (at >= start - half) & (at <= end + half)
    if pick.sum() < 6:
        pick = np.ones(len(at), bool)
    x, v = at[pick], value[pick]
    span = float(np.ptp(x)) or 1.0
    s = (x - x.mean()) / span
    q = np.linalg.qr(np.column_stack([np.ones_like(s), s]))[0]  # the straight line's span, orthonormal
    rest = v - q @ (q.T @ v)
    line = float(rest @ rest)
    total = float(np.sum((v - v.mean()) ** 2)) or 1e-300
    if span >= 0.8 * travel and line <= 0.1 * float(np.sum(v**2)):
        return "level"

    def left(*columns: np.ndarray) -> np.ndarray:
        """What is left of v beside the line and each template's columns (n × m each: m templates of
        len(columns) columns): the line's residual less its part in the template's columns outside the
        line's span (the templates' values are of order one: a column whose part outside is below
        ROUNDING_OUTSIDE in squared norm, a sine sampled at its nodes, adds nothing; two columns that
        are one there count once, by the pseudo-inverse)."""
        outside = [c - q @ (q.T @ c) for c in columns]
        gram = np.stack([np.stack([(a * b).sum(0) for b in outside], -1) for a in outside], -2)  # m × k × k
        along = np.stack([rest @ a for a in outside], -1)  # m × k
        keep = np.stack([gram[:, i, i] for i in range(len(columns))], -1) > ROUNDING_OUTSIDE
        gram = np.where(keep[:, :, None] & keep[:, None, :], gram, 0.0)
        along = np.where(keep, along, 0.0)
        return line - np.einsum("mk,mk->m", along, (np.linalg.pinv(gram) @ along[..., None])[..., 0])

    centres = x[1:-1:max(1, len(x) // 40)]
    widths = np.geomspace(span / 40, span / 2, 8)
    scores = {
        "step": float(left((x[:, None] > centres).astype(float)).min()),
        "slope change": float(left(np.maximum(x[:, None] - centres, 0.0)).min()),
        "bump": float(left(np.exp(-0.5 * ((x[:, None, None] - centres[:, None]) / widths) ** 2)
                           .reshape(len(x), -1)).min()),
    }
    periods = np.geomspace(span / 8, span / 1.5, 24)
    wave = float(left(np.sin(2 * np.pi * x[:, None] / periods), np.cos(2 * np.pi * x[:, None] / periods)).min())
    best = min(scores, key=lambda key: scores[key])
    # a wave has one parameter more: it must leave clearly less than the best single shape
    return "wave" if wave < 0.5 * scores[best] and wave < 0.2 * total else best


def _combined(curves: list[Curve]) -> list[Curve]:
    """The two directions' curves as their mean (direction "both") and half their difference
    (direction "opposite": a reversal, + minus −), each with its band; one direction's curve alone
    when the table has one."""
    if len(curves) < 2:
        return curves
    plus, minus = curves
    band = np.sqrt(plus.band_um**2 + minus.band_um**2) / 2
    dof, cv = plus.dof + minus.dof, math.hypot(plus.cv_rms_um, minus.cv_rms_um) / 2
    return [Curve("position", "deviation", "both", plus.at, (plus.value_um + minus.value_um) / 2, band, dof,
                  plus.penalty, cv),
            Curve("position", "deviation", "opposite", plus.at, (plus.value_um - minus.value_um) / 2, band, dof,
                  plus.penalty, cv)]


ONE_SIDE = 0.5
"""A departure of the mean and one of the half difference at the same place (SHARED), of sizes
within this share of each other, are one departure seen in one direction only."""
SHARED = 0.7
"""...at the same place: sharing at least this share of their joint extent."""


def _regions_of(curves: list[Curve], travel: float, unit: str, dev: str, smallest_um: float,
                paired: tuple[Curve, Curve] | None = None) -> list[Region]:
    """Regions along the axis from the two directions' curves: departures of their mean (both
    directions), of half their difference (opposite in the two directions: a reversal), and where one
    of each meets with about the same size, of one direction only; and the departures of the `paired`
    mean (the directions' target means averaged, then smoothed: paired_curves) where the directions'
    curves show none in both directions (a reversal's departure there, opposite in the two, does not say
    it): an error both directions share, which each direction's curve, on half the points, passes by (in
    one direction when the paired half difference says so: _one_side_of)."""
    mean, half = paired if paired is not None else (None, None)
    lobes = []
    for curve in _combined(curves):
        for i, j in _lobes(curve, smallest_um):
            k = i + int(np.argmax(np.abs(curve.value_um[i:j])))
            lobes.append((curve, i, j, float(curve.value_um[k]), float(curve.at[k])))
    if mean is not None:
        for i, j in _lobes(mean, smallest_um):
            if all(j <= i2 or j2 <= i for other, i2, j2, _, _ in lobes if other.direction != "opposite"):
                k = i + int(np.argmax(np.abs(mean.value_um[i:j])))
                lobes.append((mean, i, j, float(mean.value_um[k]), float(mean.at[k])))
    used = [False] * len(lobes)
    out: list[tuple[Region, np.ndarray]] = []
    for a, (curve, i, j, peak, peak_at) in enumerate(lobes):
        if used[a]:
            continue
        used[a] = True
        direction, value = curve.direction, curve.value_um
        if curve.direction in ("both", "opposite"):
            for b, (other, i2, j2, peak2, _) in enumerate(lobes):
                shared = min(j, j2) - max(i, i2)
                if (used[b] or other.direction == curve.direction or shared < SHARED * (max(j, j2) - min(i, i2))
                        or abs(abs(peak2) - abs(peak)) > ONE_SIDE * max(abs(peak), abs(peak2))):
                    continue
                used[b] = True
                mean_peak = peak if curve.direction == "both" else peak2
                diff_peak = peak2 if curve.direction == "both" else peak
                direction = "+" if mean_peak * diff_peak > 0 else "-"
                value = curve.value_um + other.value_um * (1 if direction == "+" or curve.direction == "opposite"
                                                           else -1)
                if direction == "-" and curve.direction == "opposite":
                    value = other.value_um - curve.value_um
                i, j = min(i, i2), max(j, j2)
                k = i + int(np.argmax(np.abs(value[i:j])))
                peak, peak_at = float(value[k]), float(curve.at[k])
                break
        if curve is mean and half is not None:
            direction, value, peak = _one_side_of(mean, half, i, j, peak)
        start, end = float(curve.at[i]), float(curve.at[j - 1])
        shape = shape_of(curve.at, value, start, end, travel)
        out.append((Region("position", "deviation", start, end, peak, peak_at, direction, shape, unit, dev), value))
    out.sort(key=lambda r: r[0].start)
    return _steps_joined(out, curves[0].at, travel)


def _one_side_of(mean: Curve, opposite: Curve, i: int, j: int, peak: float) -> tuple[str, np.ndarray, float]:
    """The direction(s) a departure of the directions' mean over [i, j) is in, the curve that holds it and
    its peak: one direction when half the directions' difference, smoothed alike (`opposite`, less its
    median over the travel: a reversal's level), is there about as large (ONE_SIDE) as the mean and beyond
    half its band (the same as the mean's); else both."""
    level = float(np.median(opposite.value_um))
    k = i + int(np.argmax(np.abs(mean.value_um[i:j])))
    half = float(opposite.value_um[k]) - level
    if (abs(abs(half) - abs(peak)) > ONE_SIDE * max(abs(half), abs(peak))
            or abs(half) <= 0.5 * float(opposite.band_um[k])):
        return "both", mean.value_um, peak
    direction = "+" if peak * half > 0 else "-"
    value = mean.value_um + (opposite.value_um - level) * (1.0 if direction == "+" else -1.0)
    return direction, value, float(value[i + int(np.argmax(np.abs(value[i:j])))])


STEEP = 2.0
"""Two departures of opposite sign are one step when the curve changes between their peaks at least
this many times faster than on their outer sides (a wave changes as fast on both)."""


def _steps_joined(regions: list[tuple[Region, np.ndarray]], at: np.ndarray, travel: float) -> list[Region]:
    """Two neighbouring departures of opposite sign in the same direction that meet in a steep change are
    one step (a jump beside a straight line leaves a saw tooth: one side below the line, the other
    above): from one peak to the other, its size the jump, placed where the curve changes most."""
    out: list[Region] = []
    i = 0
    while i < len(regions):
        a, value = regions[i]
        b = next((r for r, _ in regions[i + 1:] if r.direction == a.direction), None)
        if b is not None and a.peak_um * b.peak_um < 0 and b.start - a.end < 0.5 * (b.peak_at - a.peak_at):
            lo, hi = sorted((a.peak_at, b.peak_at))
            pick = (at >= lo) & (at <= hi)
            outer = ((at >= a.start) & (at < lo)) | ((at > hi) & (at <= b.end))
            slope = np.abs(np.diff(value)) / np.diff(at)
            inner = slope[pick[1:] & pick[:-1]]
            flanks = slope[outer[1:] & outer[:-1]]
            if len(inner) and float(np.max(inner)) >= STEEP * float(np.max(flanks, initial=0.0)):
                slope = np.abs(np.diff(value[pick]))
                k = int(np.argmax(slope))
                where = float((at[pick][k] + at[pick][k + 1]) / 2)
                step = Region("position", "deviation", lo, hi, b.peak_um - a.peak_um, where, a.direction, "step",
                              a.unit, a.deviation_unit)
                out.append(step)
                regions = [r for r in regions if r[0] is not b]
                i += 1
                continue
        out.append(a)
        i += 1
    return out


WIDE = 0.5
"""A region wider than this share of the travel (a reversal over the travel, a bow) is the vocabulary's:
a target inside it that departs from its direction's curve is still said as one target's departure."""


SAID_SHARE = 0.5
"""One target's departure inside a region already found is said by it when the region shows the
direction(s) it departs in, with its sign there (a departure in both directions: a region of both) and its
peak is at least this share of the departure (the smoother followed part of a narrow error); a smaller region there
(a reversal of a few tenths), one in the other direction alone, or one where the directions part (opposite)
beside a departure both share, does not say it."""


def odd_targets(data: CampaignData, residual: np.ndarray, noise_um: float, curves: list[Curve],
                regions: list[Region], scale: np.ndarray | None) -> list[Region]:
    """Targets whose mean residual departs from the smoothed curve of its direction beyond their own
    noise (noise / √points, the normal quantile of BAND_ALPHA over every target and direction), unless a
    region already found says it (SAID_SHARE; not one over most of the travel, WIDE): an error narrower than the
    spacing of the targets, which one target shows and its neighbours do not (the smoother,
    cross-validated by leaving targets out, cannot follow it). Each is a bump from the target before to the one after (where between them it begins
    and ends the data do not say), in the direction(s) that show it."""
    from scipy.stats import norm

    targets = np.unique(np.round(data.x, 6))
    if len(targets) < 4 or noise_um <= 0:
        return []
    travel = float(np.ptp(targets)) or 1.0
    by_direction = {c.direction: c for c in curves if c.over == "position"}
    departures: dict[int, dict[str, tuple[float, float]]] = {}
    tests = 0
    for sign, name in DIRECTIONS.items():
        curve = by_direction.get(name)
        if curve is None:
            continue
        pick = data.d == sign
        where = np.searchsorted(targets, np.round(data.x[pick], 6))
        weight = np.ones(int(pick.sum())) if scale is None else scale[pick] ** 2
        count = np.bincount(where, weight, minlength=len(targets))  # points weighed by 1/u² (row_scale), as the curves
        seen = count > 0
        means = np.bincount(where, weight * residual[pick], minlength=len(targets))[seen] / count[seen]
        left = means - np.interp(targets[seen], curve.at, curve.value_um)
        z = left / (noise_um / np.sqrt(count[seen]))  # noise_um: a point's of unit weight
        tests += int(seen.sum())
        for at, zk, dk in zip(np.flatnonzero(seen), z, left):
            departures.setdefault(int(at), {})[name] = (float(zk), float(dk))
    limit = float(norm.isf(BAND_ALPHA / (2 * max(tests, 1))))
    out = []
    for k, sides in sorted(departures.items()):  # k: the target's index
        odd = {name: v for name, v in sides.items() if abs(v[0]) > limit}
        if not odd:
            continue
        x = float(targets[k])
        signs = {math.copysign(1.0, v[1]) for v in sides.values()}
        both = len(odd) == 2 or (len(sides) == 2 and len(signs) == 1
                                 and all(abs(v[0]) > limit / 2 for v in sides.values()))
        direction = "both" if both else next(iter(odd))
        peak = float(np.mean([v[1] for v in (sides if both else odd).values()]))
        if any(r.start <= x <= r.end and abs(r.peak_um) >= SAID_SHARE * abs(peak) and (
                r.direction == direction and r.peak_um * peak > 0
                or direction != "both" and r.direction == "both" and r.peak_um * peak > 0
                # an opposite region's value is the + direction's (half of + less −)
                or direction != "both" and r.direction == "opposite"
                and r.peak_um * peak * (1.0 if direction == "+" else -1.0) > 0)
               for r in regions if r.end - r.start <= WIDE * travel):
            continue  # said by that region (one over most of the travel, a reversal or a bow, does not say it)
        start = float(targets[k - 1 if k > 0 else 0])
        end = float(targets[k + 1 if k + 1 < len(targets) else k])
        out.append(Region("position", "deviation", start, end, peak, x, direction, "bump", data.position_unit,
                          data.deviation_unit, one_target=True))
    return out


ROW = 10
"""More one-target departures than this, spread over more than WIDE of the travel, are a row (row_of_singles)."""


def row_of_singles(located: Located) -> tuple[list[Region], list[Region]]:
    """The one-target departures along the axis when they are a row over the travel (more than ROW of
    them spread over more than WIDE of the span of the curves), and the other regions; no row: ([], all).
    Such a row is structure finer than the smoother follows, seen target by target: on a dense table,
    a wave of a few millimetres that MAX_BASIS basis functions over a metre cannot hold (a 10 mm lead
    over 1,000 mm at 25,000 positions departs at 2,800 to 3,800 of them before anything is named). Said as
    one row; each one stays a region of its own (the routes and --json see them all)."""
    singles = [r for r in located.regions if r.over == "position" and r.one_target]
    spans = [float(np.ptp(c.at)) for c in located.curves if c.over == "position"]
    if len(singles) <= ROW or not spans:
        return [], located.regions
    if max(r.end for r in singles) - min(r.start for r in singles) <= WIDE * max(spans):
        return [], located.regions
    return singles, [r for r in located.regions if not (r.over == "position" and r.one_target)]


def beside_period(regions: list[Region], travel: float) -> list[Region]:
    """The regions left beside an unresolved period. One target's departures are that period seen at few
    targets (said by its unresolved group) when they spread over more than WIDE of the travel; in part
    of it they are structure there, finer than the target spacing (a screw lead repeats on every turn):
    neighbouring ones (their regions overlap) said as one region from the first's neighbour to the
    last's, a wave when they change sign, a bump when not. When all of them spread wider, the
    neighbouring ones are still said when they are all within WIDE (one target alone is left out)."""
    singles = sorted((r for r in regions if r.one_target), key=lambda r: r.start)
    rest = [r for r in regions if not r.one_target]
    groups: list[list[Region]] = []
    for r in singles:
        if groups and r.start < groups[-1][-1].end:
            groups[-1].append(r)
        else:
            groups.append([r])
    if singles and max(r.end for r in singles) - singles[0].start > WIDE * travel:
        groups = [g for g in groups if len(g) > 1]
        if groups and groups[-1][-1].end - groups[0][0].start > WIDE * travel:
            groups = []
    for group in groups:
        if len(group) == 1:
            rest.append(group[0])
            continue
        peak = max(group, key=lambda r: abs(r.peak_um))
        sides = {r.direction for r in group}
        shape = "wave" if len({r.peak_um > 0 for r in group}) > 1 else "bump"
        rest.append(Region("position", "deviation", group[0].start, max(r.end for r in group), peak.peak_um,
                           peak.peak_at, sides.pop() if len(sides) == 1 else "both", shape, peak.unit,
                           peak.deviation_unit))
    return sorted(rest, key=lambda r: r.start)


def kinds_of_rows(data: CampaignData) -> list[np.ndarray | None]:
    """The rows each curve over position smooths: all of them ([None]), or, when a scan's profile is
    fitted with tables of stopped targets, the stopped targets' rows and each profile's rows apart
    (its rows: `data.sloped`, per table). One penalty cannot serve both: chosen where the profile's
    bins, 0.1 mm apart, are dense and weigh most, it left the curve as flexible in the 39 mm gap
    between the scan's end and the table's next target as over the bins, and the curve carried a
    10 mm lead's slope on and dived to −3.9 ± 0.7 µm where nothing was measured (a bump of −3.3 µm
    said before naming on an axis that has none; a user's trial saw −6.7 µm). Each curve is over
    its own rows' span, with the weights and the noise of the tables fitted together."""
    if data.sloped is None or not np.any(data.sloped):
        return [None]
    stopped = ~data.sloped
    kinds: list[np.ndarray | None] = [stopped] if np.count_nonzero(stopped) else []
    for table in np.unique(data.campaign_index[data.sloped]):
        kinds.append(data.sloped & (data.campaign_index == table))
    return kinds


def locate(data: CampaignData, residual: np.ndarray) -> Located:
    """The regions where `residual` (µm per point: measured - model) departs from zero beyond the
    noise, along the axis per direction and in time, and the curves they come from."""
    residual = np.asarray(residual, dtype=float)
    noise = pooled_noise_um(data, residual)
    if len(data) < 8 or noise <= 0:
        return Located([], [], noise)
    travel = float(np.ptp(data.x)) or 1.0
    scale = data.row_scale
    curves, regions = [], []
    for rows in kinds_of_rows(data):
        part = data if rows is None else keep_rows(data, rows)
        left, weights = (residual, scale) if rows is None else (residual[rows], None if scale is None else scale[rows])
        along = position_curves(part, left, noise, weights)
        if not along:  # fewer than four targets in each direction: no curve to read
            continue
        paired = paired_curves(part, left, noise, weights)
        found = _regions_of(along, travel, data.position_unit, data.deviation_unit, SMALLEST * noise, paired)
        regions += found + odd_targets(part, left, noise, along, found, weights)
        curves += along + ([paired[0]] if paired is not None else [])  # its half difference only tells a direction
    regions.sort(key=lambda r: r.start)
    timed = time_curves(data, residual, noise)
    time_unit = "s" if data.time_source == "time_s" else "points"
    for curve in timed:
        for i, j in _lobes(curve, SMALLEST * noise):
            k = i + int(np.argmax(np.abs(curve.value_um[i:j])))
            start, end = float(curve.at[i]), float(curve.at[j - 1])
            shape = shape_of(curve.at, curve.value_um, start, end, float(np.ptp(curve.at)) or 1.0)
            if shape == "slope change" and (i == 0 or j == len(curve.at)):
                shape = "drift"
            regions.append(Region("time", curve.what, start, end, float(curve.value_um[k]), float(curve.at[k]),
                                  "both", shape, time_unit, data.deviation_unit))
    return Located(regions, curves + timed, noise)


def short(region: Region) -> str:
    """A region in a few words: 'bump +2.1 µm at 66–141 mm', '(+ only)' when one direction shows it."""
    sides = {"both": "", "+": " (+ only)", "-": " (− only)", "opposite": " (opposite directions)"}[region.direction]
    what = "" if region.over == "position" else f"{region.what} "
    return (f"{what}{region.shape} {region.peak_um:+.1f} {region.deviation_unit} at {region.start:.4g}–"
            f"{region.end:.4g} {region.unit}{sides}")

"""Least-squares fitting of a model of effect terms to a campaign, and the tests discovery uses.

The deviation is offset (one per campaign fitted together) + Σ (free terms' columns · coefficients) + Σ (fixed terms' deviations).
Shape parameters (periods, time constants) are found by variable projection: for given shapes the
coefficients are a linear least-squares solution; the shapes are refined with
scipy.optimize.least_squares (in log space, within bounds) from a grid or periodogram start.

Units: deviations and RMS values µm; everything else as in campaign.discovery.effects.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from campaign.discovery.data import CampaignData
from campaign.discovery.effects import form_of, period_limits
from campaign.effects import RegistryView
from campaign.model import effect_um

COLLINEAR = 1e-3
"""A column whose part outside the model's span is below this fraction of its norm adds nothing."""


@dataclass
class Term:
    """One effect in the model. held: parameters given by the user and kept. fixed: every
    parameter given, so the effect's deviation is fixed. shape: current shape parameters.
    keep: which of the form's columns are fitted (a column collinear with the model is dropped and
    its coefficient is 0)."""

    name: str
    held: dict[str, float] = field(default_factory=dict)
    fixed: bool = False
    shape: dict[str, float] = field(default_factory=dict)
    keep: tuple[bool, ...] | None = None

    @property
    def searched(self) -> list[str]:
        return [] if self.fixed else [k for k in form_of(self.name).shape if k not in self.held]

    def columns(self, data: CampaignData) -> np.ndarray:
        cols = form_of(self.name).columns(data, self.shape, self.held)
        return cols if self.keep is None else cols[:, list(self.keep)]


@dataclass
class Fit:
    """Fitted terms: coefficients per free term (in the form's full column order), offset µm (the
    first campaign's), prediction µm per point, residual sum of squares µm², number of fitted
    parameters, and the offset of every campaign fitted together, µm."""

    terms: list[Term]
    coefs: list[np.ndarray]
    offset_um: float
    prediction: np.ndarray
    rss: float
    n_params: int
    offsets_um: tuple[float, ...] = ()

    def params(self) -> dict[str, dict[str, float]]:
        """Effect name -> model parameters (physical units, see model.EFFECT_PARAMS)."""
        out = {}
        for term, coefs in zip(self.terms, self.coefs):
            out[term.name] = dict(term.held) if term.fixed else form_of(term.name).params(coefs, term.shape, term.held)
        return out

    def rms_um(self, y: np.ndarray) -> float:
        return float(np.sqrt(np.mean((y - self.prediction) ** 2)))


def fixed_deviation(data: CampaignData, terms: list[Term]) -> np.ndarray:
    """The capture-averaged deviation of the fixed terms, µm."""
    total = np.zeros(len(data))
    w = data.w if data.w is not None else np.full(data.t.shape, np.inf)
    for term in terms:
        if term.fixed:
            values = effect_um(term.name, term.held, data.x[:, None], data.d[:, None], data.t, w)
            total += np.nanmean(np.where(np.isnan(data.t), np.nan, values), axis=1)
    return total


def design(data: CampaignData, terms: list[Term]) -> tuple[np.ndarray, list[slice]]:
    """The regressors: one offset column per campaign (ones at its points: each campaign has its
    own laser datum), then each free term's kept columns."""
    offsets = (data.campaign_index[:, None] == np.arange(data.campaigns)[None, :]).astype(float)
    blocks, slices, start = [offsets], [], data.campaigns
    for term in terms:
        cols = np.zeros((len(data), 0)) if term.fixed else term.columns(data)
        blocks.append(cols)
        slices.append(slice(start, start + cols.shape[1]))
        start += cols.shape[1]
    return np.hstack(blocks), slices


def _solve(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(a, y, rcond=None)[0]


def linear_fit(data: CampaignData, terms: list[Term]) -> Fit:
    """Fit the coefficients for the terms' current shapes."""
    base = fixed_deviation(data, terms)
    a, slices = design(data, terms)
    beta = _solve(a, data.y - base)
    prediction = base + a @ beta
    coefs = []
    for term, sl in zip(terms, slices):
        full = np.zeros(form_of(term.name).columns(data, term.shape, term.held).shape[1]) if not term.fixed \
            else np.zeros(0)
        if not term.fixed:
            keep = term.keep if term.keep is not None else (True,) * len(full)
            full[list(np.flatnonzero(keep))] = beta[sl]
        coefs.append(full)
    n_params = a.shape[1] + sum(len(t.searched) for t in terms)
    return Fit(terms, coefs, float(beta[0]), prediction, float(np.sum((data.y - prediction) ** 2)), n_params,
               tuple(float(b) for b in beta[:data.campaigns]))


def shape_bounds(data: CampaignData, name: str, key: str) -> tuple[float, float]:
    """The bounds of a searched shape parameter: the period's range, or a third of the lowest and
    three times the highest value of its grid (a time constant's; a grid runs upwards)."""
    if key == "period_mm":
        return period_limits(data)
    grid = form_of(name).grid(data, {})
    return grid[0][key] / 3, grid[-1][key] * 3


def refine(data: CampaignData, terms: list[Term]) -> Fit:
    """Refine every searched shape parameter from its current value (least_squares on logs)."""
    slots = [(i, key) for i, term in enumerate(terms) for key in term.searched]
    if not slots:
        return linear_fit(data, terms)
    lower = np.log([shape_bounds(data, terms[i].name, k)[0] for i, k in slots])
    upper = np.log([shape_bounds(data, terms[i].name, k)[1] for i, k in slots])
    start = np.clip(np.log([terms[i].shape[k] for i, k in slots]), lower + 1e-9, upper - 1e-9)

    def with_shapes(logs: np.ndarray) -> list[Term]:
        new = [replace(t, shape=dict(t.shape)) for t in terms]
        for (i, key), value in zip(slots, logs):
            new[i].shape[key] = float(math.exp(value))
        return new

    def residual(logs: np.ndarray) -> np.ndarray:
        f = linear_fit(data, with_shapes(logs))
        return data.y - f.prediction

    from scipy import optimize

    result = optimize.least_squares(residual, start, bounds=(lower, upper), x_scale=0.1, diff_step=1e-4)
    best = linear_fit(data, with_shapes(result.x))
    first = linear_fit(data, terms)
    return best if best.rss <= first.rss else first


def drop_collinear(data: CampaignData, terms: list[Term], term: Term) -> Term:
    """`term` with its columns that the model's columns already span dropped (keep mask)."""
    base, _ = design(data, terms)
    q, _ = np.linalg.qr(base)
    cols = form_of(term.name).columns(data, term.shape, term.held)
    outside = cols - q @ (q.T @ cols)
    norms = np.linalg.norm(cols, axis=0)
    keep = tuple(bool(n > 0 and np.linalg.norm(o) > COLLINEAR * n) for o, n in zip(outside.T, norms))
    return replace(term, keep=keep)


def confounders(data: CampaignData, terms: list[Term], term: Term) -> list[str]:
    """The model's effects whose columns (with the offset) span `term`'s columns on this data."""
    cols = form_of(term.name).columns(data, term.shape, term.held)
    names = []
    for other in terms:
        if other.name == term.name:
            continue
        q, _ = np.linalg.qr(design(data, [replace(other, fixed=False, keep=None)])[0])
        outside = cols - q @ (q.T @ cols)
        if np.linalg.norm(outside) <= COLLINEAR * max(float(np.linalg.norm(cols)), 1e-300):
            names.append(other.name)
    return names


PERIODOGRAM_CELLS = 4_000_000
"""Rows × frequencies evaluated at a time by the periodogram (about 32 MB per array)."""


def periodogram_periods(data: CampaignData, fit: Fit, top: int = 3) -> list[float]:
    """Periods (mm) where a sine of the residual, fitted beside the model, explains most: a
    Lomb-Scargle-like periodogram over the plausible screw leads with the model projected out."""
    low, high = period_limits(data)
    travel = float(np.ptp(data.x)) or 1.0
    freqs = np.arange(1 / high, 1 / low, 1 / (8 * travel))
    a, _ = design(data, fit.terms)
    q, _ = np.linalg.qr(a)
    r = data.y - fit.prediction
    power = np.zeros(len(freqs))
    block = max(1, PERIODOGRAM_CELLS // max(len(data), 1))  # frequencies at a time: memory linear in the rows
    for lo in range(0, len(freqs), block):
        f = freqs[lo:lo + block]
        angle = 2 * np.pi * np.outer(data.x, f)
        s, c = np.sin(angle), np.cos(angle)
        s -= q @ (q.T @ s)
        c -= q @ (q.T @ c)
        ss, cc, sc = (s * s).sum(0), (c * c).sum(0), (s * c).sum(0)
        rs, rc = r @ s, r @ c
        det = ss * cc - sc * sc
        ok = det > 1e-9 * np.maximum(ss * cc, 1e-300)
        power[lo:lo + block][ok] = (cc * rs**2 - 2 * sc * rs * rc + ss * rc**2)[ok] / det[ok]
    peaks = [i for i in range(len(power)) if power[i] > 0 and (i == 0 or power[i] >= power[i - 1])
             and (i == len(power) - 1 or power[i] >= power[i + 1])]
    peaks.sort(key=lambda i: -power[i])
    return [float(1 / freqs[i]) for i in peaks[:top]]


def independent_periods(data: CampaignData) -> float:
    """About how many independent periods the periodogram tries (for the look-elsewhere effect)."""
    low, high = period_limits(data)
    return max(1.0, float(np.ptp(data.x)) * (1 / low - 1 / high))


CV_RCOND = COLLINEAR
"""In a cross-validation fold, directions of the (column-normalised) design whose singular value is
below this fraction of the largest are left out: a fold can lose what tells two columns apart
(leaving out the one run in which a short thermal time constant acts makes its columns those of
linear_scale and the offset), and the prediction must then be what the fold can say, not a
difference of two huge coefficients."""


def _fold_solve(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(a, axis=0)
    norms[norms == 0] = 1.0
    return np.linalg.lstsq(a / norms, y, rcond=CV_RCOND)[0] / norms


CV_FOLDS_REFITTED = 200
"""Up to this many groups each fold is refitted; beyond (a dense table), the left-out residuals come
from the whole fit's hat matrix, group by group (e_g = (I - H_gg)⁻¹ r_g), in time linear in the rows."""


def cv_rms_um(data: CampaignData, terms: list[Term], groups: np.ndarray) -> float:
    """Cross-validated RMS, µm: each group (a target or a run) predicted from the others, shapes
    held at their fitted values (a direction the fold cannot determine is left out: CV_RCOND)."""
    base = fixed_deviation(data, terms)
    a, _ = design(data, terms)
    y = data.y - base
    errors = np.zeros(len(y))
    names, index = np.unique(groups, return_inverse=True)
    if len(names) > CV_FOLDS_REFITTED:
        return _cv_from_hat(a, y, index)
    for g in range(len(names)):
        out = index == g
        beta = _fold_solve(a[~out], y[~out])
        errors[out] = y[out] - a[out] @ beta
    return float(np.sqrt(np.mean(errors**2)))


def _cv_from_hat(a: np.ndarray, y: np.ndarray, index: np.ndarray) -> float:
    """The grouped leave-out RMS from the hat matrix of the whole fit (column-normalised, directions
    below CV_RCOND left out): e_g = (I - H_gg)⁻¹ r_g, a small solve per group."""
    norms = np.linalg.norm(a, axis=0)
    norms[norms == 0] = 1.0
    u, sv, _ = np.linalg.svd(a / norms, full_matrices=False)
    q = u[:, sv > CV_RCOND * sv[0]] if len(sv) else u[:, :0]
    r = y - q @ (q.T @ y)
    order = np.argsort(index, kind="stable")
    bounds = np.flatnonzero(np.diff(index[order])) + 1
    total = 0.0
    for rows in np.split(order, bounds):
        qg = q[rows]
        block = np.eye(len(rows)) - qg @ qg.T
        e = np.linalg.lstsq(block, r[rows], rcond=CV_RCOND)[0]
        total += float(e @ e)
    return float(np.sqrt(total / len(y)))


def bic(fit: Fit, n: int) -> float:
    """Bayesian information criterion of a fit with Gaussian residuals (dimensionless)."""
    return n * math.log(max(fit.rss, 1e-300) / n) + fit.n_params * math.log(n)


def f_test_p(before: Fit, after: Fit, n: int) -> float:
    """p-value of the nested-model F-test that the added parameters explain nothing."""
    q = after.n_params - before.n_params
    dof = n - after.n_params
    if q <= 0 or dof <= 0 or after.rss <= 0:
        return 1.0
    f_value = (before.rss - after.rss) / q / (after.rss / dof)
    from scipy import stats

    return float(stats.f.sf(f_value, q, dof)) if f_value > 0 else 1.0


DERIVED: RegistryView[Callable[[dict[str, float]], dict[str, float]]] = RegistryView(lambda e: e.derived)
"""Quantities reported beside an effect's parameters, computed from them (and given an error the
same way; each effect's `derived`, campaign/effects/): thermal drift's initial rate of slope change, µm/m per hour (per 3600 points without a
time column); the bow's RMS over its span, µm (its size: P2 and P3 have RMS 1/√5 and 1/√7)."""
ANGLES = ("phase_rad",)
"""Parameters that are angles: their differences are wrapped to (-π, π]."""


def jacobian(data: CampaignData, fit: Fit, step: float = 1e-4) -> tuple[np.ndarray, list]:
    """The Jacobian of the prediction with respect to the offsets, every fitted coefficient (label
    (term index, "coef", column in the form's full order)) and the log of every searched shape
    (label (term index, "log", key)); an offset's label is None."""
    a, slices = design(data, fit.terms)
    blocks = [a]
    labels: list[tuple[int, str, int | str] | None] = [None] * a.shape[1]
    for i, (term, sl) in enumerate(zip(fit.terms, slices)):
        if term.fixed:
            continue
        count = len(fit.coefs[i])
        kept = np.flatnonzero(term.keep if term.keep is not None else (True,) * count)
        for j, col in zip(range(sl.start, sl.stop), kept):
            labels[j] = (i, "coef", int(col))
    for i, (term, coefs) in enumerate(zip(fit.terms, fit.coefs)):
        for key in term.searched:
            base = form_of(term.name).columns(data, term.shape, term.held) @ coefs
            moved = {**term.shape, key: term.shape[key] * math.exp(step)}
            blocks.append(((form_of(term.name).columns(data, moved, term.held) @ coefs - base) / step)[:, None])
            labels.append((i, "log", key))
    return np.hstack(blocks), labels


def derived(effect: str, params: dict[str, float]) -> dict[str, float]:
    """The quantities computed from an effect's parameters (DERIVED); none for most effects."""
    extra = DERIVED.get(effect)
    return extra(params) if extra else {}


def term_params(term: Term, coefs: np.ndarray) -> dict[str, float]:
    """A free term's model parameters and its derived quantities (DERIVED)."""
    params = form_of(term.name).params(coefs, term.shape, term.held)
    return {**params, **derived(term.name, params)}


def standard_errors(data: CampaignData, fit: Fit, step: float = 1e-4) -> dict[str, dict[str, float]]:
    """1-σ standard errors of every fitted parameter (and derived quantity, DERIVED), in their
    units: cov = s²·(JᵀJ)⁻¹ over the offset, every coefficient and the log of every searched shape
    (s² = RSS/(n - p)), carried to each parameter by its gradient (the delta method: a periodic
    amplitude and phase from the sine and cosine coefficients, thermal drift's pivot from its two
    coefficients). Parameters the user gave, and fixed shapes (the bow's span), get none.
    Asymptotic (linearised) values: the spread over repeated campaigns, not a guarantee; a phase's
    error is meaningless when the amplitude is not different from zero."""
    jac, labels = jacobian(data, fit, step)
    n, p = jac.shape
    if n <= p:
        return {}
    cov = np.linalg.pinv(jac.T @ jac) * fit.rss / (n - p)
    out: dict[str, dict[str, float]] = {}
    for i, term in enumerate(fit.terms):
        index = [j for j, label in enumerate(labels) if label is not None and label[0] == i]
        if term.fixed or not index:
            continue

        def values(delta: np.ndarray, i: int = i, term: Term = term, index: list[int] = index) -> dict[str, float]:
            coefs, shape = fit.coefs[i].astype(float).copy(), dict(term.shape)
            for j, d in zip(index, delta):
                _, kind, what = labels[j]
                if kind == "coef":
                    coefs[what] += d
                else:
                    shape[what] *= math.exp(d)
            return term_params(replace(term, shape=shape), coefs)

        base = values(np.zeros(len(index)))
        sds = np.sqrt(np.maximum(np.diag(cov)[index], 0.0))
        grads = {k: np.zeros(len(index)) for k in base}
        for m in range(len(index)):
            h = np.zeros(len(index))
            h[m] = max(1e-3 * sds[m], 1e-12)
            up, down = values(h), values(-h)
            for k in base:
                diff = up[k] - down[k]
                if k in ANGLES:
                    diff = (diff + math.pi) % (2 * math.pi) - math.pi
                grads[k][m] = diff / (2 * h[m])
        sub = cov[np.ix_(index, index)]
        for k, g in grads.items():
            if k in term.held or not np.any(g):
                continue
            out.setdefault(term.name, {})[k] = float(math.sqrt(max(float(g @ sub @ g), 0.0)))
    return out

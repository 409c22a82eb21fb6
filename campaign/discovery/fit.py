"""Least-squares fitting of a model of effect terms to a campaign, and the tests discovery uses.

The deviation is offset (one per campaign fitted together) + Σ (free terms' columns · coefficients) + Σ (fixed terms' deviations).
Shape parameters (periods, time constants) are found by variable projection: for given shapes the
coefficients are a linear least-squares solution; the shapes are refined with
scipy.optimize.least_squares (in log space, within bounds) from a grid or periodogram start.
The tests: BIC, the nested F-test and standard errors here; cross-validation in campaign.discovery.cv.

Units: deviations and RMS values µm; everything else as in campaign.discovery.effects.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
from types import ModuleType
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from campaign.discovery.data import CampaignData, keep_rows
from campaign.discovery.effects import form_of, period_key, period_limits
from campaign.effects import RegistryView
from campaign.model import effect_um

if TYPE_CHECKING:
    from scipy import sparse


def _sparse() -> ModuleType:
    """scipy.sparse, imported when first needed: the command-line parsers import this module and
    load without scipy (tests/test_config.py)."""
    from scipy import sparse

    return sparse


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
        cols = full_columns(data, self)
        return cols if self.keep is None else cols[:, list(self.keep)]


REMEMBERED_MB = 128.0
"""Memory of the arrays remembered per data set (`remembered`), MB: a search computes the same term's
columns over and over (every candidate beside the same model, every step of a shape refinement beside
the same other terms, and on a dense table every fit beside tens of local terms of a few columns each:
at 100,000 rows one such term is about 5 MB, or a fraction of it when held sparse (`held_columns`):
the fifty-odd regions a dense table's locator may find fit, with the model beside them)."""


def term_key(term: Term) -> tuple:
    """What makes a term's columns the same columns: its name, shape and held values (a key of `remembered`)."""
    return (term.name, tuple(sorted(term.shape.items())), tuple(sorted(term.held.items())))


Remembered = TypeVar("Remembered", np.ndarray, "sparse.csc_matrix")


def remembered(data: CampaignData, key: tuple, make: Callable[[], Remembered]) -> Remembered:
    """make() for `data`, computed once while among the most recently used that fit in REMEMBERED_MB
    (per data set, in data.remembered). The array is shared: callers must not change it in place."""
    store = data.remembered
    if key in store:
        store.move_to_end(key)
        return store[key]
    value = make()
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    store[key] = value
    data.remembered_bytes += _nbytes(value)
    while len(store) > 1 and data.remembered_bytes > REMEMBERED_MB * 2**20:
        data.remembered_bytes -= _nbytes(store.popitem(last=False)[1])
    return value


def _nbytes(value: np.ndarray | sparse.csc_matrix) -> int:
    """What a remembered entry holds, bytes (its arrays' data and about ENTRY_BYTES besides)."""
    if isinstance(value, np.ndarray):
        return int(value.nbytes) + ENTRY_BYTES
    return int(value.data.nbytes + value.indices.nbytes + value.indptr.nbytes) + ENTRY_BYTES


ENTRY_BYTES = 400
"""About what one remembered entry holds besides its array's data (its key, the array's header), bytes."""


def full_columns(data: CampaignData, term: Term) -> np.ndarray:
    """The term's form's columns on `data`, every one (its keep mask not applied): remembered (as a
    sparse matrix when mostly zero, `held_columns`)."""
    held = held_columns(data, term)
    return held if isinstance(held, np.ndarray) else np.asarray(held.toarray())


def held_columns(data: CampaignData, term: Term) -> np.ndarray | sparse.csc_matrix:
    """The term's full columns as remembered: a sparse matrix when at most SPARSE_SHARE of their numbers
    is not zero (a local term's, zero outside its region: on a dense table fifty of them fit in a
    fraction of the memory), else the array."""
    def make() -> np.ndarray | sparse.csc_matrix:
        cols = form_of(term.name).columns(data, term.shape, term.held)
        mostly_zero = cols.size >= SPARSE_NUMBERS and np.count_nonzero(cols) <= SPARSE_SHARE * cols.size
        return _sparse().csc_matrix(cols) if mostly_zero else cols
    return remembered(data, term_key(term), make)


SPARSE_SHARE = 0.25
"""A term's columns with at most this share of their numbers not zero are held as a sparse matrix."""


SPARSE_NUMBERS = 100_000
"""... and only when they hold at least this many numbers (800 kB): on a smaller table a sparse
matrix's own bookkeeping costs more than its products save (a product of a few hundred rows takes
microseconds as an array, tens of them as a sparse matrix)."""


def weighted(data: CampaignData, rows: np.ndarray) -> np.ndarray:
    """`rows` (one per point: a vector or a matrix's rows) times each point's weight's square root
    (data.row_scale: the largest u / u): least squares on weighted rows weighs each point
    by 1/u². Unchanged when every point is alike."""
    scale = data.row_scale
    if scale is None:
        return rows
    return rows * (scale if rows.ndim == 1 else scale[:, None])


@dataclass
class Fit:
    """Fitted terms: coefficients per free term (in the form's full column order), offset µm (the
    first campaign's), prediction µm per point (`predicted`: it, or what computes it when first
    asked: most fits of a search are only compared by their RSS, and on a dense table the prediction
    is a pass over every column), residual sum of squares µm² (weighted: each residual times its
    point's data.row_scale), number of fitted parameters, and the offset of every campaign fitted
    together, µm (a campaign of several datums, a scan profile's sweeps: their mean)."""

    terms: list[Term]
    coefs: list[np.ndarray]
    offset_um: float
    predicted: np.ndarray | Callable[[], np.ndarray]
    rss: float
    n_params: int
    offsets_um: tuple[float, ...] = ()

    @property
    def prediction(self) -> np.ndarray:
        """The fit's deviation at each point, µm."""
        if callable(self.predicted):
            self.predicted = self.predicted()
        return self.predicted

    def params(self) -> dict[str, dict[str, float]]:
        """Effect name -> model parameters (physical units, see model.EFFECT_PARAMS)."""
        out = {}
        for term, coefs in zip(self.terms, self.coefs):
            out[term.name] = dict(term.held) if term.fixed else form_of(term.name).params(coefs, term.shape, term.held)
        return out

    def rms_um(self, y: np.ndarray) -> float:
        return float(np.sqrt(np.mean((y - self.prediction) ** 2)))


def fixed_deviation(data: CampaignData, terms: list[Term]) -> np.ndarray:
    """The capture-averaged deviation of the fixed terms, µm (computed once per data set: remembered)."""
    fixed = [t for t in terms if t.fixed]
    return remembered(data, ("fixed", *(term_key(t) for t in fixed)), lambda: _fixed_deviation(data, fixed))


def _fixed_deviation(data: CampaignData, terms: list[Term]) -> np.ndarray:
    total = np.zeros(len(data))
    w = data.w if data.w is not None else np.full(data.t.shape, np.inf)
    for term in terms:
        if term.fixed:
            values = effect_um(term.name, term.held, data.x[:, None], data.d[:, None], data.t, w)
            total += np.nanmean(np.where(np.isnan(data.t), np.nan, values), axis=1)
    return total


def design(data: CampaignData, terms: list[Term]) -> tuple[np.ndarray, list[slice]]:
    """The regressors: one offset column per datum (ones at its points: each campaign has its own
    laser datum, a scan profile's every sweep its own: data.datum) and a scan profile's sweeps'
    slopes beside another table (datum_columns), then each free term's kept columns."""
    offsets = datum_columns(data)
    blocks, slices, start = [offsets], [], offsets.shape[1]
    for term in terms:
        cols = np.zeros((len(data), 0)) if term.fixed else term.columns(data)
        blocks.append(cols)
        slices.append(slice(start, start + cols.shape[1]))
        start += cols.shape[1]
    return np.hstack(blocks), slices


def datum_columns(data: CampaignData) -> np.ndarray:
    """One offset column per datum (ones at its points); then, when campaigns are fitted together,
    one slope column per datum whose points are data.sloped (position less the datum's mean
    position, over its span): a scan profile's sweep, whose timing error grows along it with the
    clocks' rate error and wander, differently in each sweep (remembered)."""
    return remembered(data, ("datums",), lambda: _datum_columns(data))


def _datum_columns(data: CampaignData) -> np.ndarray:
    index = data.datum_index
    offsets = (index[:, None] == np.arange(data.datums)[None, :]).astype(float)
    if data.sloped is None or not data.sloped.any() or data.campaigns < 2:
        return offsets
    slopes = []
    for k in np.unique(index[data.sloped]):
        mine = index == k
        x = data.x[mine]
        col = np.zeros(len(data))
        col[mine] = (x - x.mean()) / (float(np.ptp(x)) or 1.0)
        slopes.append(col)
    return np.column_stack([offsets, *slopes])


class Blocks:
    """A model's design (`design`) as its blocks of columns, never stacked: the datums' columns and each
    free term's full columns (remembered), with the indices of the kept ones. Products with it cost
    O(n·p) and its normal matrix (`gram`) is assembled from remembered products of two blocks (CᵢᵀWCⱼ,
    W the rows' weights when `weighted`): a model and a candidate beside it share all but the
    candidate's, so a fit costs O(n·k·p) for a new term of k columns instead of O(n·p²) and no n × p
    copy (on a dense table of a hundred local terms, hundreds of MB)."""

    def __init__(self, data: CampaignData, terms: list[Term], weighted: bool = True):
        self.data = data
        self.w = data.row_scale**2 if weighted and data.row_scale is not None else None
        free = [t for t in terms if not t.fixed]
        self.keys: list[tuple] = [("datums",), *(term_key(t) for t in free)]
        self.fetched: dict[int, np.ndarray] = {}
        self.held: dict[int, np.ndarray | sparse.csc_matrix] = {}
        self.holders: list[Callable[[], np.ndarray | sparse.csc_matrix]] = [lambda: datum_columns(data)]
        self.holders += [lambda t=t: held_columns(data, t) for t in free]  # type: ignore[misc]
        self.makers: list[Callable[[], np.ndarray]] = [lambda: datum_columns(data)]
        self.makers += [lambda t=t: full_columns(data, t) for t in free]  # type: ignore[misc]
        self.getters = [lambda i=i: self._fetch(i) for i in range(len(self.makers))]
        self.kept: list[np.ndarray | None] = [None, *(None if t.keep is None else np.flatnonzero(t.keep) for t in free)]
        self.widths = [self._width(i) for i in range(len(self.keys))]
        self.starts = np.concatenate([[0], np.cumsum(self.widths)]).astype(int)

    def _fetch(self, i: int) -> np.ndarray:
        """Block i's full columns, asked of the remembered store once per Blocks."""
        if i not in self.fetched:
            self.fetched[i] = self.makers[i]()
        return self.fetched[i]

    def operand(self, i: int) -> np.ndarray | sparse.csc_matrix:
        """Block i's full columns for products: as remembered (`held_columns`: sparse when mostly zero)."""
        if i not in self.held:
            self.held[i] = self.holders[i]()
        return self.held[i]

    def _width(self, i: int) -> int:
        kept = self.kept[i]
        if kept is not None:
            return len(kept)
        return int(self.operand(i).shape[1])

    def slice_of(self, terms: list[Term], index: int) -> slice:
        """The columns of terms[index] (the terms the blocks were made of) in the design."""
        block = sum(1 for t in terms[:index + 1] if not t.fixed)
        if terms[index].fixed:
            return slice(0, 0)
        return slice(int(self.starts[block]), int(self.starts[block + 1]))

    @property
    def width(self) -> int:
        return int(self.starts[-1])

    def block(self, i: int) -> np.ndarray:
        """The kept columns of block i (n × its width)."""
        cols, kept = self.getters[i](), self.kept[i]
        return cols if kept is None else cols[:, kept]

    def _weighted(self, v: np.ndarray) -> np.ndarray:
        return v if self.w is None else v * (self.w if v.ndim == 1 else self.w[:, None])

    def _full(self, i: int, part: np.ndarray) -> np.ndarray:
        """Block i's kept coefficients `part` in its full column order (0 at the dropped)."""
        kept = self.kept[i]
        if kept is None:
            return part
        full = np.zeros((self.operand(i).shape[1], *part.shape[1:]))
        full[kept] = part
        return full

    def times(self, beta: np.ndarray) -> np.ndarray:
        """A·beta (n; beta: p, or p × m for n × m)."""
        out = np.zeros((len(self.data), *beta.shape[1:]))
        for i in range(len(self.keys)):
            if self.widths[i]:
                out += self.operand(i) @ self._full(i, beta[self.starts[i]:self.starts[i + 1]])
        return out

    def t_times(self, v: np.ndarray, key: tuple | None = None) -> np.ndarray:
        """AᵀW·v (p; v: n, or n × m for p × m); remembered per block when `key` names v."""
        wv = self._weighted(v)
        parts = []
        for i in range(len(self.keys)):
            if self.widths[i]:
                if key is None:
                    part = np.asarray(self.operand(i).T @ wv)
                else:
                    part = remembered(self.data, ("Aᵀy", self.w is not None, key, self.keys[i]),
                                      lambda i=i: np.asarray(self.operand(i).T @ wv))  # type: ignore[misc]
                parts.append(part if self.kept[i] is None else part[self.kept[i]])
        return np.concatenate(parts) if parts else np.zeros((0, *v.shape[1:]))

    def rows(self, index: np.ndarray, which: np.ndarray | None = None) -> np.ndarray:
        """A's rows `index` (len(index) × p); only the blocks where `which` (bool per block) when given."""
        chosen = [i for i in range(len(self.keys)) if self.widths[i] and (which is None or which[i])]
        out = np.zeros((len(index), sum(self.widths[i] for i in chosen)))
        at = 0
        for i in chosen:
            held, kept = self.operand(i), self.kept[i]
            part = held[index].toarray() if _sparse().issparse(held) else held[index]
            out[:, at:at + self.widths[i]] = part if kept is None else part[:, kept]
            at += self.widths[i]
        return out

    def columns_of(self, which: np.ndarray) -> np.ndarray:
        """The design's columns (bool per column) of the blocks where `which` (bool per block)."""
        return np.repeat(which, self.widths)

    def constant_within(self, index: np.ndarray, groups_hash: int) -> np.ndarray:
        """Bool per block: are its columns the same at every row of each group (`index`)? (A position's
        function within targets; remembered per block and grouping.)"""
        order = np.argsort(index, kind="stable")
        same = index[order][1:] == index[order][:-1]  # neighbours of one group, in the group order

        def check(i: int) -> np.ndarray:
            cols = self.getters[i]()[order]
            return np.array([bool(np.all(cols[1:][same] == cols[:-1][same]))])
        return np.array([bool(remembered(self.data, ("constant", groups_hash, self.keys[i]), partial(check, i))[0])
                         for i in range(len(self.keys))])

    def stacked(self) -> np.ndarray:
        """A itself (n × p): for the rare solve the normal equations cannot do."""
        return np.hstack([self.block(i) for i in range(len(self.keys))])

    def _pair(self, i: int, j: int, groups: tuple | None = None) -> np.ndarray:
        """CᵢᵀWCⱼ of the two blocks' full columns (remembered); with `groups` ((hash, members: each
        group's rows)), one per group (groups × ki × kj)."""
        tag = ("gram", self.w is not None, *(() if groups is None else (groups[0],)))
        key, swapped = (*tag, self.keys[i], self.keys[j]), (*tag, self.keys[j], self.keys[i])
        if swapped in self.data.remembered and key not in self.data.remembered:
            return np.swapaxes(remembered(self.data, swapped, lambda: np.zeros(0)), -1, -2)

        def make() -> np.ndarray:
            if groups is None:
                left, right = self.operand(i), self.operand(j)
                if self.w is not None:
                    right = _sparse().diags(self.w) @ right if _sparse().issparse(right) else right * self.w[:, None]
                product = left.T @ right
                return product.toarray() if _sparse().issparse(product) else np.asarray(product)
            left, right = self.operand(i), self.operand(j)
            if self.w is not None:
                right = _sparse().diags(self.w) @ right if _sparse().issparse(right) else right * self.w[:, None]
            products = [left[rows].T @ right[rows] for rows in groups[1]]
            return np.stack([p.toarray() if _sparse().issparse(p) else np.asarray(p) for p in products])
        return remembered(self.data, key, make)

    def _model_key(self, upto: int, groups: tuple | None) -> tuple:
        kept = tuple(None if k is None else tuple(k) for k in self.kept[:upto])
        return ("model gram", self.w is not None, None if groups is None else groups[0], *self.keys[:upto], kept)

    def gram(self, groups: tuple | None = None) -> np.ndarray:
        """AᵀWA of the kept columns (p × p); with `groups` (hash, members: each group's rows), each
        group's (groups × p × p). Remembered per model; a model whose first blocks are a remembered
        model (a candidate beside the current model, a shape refined in its last term) starts from
        that one's."""
        count = () if groups is None else (len(groups[1]),)
        whole = self._model_key(len(self.keys), groups)
        if whole in self.data.remembered:
            return np.array(remembered(self.data, whole, lambda: np.zeros(0)))
        out = np.zeros((*count, self.width, self.width))
        first = 0
        prefix = self._model_key(len(self.keys) - 1, groups)
        if len(self.keys) > 1 and prefix in self.data.remembered:
            first = len(self.keys) - 1
            held = int(self.starts[first])
            out[..., :held, :held] = remembered(self.data, prefix, lambda: np.zeros(0))
        for j in range(first, len(self.keys)):
            for i in range(j + 1):
                if not self.widths[i] or not self.widths[j]:
                    continue
                pair = self._pair(i, j, groups)
                if self.kept[i] is not None:
                    pair = pair[..., self.kept[i], :]
                if self.kept[j] is not None:
                    pair = pair[..., :, self.kept[j]]
                si, sj = slice(self.starts[i], self.starts[i + 1]), slice(self.starts[j], self.starts[j + 1])
                out[..., si, sj] = pair
                out[..., sj, si] = np.swapaxes(pair, -1, -2)
        if groups is None:  # (one per group would be groups × p × p: the pairs' are remembered)
            remembered(self.data, whole, lambda: out.copy())
        return out


NORMAL_COND = 1e4
"""Up to this condition number of the column-normalised design, least squares solves the normal
equations (one pass over the rows, then a p × p Cholesky, refined once above REFINE_COND: relative
error at most about NORMAL_COND × 1e-16 after the refinement); above it, an SVD of the whole
design (numpy's lstsq), which also holds a rank-deficient one."""


def _normal_scaled(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """(AᵀA of the column-normalised a, 1/column norms, its condition number) when a is tall, has no zero column and its
    normalised condition number is at most NORMAL_COND; None otherwise."""
    if not a.shape[0] > a.shape[1] > 0:
        return None
    return _gram_scaled(a.T @ a)


def _gram_scaled(gram: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """_normal_scaled from the normal matrix AᵀA of a tall A (changed in place)."""
    if not gram.shape[0]:
        return None
    diag = np.diag(gram).copy()
    if not np.all(diag > 0):
        return None
    scale = 1 / np.sqrt(diag)
    gram *= np.outer(scale, scale)
    eig = np.linalg.eigvalsh(gram)
    return (gram, scale, float(eig[-1] / eig[0])) if eig[0] > eig[-1] / NORMAL_COND**2 else None


def cholesky_upper(gram: np.ndarray) -> np.ndarray:
    """The upper Cholesky factor of a positive definite gram (LAPACK's potrf, as scipy's cho_factor
    calls it, without its checks: the normal matrices here passed _gram_scaled's or campaign.discovery.cv's
    eigenvalue test, so they are finite; a call costs a tenth of cho_factor's on a small matrix)."""
    from scipy.linalg import lapack

    factor, info = lapack.dpotrf(gram, lower=0, clean=0)
    if info != 0:
        raise np.linalg.LinAlgError(f"the normal matrix is not positive definite (potrf info {info})")
    return np.asarray(factor)


def cholesky_solve(factor: np.ndarray, b: np.ndarray) -> np.ndarray:
    """gram⁻¹·b from cholesky_upper's factor (potrs, as scipy's cho_solve)."""
    from scipy.linalg import lapack

    x, info = lapack.dpotrs(factor, b, lower=0)
    if info != 0:
        raise ValueError(f"potrs: illegal value in argument {-info}")
    return np.asarray(x)


REFINE_COND = 1e3
"""Above this condition number of the normalised normal matrix (the design's squared), the normal
equations' solution gets one step of iterative refinement (below it, its relative error is under
about 1e-13 without)."""


def _times(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """a·v for a tall a (numpy's einsum: several times faster than BLAS's matrix-vector product on
    a few columns)."""
    return np.asarray(np.einsum("ij,j->i", a, v))


def _t_times(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """aᵀ·v for a tall a (einsum, as _times)."""
    return np.asarray(np.einsum("ij,i->j", a, v))


def _solve(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    normal = _normal_scaled(a)
    if normal is not None:
        gram, scale, cond = normal
        factor = cholesky_upper(gram)
        beta = scale * cholesky_solve(factor, scale * _t_times(a, y))
        if cond > REFINE_COND:  # one step of iterative refinement
            beta += scale * cholesky_solve(factor, scale * _t_times(a, y - _times(a, beta)))
        return np.asarray(beta)
    return np.linalg.lstsq(a, y, rcond=None)[0]


def thin_q(a: np.ndarray) -> np.ndarray:
    """An orthonormal basis of a's columns (n × p, as the Q of a thin QR): Cholesky QR done twice on
    the column-normalised matrix (O(n·p²)) when its condition number is at most NORMAL_COND;
    numpy's Householder QR otherwise (a rank-deficient a)."""
    normal = _normal_scaled(a)
    if normal is None:
        return np.linalg.qr(a)[0]
    from scipy import linalg

    gram, scale, _cond = normal
    upper = linalg.cholesky(gram)
    q = a @ (scale[:, None] * linalg.solve_triangular(upper, np.eye(len(upper))))  # a·D·R⁻¹
    again = linalg.cholesky(q.T @ q)
    return np.asarray(q @ linalg.solve_triangular(again, np.eye(len(again))))


def outside_norms(base: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The norm of each column of `cols` outside the span of `base`'s columns: from the normal
    equations, ‖c‖² - bᵀ(AᵀA)⁻¹b with b = Aᵀc (one pass over the rows), when base is well conditioned
    (NORMAL_COND); through thin_q otherwise."""
    normal = _normal_scaled(base)
    total = np.einsum("ij,ij->j", cols, cols)
    if normal is not None:
        gram, scale, _cond = normal
        b = scale[:, None] * (base.T @ cols)
        inside = np.einsum("ij,ij->j", b, cholesky_solve(cholesky_upper(gram), b))
        out2 = total - inside
        if np.all(out2 > 1e-6 * total):  # no cancellation to speak of: else the projection below
            return np.asarray(np.sqrt(out2))
    q = thin_q(base)
    return np.asarray(np.linalg.norm(cols - q @ (q.T @ cols), axis=0))


def _solve_blocks(blocks: Blocks, y: np.ndarray, y_key: tuple) -> tuple[np.ndarray, float | None]:
    """_solve of the weighted design and y (unweighted, n; `y_key` names it for the remembered AᵀWy)
    from the normal matrix the blocks assemble (the same test, factor and refinement: only AᵀWA is
    summed differently), and the weighted RSS from the normal equations, yᵀWy - βᵀ(2AᵀWy - AᵀWAβ):
    stationary at the solution, so accurate to rounding of yᵀWy, without a pass over the rows. Above
    NORMAL_COND the stacked design's SVD, as there (RSS None: from the residual)."""
    normal = _gram_scaled(blocks.gram()) if len(y) > blocks.width else None
    if normal is None:
        return _solve(weighted(blocks.data, blocks.stacked()), weighted(blocks.data, y)), None
    gram, scale, cond = normal
    factor = cholesky_upper(gram)
    aty = blocks.t_times(y, y_key)
    beta = scale * cholesky_solve(factor, scale * aty)
    if cond > REFINE_COND:  # one step of iterative refinement
        beta += scale * cholesky_solve(factor, scale * blocks.t_times(y - blocks.times(beta)))
    yty = float(remembered(blocks.data, ("yWy", blocks.w is not None, y_key),
                           lambda: np.array([np.sum(blocks._weighted(y) * y)]))[0])
    unscaled = beta / scale  # the normal matrix is held column-normalised: AᵀWA = D⁻¹·gram·D⁻¹
    rss = yty - float(beta @ (2 * aty)) + float(unscaled @ gram @ unscaled)
    return np.asarray(beta), max(rss, 0.0)


def normal_beside(data: CampaignData, terms: list[Term], extra: np.ndarray) -> tuple[Blocks, np.ndarray, np.ndarray]:
    """The design's blocks, and the normal equations of the design with `extra` columns (n × m) beside
    it, on weighted rows: [A, E]ᵀW[A, E] and [A, E]ᵀW(y - fixed terms' deviation) (from the blocks:
    no stacked n × p design)."""
    blocks = Blocks(data, terms)
    w = data.row_scale**2 if data.row_scale is not None else np.ones(len(data))
    cross = blocks.t_times(extra)
    normal = np.block([[blocks.gram(), cross], [cross.T, extra.T @ (w[:, None] * extra)]])
    y = data.y - fixed_deviation(data, terms)
    return blocks, normal, np.concatenate([blocks.t_times(y), extra.T @ (w * y)])


def solve_normal(normal: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The least-squares coefficients from normal equations (a pseudo-inverse of the column-normalised
    normal matrix: a direction the columns do not determine gets no coefficient, as an SVD of the
    rows gives)."""
    norms = np.sqrt(np.maximum(np.diag(normal), 0.0))
    norms[norms == 0] = 1.0
    return np.asarray(np.linalg.pinv(normal / np.outer(norms, norms)) @ (rhs / norms) / norms)


def _outside_norms_blocks(blocks: Blocks) -> tuple[np.ndarray, np.ndarray]:
    """outside_norms of the last block's columns beside the others' (from the normal matrix the blocks
    assemble; the stacked columns when outside_norms would project), and the columns' norms."""
    gram = blocks.gram()
    held = int(blocks.starts[-2])
    total = np.diag(gram)[held:].copy()
    normal = _gram_scaled(gram[:held, :held].copy()) if len(blocks.data) > held else None
    if normal is not None:
        base_gram, scale, _ = normal
        b = scale[:, None] * gram[:held, held:]
        inside = np.einsum("ij,ij->j", b, cholesky_solve(cholesky_upper(base_gram), b))
        out2 = total - inside
        if np.all(out2 > 1e-6 * total):  # no cancellation to speak of: else the projection
            return np.sqrt(out2), np.sqrt(total)
    a = blocks.stacked()
    return outside_norms(a[:, :held], a[:, held:]), np.sqrt(total)


def linear_fit(data: CampaignData, terms: list[Term]) -> Fit:
    """Fit the coefficients for the terms' current shapes (from the normal matrix of the design's
    blocks, `Blocks`: the design is not stacked; the prediction is computed when asked)."""
    fixed = [t for t in terms if t.fixed]
    y_key = ("fixed", *(term_key(t) for t in fixed))
    base = fixed_deviation(data, terms)
    blocks = Blocks(data, terms)
    beta, rss = _solve_blocks(blocks, data.y - base, y_key)

    def prediction() -> np.ndarray:  # (its own Blocks: a fit kept must not keep the columns it fetched)
        return np.asarray(fixed_deviation(data, terms) + Blocks(data, terms).times(beta))

    slices = [slice(0, 0)] * len(terms)
    free = [k for k, t in enumerate(terms) if not t.fixed]
    for block, k in enumerate(free, start=1):
        slices[k] = slice(int(blocks.starts[block]), int(blocks.starts[block + 1]))
    coefs = []
    for term, sl in zip(terms, slices):
        full = np.zeros(0 if term.fixed else len(term.keep) if term.keep is not None else sl.stop - sl.start)
        if not term.fixed:
            keep = term.keep if term.keep is not None else (True,) * len(full)
            full[list(np.flatnonzero(keep))] = beta[sl]
        coefs.append(full)
    n_params = blocks.width + sum(len(t.searched) for t in terms)
    datums = beta[:data.datums]
    first = np.bincount(data.datum_index, data.campaign_index, data.datums) / np.bincount(data.datum_index,
                                                                                        minlength=data.datums)
    offsets = tuple(float(np.mean(datums[first == c])) for c in range(data.campaigns))
    if rss is None:
        predicted = prediction()
        return Fit(terms, coefs, float(beta[0]), predicted,
                   float(np.sum(weighted(data, data.y - predicted) ** 2)), n_params, offsets)
    return Fit(terms, coefs, float(beta[0]), prediction, rss, n_params, offsets)


def searched_periods(data: CampaignData) -> tuple[float, float]:
    """The range of periods searched on this data, mm (period_limits; the same for every period term,
    remembered: the searches and the periodogram ask often, and each asking sorts the positions)."""
    low, high = remembered(data, ("period_limits",), lambda: np.array(period_limits(data)))
    return float(low), float(high)


def shape_bounds(data: CampaignData, name: str, key: str) -> tuple[float, float]:
    """The bounds of a searched shape parameter: the period's range, or a third of the lowest and
    three times the highest value of its grid (a time constant's; a grid runs upwards)."""
    if key == period_key(name):
        return searched_periods(data)
    grid = form_of(name).grid(data, {})
    return grid[0][key] / 3, grid[-1][key] * 3


def _constant_within(data: CampaignData, index: np.ndarray, count: np.ndarray, moving: list[int],
                     probes: list[list[Term]]) -> bool:
    """Are the moving terms' columns the same within every group of `index`, on every probe?"""
    for probe in probes:
        for i in moving:
            cols = full_columns(data, probe[i])
            means = np.column_stack([np.bincount(index, c) for c in cols.T]) / count[:, None]
            if np.max(np.abs(cols - means[index]), initial=0.0) > 1e-12 * max(1.0, float(np.max(np.abs(cols)))):
                return False
    return True


REDUCE_SHARE = 0.5
"""A shape search runs on the projected problem (reduced_residual) when the data has at most this
share of its rows as distinct (position, direction) pairs."""


def distinct_rows(data: CampaignData, by_direction: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The first row of each distinct position (or position and direction) and each row's index among
    them, in their sorted order (np.unique's: data.x[first] are the sorted distinct positions);
    remembered, the two arrays end to end (the shape searches, the local grid and the periodogram ask
    for them on every model)."""
    def both() -> np.ndarray:
        by = np.column_stack([data.x, data.d]) if by_direction else data.x[:, None]
        _, first, index = np.unique(by, axis=0, return_index=True, return_inverse=True)
        return np.concatenate([first, index.ravel()])

    packed = remembered(data, ("distinct", by_direction), both)
    return packed[:len(packed) - len(data)], packed[len(packed) - len(data):]


def reduced_residual(data: CampaignData, terms: list[Term], moving: list[int],
                     probes: list[list[Term]]) -> Callable[[list[Term]], np.ndarray] | None:
    """The residual of a shape search, projected exactly onto a smaller space, when the moving terms'
    columns (`moving`: their indices in `terms`) are functions of position (a screw lead, a local
    error), or of position and direction (one per direction), alone (checked on every term list of
    `probes`). Every column of the model then lies in the span W of the indicators of the distinct
    positions (or pairs) and of the other terms' parts outside them; ‖y - Aβ‖² = ‖y - WWᵀy‖² + ‖Wᵀy - WᵀAβ‖², so the returned
    function (terms at new shapes -> Wᵀy - WᵀAβ̂, with √‖y - WWᵀy‖² appended) has the norm and the
    Jacobian's normal matrix of the full residual: least squares takes the same steps on about one
    row per position (or pair). None when the moving columns are not such functions or the saving is small
    (REDUCE_SHARE)."""
    for by_direction in (False, True):  # positions, else pairs
        first, index = distinct_rows(data, by_direction)
        count = np.bincount(index).astype(float)
        if len(first) <= REDUCE_SHARE * len(data) and _constant_within(data, index, count, moving, probes):
            break
    else:
        return None
    if data.row_scale is not None:  # weighted rows: a column of position alone is not so on them
        return None
    still = [t for i, t in enumerate(terms) if i not in moving]
    y = data.y - fixed_deviation(data, terms)
    blocks = Blocks(data, still)
    # the other terms' block by block (never stacked): their means per pair, and their parts outside
    # the pairs' indicators, which are zero (to rounding: below the cut of `kept`) for a block of
    # position (or pair) alone (a screw lead, a local term, the offsets): only the other blocks' are formed
    b_means = np.zeros((len(count), blocks.width))
    moving_within = np.zeros(blocks.width, dtype=bool)
    outside_parts = []
    for i in range(len(blocks.keys)):
        cols = blocks.block(i)
        means = np.column_stack([np.bincount(index, c, len(count)) for c in cols.T]) / count[:, None] if cols.shape[1] \
            else np.zeros((len(count), 0))
        b_means[:, blocks.starts[i]:blocks.starts[i + 1]] = means
        part = cols - means[index]
        if np.max(np.abs(part), initial=0.0) > 1e-12 * max(1.0, float(np.max(np.abs(cols), initial=0.0))):
            moving_within[blocks.starts[i]:blocks.starts[i + 1]] = True
            outside_parts.append(part)
    outside = np.hstack(outside_parts) if outside_parts else np.zeros((len(y), 0))
    eig, vectors = np.linalg.eigh(outside.T @ outside)
    b_norm = math.sqrt(max(float(np.trace(blocks.gram())), 0.0))
    kept = eig > (1e-7 * max(b_norm, 1e-300)) ** 2  # (what is below adds < 1e-14 to the RSS)
    u = outside @ (vectors[:, kept] / np.sqrt(eig[kept]))
    root = np.sqrt(count)
    y_small = np.concatenate([np.bincount(index, y) / root, u.T @ y])
    u_b = np.zeros((u.shape[1], blocks.width))
    u_b[:, moving_within] = u.T @ outside  # uᵀB: the pairs' means of B are orthogonal to u
    b_small = np.vstack([b_means * root[:, None], u_b])
    rest = math.sqrt(max(float(y @ y - y_small @ y_small), 0.0))
    pairs = keep_rows(data, np.isin(np.arange(len(data)), first))  # one row per pair, in data order
    to_keys = np.argsort(np.argsort(first))  # the row of `pairs` of each key

    def residual(new: list[Term]) -> np.ndarray:
        cols = np.hstack([new[i].columns(pairs)[to_keys] for i in moving]) * root[:, None]
        a = np.hstack([b_small, np.vstack([cols, np.zeros((len(y_small) - len(cols), cols.shape[1]))])])
        return np.append(y_small - a @ _solve(a, y_small), rest)

    return residual


PROJECT_COLUMNS = 20
"""A shape search beside at least this many columns that do not move (a dense table's local terms)
runs with them projected out once (projected_residual)."""


def _basis_of(gram: np.ndarray, cut: float = 1e-14) -> np.ndarray:
    """T (p × r) with A·T an orthonormal basis of A's span, from A's normal matrix AᵀA (`gram`):
    the column-normalised matrix's eigenvectors, those whose eigenvalue is below `cut` of the largest
    (so its singular value below √cut) left out."""
    norms = np.sqrt(np.maximum(np.diag(gram), 0.0))
    norms[norms == 0] = 1.0
    eig, vectors = np.linalg.eigh(gram / np.outer(norms, norms))
    keep = eig > cut * max(float(eig.max()), 1e-300) if len(eig) else np.zeros(0, dtype=bool)
    return np.asarray((vectors[:, keep] / np.sqrt(eig[keep])) / norms[:, None])


def projected_residual(data: CampaignData, terms: list[Term],
                       moving: list[int]) -> Callable[[list[Term]], np.ndarray] | None:
    """The residual of a shape search with the columns that do not move (the offsets and every term
    not in `moving`) projected out once: for the moving terms' columns C at new shapes, the residual
    of the joint least squares is (I - P)(y - Cβ) with β the fit of (I - P)C to (I - P)y (Frisch-Waugh-
    Lovell), the same vector as linear_fit's in O(n·p·k) instead of O(n·p²) (p the columns held, k the
    moving ones). None below PROJECT_COLUMNS held columns (a refit is as cheap)."""
    still = [t for i, t in enumerate(terms) if i not in moving]
    blocks = Blocks(data, still)  # on weighted rows, as the refit it stands for
    if blocks.width < PROJECT_COLUMNS:
        return None
    to_q = _basis_of(blocks.gram())  # the span of what is held, to rounding: Q = (weighted B)·to_q

    def outside(v: np.ndarray) -> np.ndarray:  # (I - QQᵀ) of v's weighted rows, from the blocks
        return np.asarray(weighted(data, v - blocks.times(to_q @ (to_q.T @ blocks.t_times(v)))))

    y_out = outside(data.y - fixed_deviation(data, terms))

    def residual(new: list[Term]) -> np.ndarray:
        c_out = outside(np.hstack([new[i].columns(data) for i in moving]))
        return np.asarray(y_out - c_out @ _solve(c_out, y_out))

    return residual


REFINE_TOL = 1e-6
"""refine's tolerances on the cost's and the log shapes' relative changes (scipy's ftol and xtol,
default 1e-8): on 70 drawn discoveries the same names, places and gaps as at 1e-8, a parameter
differing at most in its fourth decimal, in about 10 % less time."""


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

    moving = sorted({i for i, _ in slots})
    reduced = reduced_residual(data, terms, moving, [with_shapes(start), with_shapes(start + 0.1)])
    projected = projected_residual(data, terms, moving) if reduced is None else None

    def residual(logs: np.ndarray) -> np.ndarray:
        if reduced is not None:
            return reduced(with_shapes(logs))
        if projected is not None:
            return projected(with_shapes(logs))
        f = linear_fit(data, with_shapes(logs))
        return weighted(data, data.y - f.prediction)

    from scipy import optimize

    result = optimize.least_squares(residual, start, bounds=(lower, upper), x_scale=0.1, diff_step=1e-4,
                                    ftol=REFINE_TOL, xtol=REFINE_TOL)
    best = linear_fit(data, with_shapes(result.x))
    first = linear_fit(data, terms)
    return best if best.rss <= first.rss else first


def drop_collinear(data: CampaignData, terms: list[Term], term: Term) -> Term:
    """`term` with its columns that the model's columns already span dropped (keep mask)."""
    outside, norms = _outside_norms_blocks(Blocks(data, [*terms, replace(term, keep=None)], weighted=False))
    keep = tuple(bool(n > 0 and o > COLLINEAR * n) for o, n in zip(outside, norms))
    return replace(term, keep=keep)


def confounders(data: CampaignData, terms: list[Term], term: Term) -> list[str]:
    """The model's effects whose columns (with the offset) span `term`'s columns on this data."""
    cols = form_of(term.name).columns(data, term.shape, term.held)
    names = []
    for other in terms:
        if other.name == term.name:
            continue
        q = thin_q(design(data, [replace(other, fixed=False, keep=None)])[0])
        outside = cols - q @ (q.T @ cols)
        if np.linalg.norm(outside) <= COLLINEAR * max(float(np.linalg.norm(cols)), 1e-300):
            names.append(other.name)
    return names


def span_at_positions(data: CampaignData, fit: Fit, where: np.ndarray, positions: int) -> tuple[np.ndarray, np.ndarray]:
    """For an orthonormal basis Q of the span of the fit's design on weighted rows: the sums at each
    distinct position (`where`: each row's, of `positions`) of its weighted rows times the rows' weight's
    square root (positions × r), and Qᵀ times the weighted residual (r): what a search over shapes of
    position (a sine, a local shape) needs of the model. From the design's blocks and normal matrix
    (Q = weighted A·T, `_basis_of`): never the n × p design or Q themselves."""
    blocks = Blocks(data, fit.terms)
    to_q = _basis_of(blocks.gram())
    w = data.row_scale**2 if data.row_scale is not None else np.ones(len(data))
    a_at = np.column_stack([np.bincount(where, w * col, minlength=positions)
                            for i in range(len(blocks.keys)) for col in blocks.block(i).T])
    return a_at @ to_q, to_q.T @ blocks.t_times(data.y - fit.prediction)


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


def jacobian_normal(data: CampaignData, fit: Fit, step: float = 1e-4) -> tuple[np.ndarray, list]:
    """JᵀWJ of the Jacobian J of the prediction with respect to the offsets, every fitted coefficient
    (label (term index, "coef", column in the form's full order)) and the log of every searched shape
    (label (term index, "log", key)), on weighted rows (`weighted`); an offset's label is None. The
    coefficients' part is the design's normal matrix (`Blocks`: not stacked)."""
    blocks = Blocks(data, fit.terms)
    labels: list[tuple[int, str, int | str] | None] = [None] * blocks.width
    free = [i for i, t in enumerate(fit.terms) if not t.fixed]
    for block, i in enumerate(free, start=1):
        term = fit.terms[i]
        kept = np.flatnonzero(term.keep if term.keep is not None else (True,) * len(fit.coefs[i]))
        for j, col in zip(range(int(blocks.starts[block]), int(blocks.starts[block + 1])), kept):
            labels[j] = (i, "coef", int(col))
    moves = []
    for i, (term, coefs) in enumerate(zip(fit.terms, fit.coefs)):
        for key in term.searched:
            base = form_of(term.name).columns(data, term.shape, term.held) @ coefs
            moved = {**term.shape, key: term.shape[key] * math.exp(step)}
            moves.append((form_of(term.name).columns(data, moved, term.held) @ coefs - base) / step)
            labels.append((i, "log", key))
    gram = blocks.gram()
    if not moves:
        return gram, labels
    shapes = np.column_stack(moves)
    cross = blocks.t_times(shapes)
    own = shapes.T @ weighted(data, weighted(data, shapes))
    return np.block([[gram, cross], [cross.T, own]]), labels


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
    (s² = RSS/(n - p); J and the RSS on weighted rows, `weighted`), carried to each parameter by its gradient (the delta method: a periodic
    amplitude and phase from the sine and cosine coefficients, thermal drift's pivot from its two
    coefficients). Parameters the user gave, and fixed shapes (the bow's span), get none.
    Asymptotic (linearised) values: the spread over repeated campaigns, not a guarantee; a phase's
    error is meaningless when the amplitude is not different from zero."""
    normal, labels = jacobian_normal(data, fit, step)
    n, p = len(data), len(labels)
    if n <= p:
        return {}
    cov = np.linalg.pinv(normal) * fit.rss / (n - p)
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

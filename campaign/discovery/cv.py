"""Cross-validation of a fit (campaign.discovery.fit): each group of rows (a target, a run) predicted
from the others, its shapes held (cv_rms_um, cv_group_errors); with searched shapes found again in
each fold (cv_searched_errors); and GrowingFit, terms tried one at a time beside a fit on a dense
table without refitting it. Few groups are refitted fold by fold; many (a dense table) come from the
hat matrix's diagonal blocks, in time linear in the rows.

Units: residuals and RMS values µm (weighted rows, as the fit).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from campaign.discovery.data import CampaignData, keep_rows
from campaign.discovery.fit import (
    COLLINEAR,
    Blocks,
    Fit,
    Term,
    cholesky_solve,
    cholesky_upper,
    design,
    fixed_deviation,
    remembered,
    term_key,
    weighted,
)

CV_RCOND = COLLINEAR
"""In a cross-validation fold, directions of the (column-normalised) design whose singular value is
below this fraction of the largest are left out: a fold can lose what tells two columns apart
(leaving out the one run in which a short thermal time constant acts makes its columns those of
linear_scale and the offset), and the prediction must then be what the fold can say, not a
difference of two huge coefficients."""


CV_FOLDS_REFITTED = 200
"""Up to this many groups each fold is refitted; beyond (a dense table), the left-out residuals come
from the whole fit's hat matrix, group by group (e_g = (I - H_gg)⁻¹ r_g), in time linear in the rows."""


CV_BLOCK_MAX = 2000
"""A group larger than this is refitted whatever the number of groups (its hat block would be
that size squared)."""


def cv_rms_um(data: CampaignData, terms: list[Term], groups: np.ndarray) -> float:
    """Cross-validated RMS, µm: each group (a target or a run) predicted from the others, shapes
    held at their fitted values (a direction the fold cannot determine is left out: CV_RCOND);
    on weighted rows (`weighted`), as the fit; computed once per model and grouping (remembered:
    every candidate of a step compares with the same model)."""
    return float(np.sqrt(cv_group_errors(data, terms, groups).sum() / len(data))) if len(data) else 0.0


def cv_group_errors(data: CampaignData, terms: list[Term], groups: np.ndarray) -> np.ndarray:
    """Each group's weighted sum of squared left-out residuals (µm², in the order of the groups' sorted
    names), as cv_rms_um computes them: by refitting each fold, or from the hat matrix beyond
    CV_FOLDS_REFITTED groups (time linear in the rows); remembered per model and grouping."""
    key = ("cv", *((term_key(t), t.keep, t.fixed) for t in terms), hash(np.asarray(groups).tobytes()))
    return remembered(data, key, lambda: _cv_group_errors(data, terms, groups))


def _cv_group_errors(data: CampaignData, terms: list[Term], groups: np.ndarray) -> np.ndarray:
    blocks = Blocks(data, terms)
    y = data.y - fixed_deviation(data, terms)
    if groups is data.target_index:  # the commonest grouping, its indices already those of the sorted targets
        count, index = len(data.targets_mm), groups
    else:
        names, inverse = np.unique(groups, return_inverse=True)
        count, index = len(names), inverse.ravel()
    if count > CV_FOLDS_REFITTED:
        return _cv_from_hat(blocks, y, index, hash(np.asarray(groups).tobytes()))
    return _cv_refitted(blocks, y, index, hash(np.asarray(groups).tobytes()))


def _fold_solve(fold_gram: np.ndarray, fold_aty: np.ndarray) -> np.ndarray:
    """A fold's least squares from its normal equations (AᵀWA and AᵀWy of its rows): on the
    column-normalised design, directions whose singular value is below CV_RCOND of the largest left
    out (the minimum-norm solution, as a truncated SVD of its rows gives, from the normal matrix's
    eigenvectors: accurate to about 1e-10 at the cut)."""
    norms = np.sqrt(np.maximum(np.diag(fold_gram), 0.0))
    norms[norms == 0] = 1.0
    eig, vectors = np.linalg.eigh(fold_gram / np.outer(norms, norms))
    sv = np.sqrt(np.maximum(eig, 0.0))
    keep = sv > CV_RCOND * sv.max() if len(sv) else np.zeros(0, dtype=bool)
    v = vectors[:, keep]
    return np.asarray(v @ ((v.T @ (fold_aty / norms)) / eig[keep]) / norms)


def _fold_beta(fold_gram: np.ndarray, fold_aty: np.ndarray) -> np.ndarray:
    """A fold's coefficients: Cholesky of its column-normalised normal matrix when no direction is near
    CV_RCOND (a margin of 10 in the singular values) and no column is empty; _fold_solve otherwise."""
    diag = np.diag(fold_gram)
    if len(diag) and np.all(diag > 0):
        scale = 1 / np.sqrt(diag)
        scaled = fold_gram * np.outer(scale, scale)
        eig = np.linalg.eigvalsh(scaled)
        if eig[0] > eig[-1] * CV_RCOND**2 * 100:
            return np.asarray(scale * cholesky_solve(cholesky_upper(scaled), scale * fold_aty))
    return _fold_solve(fold_gram, fold_aty)


def _cv_refitted(blocks: Blocks, y: np.ndarray, index: np.ndarray, groups_hash: int) -> np.ndarray:
    """Each group's leave-out sum of squares (cv_group_errors), each fold refitted from its normal equations: the whole design's
    less its group's (G - A_gᵀWA_g, each group's remembered per pair of blocks: time linear in the
    rows, and only a new term's products computed for a model that differs from a known one by it).
    The design's rows are gathered once, group after group (ROWS_GATHERED_CELLS), not once per fold."""
    data = blocks.data
    count = int(index.max()) + 1 if len(index) else 0
    gram, aty = blocks.gram(), blocks.t_times(y)
    order = np.argsort(index, kind="stable")  # each group's rows in ascending order, the groups one after another
    bounds = np.searchsorted(index[order], np.arange(count + 1))
    members = [order[bounds[g]:bounds[g + 1]] for g in range(count)]
    per_group = blocks.gram((groups_hash, members))
    w = data.row_scale**2 if data.row_scale is not None else np.ones(len(y))
    gathered = blocks.rows(order) if len(y) * blocks.width <= ROWS_GATHERED_CELLS else None
    return np.array([_fold_ss(blocks, y, w, members[g], gram, aty, per_group[g],
                              None if gathered is None else gathered[bounds[g]:bounds[g + 1]])
                     for g in range(count)])


ROWS_GATHERED_CELLS = 4_000_000
"""Up to this many numbers (32 MB) _cv_refitted gathers the design's rows in one go; beyond, fold by fold."""


def _fold_ss(blocks: Blocks, y: np.ndarray, w: np.ndarray, out: np.ndarray, gram: np.ndarray,
             aty: np.ndarray, out_gram: np.ndarray | None = None, out_rows: np.ndarray | None = None) -> float:
    """The weighted sum of squares of the rows `out` predicted by the fit without them, from the whole
    design's normal equations (`gram`, `aty`) less theirs (`out_gram`: their AᵀWA when known; `out_rows`:
    the design's rows `out` when gathered)."""
    ag, yg, wg = blocks.rows(out) if out_rows is None else out_rows, y[out], w[out]
    beta = _fold_beta(gram - (ag.T @ (wg[:, None] * ag) if out_gram is None else out_gram), aty - ag.T @ (wg * yg))
    return float(np.sum(wg * (yg - ag @ beta) ** 2))


def shapes_held(data: CampaignData, terms: list[Term]) -> list[Term]:
    """The terms as they are: a fold of cv_searched_errors keeps every shape."""
    return terms


def cv_searched_errors(data: CampaignData, terms: list[Term], groups: np.ndarray,
                       refined: Callable[[CampaignData, list[Term]], list[Term]]) -> np.ndarray:
    """Each group's sum of squared left-out residuals (weighted, µm²), as cv_rms_um but with every
    searched shape (a local term's centre and width, a period) refined again without the group, from
    its value on all the data: a shape chosen on all the targets predicts the one left out too well,
    so a searched bump would beat an effect of fixed shape (a bow) that fits as well. `refined(fold,
    terms)`: the terms with their shapes refined on the fold's rows. One refinement per group: for
    the comparisons where that matters, not for every candidate. With `shapes_held` no fold refines
    anything: cv_group_errors, without a copy of the rows per fold."""
    if refined is shapes_held:
        return cv_group_errors(data, terms, groups)
    _, index = np.unique(groups, return_inverse=True)
    index = index.ravel()
    w = data.row_scale**2 if data.row_scale is not None else np.ones(len(data))
    sums = np.zeros(int(index.max()) + 1 if len(index) else 0)
    for g in range(len(sums)):
        out = np.flatnonzero(index == g)
        shaped = refined(keep_rows(data, index != g), terms)
        blocks = Blocks(data, shaped)
        y = data.y - fixed_deviation(data, shaped)
        sums[g] = _fold_ss(blocks, y, w, out, blocks.gram(), blocks.t_times(y))
    return sums


HAT_CELLS = 1_000_000
"""Numbers gathered at a time by the hat route's blocks (8 MB per array, as periodogram.PERIODOGRAM_CELLS)."""


def _cv_from_hat(blocks: Blocks, y: np.ndarray, index: np.ndarray, groups_hash: int) -> np.ndarray:
    """Each group's leave-out sum of squares (cv_group_errors) from the hat matrix of the whole fit (column-normalised, directions
    below CV_RCOND left out): e_g = (I - H_gg)⁻¹ r_g where that block is well conditioned, the groups of
    one size at once. The basis of the fit's span, Q = A·T, comes from the eigenvectors of the p × p
    normal matrix (singular values above CV_RCOND of the largest only, so accurate to about 1e-10);
    Q's rows are formed a few groups at a time from the design's blocks (never n × p at once), a block
    that is the same at every row of a group (a function of position, the groups being targets) once
    per group. A group above CV_BLOCK_MAX rows is refitted instead, and so is a group whose block is
    not well conditioned (its leverages sum to 1 or more: a direction the fold may not determine, as a
    departure at the one target left out, where the pseudo-inverse would drop the residual's part in
    it and predict the group better than the fold can)."""
    data = blocks.data
    root = data.row_scale if data.row_scale is not None else np.ones(len(y))
    gram = blocks.gram()
    norms = np.sqrt(np.maximum(np.diag(gram), 0.0))
    norms[norms == 0] = 1.0
    eig, vectors = np.linalg.eigh(gram / np.outer(norms, norms))
    sv = np.sqrt(np.maximum(eig, 0.0))
    keep = sv > CV_RCOND * sv.max() if len(sv) else np.zeros(0, dtype=bool)
    to_q = (vectors[:, keep] / sv[keep]) / norms[:, None]  # p × r: Q = (weighted A)·to_q
    aty = blocks.t_times(y)
    r = root * (y - blocks.times(to_q @ (to_q.T @ aty)))
    order = np.argsort(index, kind="stable")
    sizes = np.bincount(index)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    same = blocks.constant_within(index, groups_hash)
    same_cols = blocks.columns_of(same)
    sums = np.zeros(len(sizes))
    for size in np.unique(sizes[sizes > 0]):
        chosen = np.flatnonzero(sizes == size)
        if size > CV_BLOCK_MAX:
            for g in chosen:
                sums[g] = _fold_ss(blocks, y, root**2, np.flatnonzero(index == g), gram, aty)
            continue
        cells = len(chosen) * int(size) * max(int(size), blocks.width)  # the blocks' and their rows' of A
        for part in np.array_split(chosen, max(1, cells // HAT_CELLS + 1)):
            rows = order[starts[part][:, None] + np.arange(size)[None, :]]  # groups × size
            flat = rows.ravel()
            qg = (blocks.rows(flat, ~same) @ to_q[~same_cols]).reshape(*rows.shape, -1)
            if same.any():
                qg += (blocks.rows(rows[:, 0], same) @ to_q[same_cols])[:, None, :]
            qg *= root[rows][..., None]
            block = np.eye(size) - qg @ np.swapaxes(qg, 1, 2)
            # the block's eigenvalues are 1 - σ²(Q_g) >= 1 - Σ leverages: above CV_RCOND (of at most 1)
            # its pseudo-inverse is its inverse, and a solve does
            plain = (qg**2).sum(axis=(1, 2)) < 1 - CV_RCOND
            sums[part[plain]] = _left_out_ss(block[plain], r[rows[plain]][..., None])
            for g, out in zip(part[~plain], rows[~plain]):
                sums[g] = _fold_ss(blocks, y, root**2, out, gram, aty)
    return sums


def _left_out_ss(block: np.ndarray, rg: np.ndarray) -> np.ndarray:
    """Each group's sum of squared left-out residuals, for groups of one size whose blocks are well
    conditioned (a group whose fold may not determine a direction is refitted instead, _fold_ss):
    (I - H_g)⁻¹ r_g for each group's block I - H_g and residual r_g (µm)."""
    return np.sum(np.linalg.solve(block, rg) ** 2, axis=(1, 2)) if len(block) else np.zeros(0)


def _span(scaled: np.ndarray, largest: float | None = None) -> tuple[np.ndarray, float]:
    """An orthonormal basis of the column-normalised `scaled`'s span, directions whose singular value is
    below CV_RCOND of the largest (`largest`, else its own) left out, from the eigenvectors of its normal
    matrix (as _cv_from_hat); and that largest singular value."""
    eig, vectors = np.linalg.eigh(scaled.T @ scaled)
    sv = np.sqrt(np.maximum(eig, 0.0))
    top = float(sv.max()) if largest is None and len(sv) else (largest or 0.0)
    keep = sv > CV_RCOND * top if len(sv) else np.zeros(0, dtype=bool)
    return scaled @ (vectors[:, keep] / sv[keep]), top


ADDED_SHELF = 48
"""Columns of the terms GrowingFit keeps held in one array (38 MB at 100,000 rows)."""


class GrowingFit:
    """Terms added one at a time beside a fit, each tried without refitting the model: the residual,
    the RSS and the leave-one-group-out CV of the model plus one term come from the current model's
    orthonormal basis Q (n × r) and its hat matrix's diagonal blocks per group (kept), in O(n·r·k) for a
    term of k columns instead of O(n·r²) for a refit and again for its CV. The numbers are those of
    linear_fit and cv_rms_um's hat-matrix route (_cv_from_hat) up to rounding (the new term's part
    outside the model is cut at CV_RCOND of the model's largest singular value, as there). For a dense
    table only: `start` gives None when the groups are few (cv_rms_um refits each fold then) or one is
    above CV_BLOCK_MAX rows."""

    def __init__(self, data: CampaignData, fit: Fit, groups: np.ndarray):
        self.data, self.fit = data, fit
        a = weighted(data, design(data, fit.terms)[0])  # on weighted rows, as linear_fit and cv_rms_um
        self.y = weighted(data, data.y - fixed_deviation(data, fit.terms))
        norms = np.linalg.norm(a, axis=0)
        norms[norms == 0] = 1.0
        self.q, self.largest = _span(a / norms)
        del a
        # the kept terms' bases side by side in shelves of ADDED_SHELF columns, each filled as far as its
        # `used` (not stacked onto q: each would copy it; a product per shelf, not per term: each pass
        # reads n rows; never grown by copying, at most one shelf's columns unused)
        self.shelves: list[tuple[np.ndarray, int]] = []
        self.residual = self.y - self.q @ (self.q.T @ self.y)
        self.rss = float(self.residual @ self.residual)
        self.n_params = fit.n_params
        self.terms = list(fit.terms)
        _, index = np.unique(groups, return_inverse=True)
        order = np.argsort(index, kind="stable")
        sizes = np.bincount(index)
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        self.buckets: list[tuple[np.ndarray, np.ndarray]] = []  # (rows: groups × size, hat blocks)
        for size in np.unique(sizes[sizes > 0]):
            chosen = np.flatnonzero(sizes == size)
            rows = order[starts[chosen][:, None] + np.arange(size)[None, :]]
            hats = np.zeros((len(chosen), size, size))
            step = max(1, 4_000_000 // (int(size) * max(self.q.shape[1], 1)))  # Q's rows gathered a part at a time
            for lo in range(0, len(chosen), step):
                qg = self.q[rows[lo:lo + step]]
                hats[lo:lo + step] = qg @ np.swapaxes(qg, 1, 2)
            self.buckets.append((rows, hats))
        self.cv_um = self._cv(self.residual, [h for _, h in self.buckets], None)

    @classmethod
    def start(cls, data: CampaignData, fit: Fit, groups: np.ndarray) -> GrowingFit | None:
        sizes = np.unique(groups, return_counts=True)[1]
        if len(sizes) <= CV_FOLDS_REFITTED or int(sizes.max()) > CV_BLOCK_MAX:
            return None
        return cls(data, fit, groups)

    def _cv(self, residual: np.ndarray, hats: list[np.ndarray], trying: Term | None) -> float:
        """The leave-one-group-out CV RMS (µm) of the model, plus the term `trying` when given: from each
        group's hat block where it is well conditioned; a group whose fold may not determine a direction
        (a departure at it alone) refitted from the design's blocks (_fold_ss), as _cv_from_hat does:
        a pseudo-inverse of its block drops the residual's part there."""
        total, refit = 0.0, []
        for (rows, _), hat in zip(self.buckets, hats):
            size = rows.shape[1]
            block = np.eye(size) - hat
            plain = np.trace(hat, axis1=1, axis2=2) < 1 - CV_RCOND
            total += float(_left_out_ss(block[plain], residual[rows[plain]][..., None]).sum())
            refit += list(rows[~plain])
        if refit:
            terms = self.terms if trying is None else [*self.terms, trying]
            blocks = Blocks(self.data, terms)
            y = self.data.y - fixed_deviation(self.data, terms)
            root = self.data.row_scale if self.data.row_scale is not None else np.ones(len(y))
            gram, aty = blocks.gram(), blocks.t_times(y)
            total += sum(_fold_ss(blocks, y, root**2, np.sort(out), gram, aty) for out in refit)
        return float(np.sqrt(total / len(residual)))

    def trial(self, term: Term) -> tuple[float, int, float, tuple]:
        """The model plus `term`: its RSS (µm²), number of parameters, leave-one-group-out CV RMS (µm),
        and what `add` needs to keep it."""
        cols = weighted(self.data, term.columns(self.data))
        norms = np.linalg.norm(cols, axis=0)
        norms[norms == 0] = 1.0
        scaled = cols / norms
        # the parts along Q and along the kept bases (orthogonal to Q and to each other), from the rows
        # where the term is not zero alone (a local term's few): their products with the others are zero
        support = np.flatnonzero(scaled.any(axis=1))
        few = 2 * len(support) < len(scaled)
        bases = [self.q, *(shelf[:, :used] for shelf, used in self.shelves)]
        alongs = [b[support].T @ scaled[support] if few else b.T @ scaled for b in bases]
        outside = scaled.copy()
        for b, along_b in zip(bases, alongs):
            outside -= b @ along_b
        qt, _ = _span(outside, self.largest)
        along = qt.T @ self.residual
        residual = self.residual - qt @ along
        hats = []
        for rows, hat in self.buckets:
            tg = qt[rows]
            hats.append(hat + tg @ np.swapaxes(tg, 1, 2))
        rss = float(residual @ residual)
        n_params, cv = self.n_params + cols.shape[1], self._cv(residual, hats, term)
        return rss, n_params, cv, (term, qt, residual, rss, n_params, cv, hats)

    def add(self, kept: tuple) -> None:
        """Keep a term tried (`trial`'s last value) in the model."""
        term, qt, residual, rss, n_params, cv, hats = kept
        if not self.shelves or self.shelves[-1][1] + qt.shape[1] > self.shelves[-1][0].shape[1]:
            self.shelves.append((np.empty((len(qt), max(ADDED_SHELF, qt.shape[1]))), 0))
        shelf, used = self.shelves[-1]
        shelf[:, used:used + qt.shape[1]] = qt
        self.shelves[-1] = (shelf, used + qt.shape[1])
        self.residual, self.rss, self.n_params, self.cv_um = residual, rss, n_params, cv
        self.buckets = [(rows, hat) for (rows, _), hat in zip(self.buckets, hats)]
        self.terms.append(term)

"""The periodogram the period search starts from: for each trial period, how much of the residual a
sine and a cosine of position explain beside the model (the model's span projected out).

Every sum is over the distinct positions (a sine takes one value per position). On fewer than
GRID_POSITIONS positions, or positions at no common step, the sums are taken directly, a block of
frequencies at a time. When the positions lie on a regular grid (a dense plan, a scan binned into
bins; to the 1e-6 mm a point table holds), each sum over positions of a value times a sine is a
discrete Fourier transform of the values on the grid, and the frequencies searched are evenly spaced:
a chirp z-transform gives them all in FFTs about as long as the grid. The two ways give the same
power: to about 1e-13 of the highest on an exact grid (a test holds them to 1e-9 of each other); a
position held to 1e-6 mm is moved to its node, which changes the power by up to about 1e-6 of the
highest (GRID_PHASE_RAD). The second costs n·log n in the positions once per column of the model, not
positions × frequencies × columns (at 25,000 positions and 3,920 frequencies, about 0.03 s for a model
of 5 columns against 0.9 s).

Units: positions and periods mm, frequencies 1/mm, power µm² (weighted).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from campaign.discovery.data import CampaignData
from campaign.discovery.fit import Fit, distinct_rows, searched_periods, span_at_positions, weighted

PERIODOGRAM_CELLS = 1_000_000
"""Rows × frequencies evaluated at a time by the direct sums (8 MB per array: blocks of that size
are reused by the allocator, where 32 MB ones were mapped and zeroed afresh each time, about 1.3 s of
system time and 125 MB of peak at 100,000 rows), and (grid nodes + frequencies) × columns by the chirp
transform (its arrays complex, of about twice that length: some 16 MB each)."""

RECURRENCE_POSITIONS = 1000
"""From this many positions on, sines_cosines steps from one frequency to the next (see there)."""

GRID_POSITIONS = 1000
"""From this many distinct positions on, positions on a regular grid take the FFT's sums."""

GRID_PHASE_RAD = 1e-5
"""Positions lie on a grid when moving each to its node turns no sine it sums by more than this
(radians; a relative change of the power of that order), at twice the highest frequency searched
(sin² and cos² are sums at twice it). A point table holds its targets to 1e-6 mm: at the shortest
period searched, 2 mm, that is 3.1e-6 rad."""

GRID_SPARSENESS = 4
"""The grid is used only when it has at most this many nodes per distinct position (a few positions
far apart at a fine common step would make a long grid for nothing)."""

FREQUENCIES_PER_TRAVEL = 8
"""The frequency step is 1 / (this × the travel): a peak's width is 1 / travel."""


def independent_periods(data: CampaignData) -> float:
    """About how many independent periods the periodogram tries (for the look-elsewhere effect)."""
    low, high = searched_periods(data)
    return max(1.0, float(np.ptp(data.x)) * (1 / low - 1 / high))


def periodogram_periods(data: CampaignData, fit: Fit, top: int = 3) -> list[float]:
    """Periods (mm) where a sine of the residual, fitted beside the model, explains most: the `top`
    highest local maxima of the power over the plausible screw leads (periodogram_power)."""
    freqs, power = periodogram_power(data, fit)
    peaks = [i for i in range(len(power)) if power[i] > 0 and (i == 0 or power[i] >= power[i - 1])
             and (i == len(power) - 1 or power[i] >= power[i + 1])]
    peaks.sort(key=lambda i: -power[i])
    return [float(1 / freqs[i]) for i in peaks[:top]]


def periodogram_power(data: CampaignData, fit: Fit) -> tuple[np.ndarray, np.ndarray]:
    """The frequencies searched (1/mm, from the longest plausible period to the shortest) and, at
    each, the decrease of the weighted residual sum of squares (µm²) when a sine and a cosine of that
    frequency are fitted beside the model: a Lomb-Scargle-like periodogram with the model projected
    out."""
    low, high = searched_periods(data)
    travel = float(np.ptp(data.x)) or 1.0
    freqs = np.arange(1 / high, 1 / low, 1 / (FREQUENCIES_PER_TRAVEL * travel))
    r = weighted(data, data.y - fit.prediction)
    # a sine of x takes one value per distinct position: every sum below is over those, with the
    # residual's and the basis's sums there (exactly the sums over the weighted rows: a row's sine
    # is its weight's square root, `root`, times the sine at its position)
    first, where = distinct_rows(data)
    xs = data.x[first]
    root = data.row_scale if data.row_scale is not None else np.ones(len(data))
    count = np.bincount(where, root**2)
    r_at = np.bincount(where, root * r)
    q_at, qr = span_at_positions(data, fit, where, len(xs))
    grid = on_grid(xs, 2 * float(freqs[-1]) if len(freqs) else 0.0)
    if grid is not None and len(freqs):
        nodes, step = grid
        dft_length = FREQUENCIES_PER_TRAVEL * int(nodes[-1])  # nodes: 8 travels give the frequency step
        freqs = freqs[0] + np.arange(len(freqs)) / (dft_length * step)  # the same, to rounding
        sums = _grid_sums(nodes, step, dft_length, freqs[0], len(freqs), count, r_at, q_at, qr)
    else:
        sums = _direct_sums(xs, freqs, count, r_at, q_at, qr)
    power = np.zeros(len(freqs))
    det = sums.ss * sums.cc - sums.sc**2
    ok = det > 1e-9 * np.maximum(sums.ss * sums.cc, 1e-300)
    power[ok] = (sums.cc * sums.rs**2 - 2 * sums.sc * sums.rs * sums.rc + sums.ss * sums.rc**2)[ok] / det[ok]
    return freqs, power


class Sums(NamedTuple):
    """Per frequency, with s and c the sine and cosine columns, r the weighted residual and Q the
    model's orthonormal basis: each product with its part in the model's span taken away."""

    ss: np.ndarray  # sᵀs − (Qᵀs)ᵀ(Qᵀs)
    cc: np.ndarray  # cᵀc − (Qᵀc)ᵀ(Qᵀc)
    sc: np.ndarray  # sᵀc − (Qᵀs)ᵀ(Qᵀc)
    rs: np.ndarray  # sᵀr − (Qᵀr)ᵀ(Qᵀs)
    rc: np.ndarray  # cᵀr − (Qᵀr)ᵀ(Qᵀc)


def _direct_sums(xs: np.ndarray, freqs: np.ndarray, count: np.ndarray, r_at: np.ndarray, q_at: np.ndarray,
                 qr: np.ndarray) -> Sums:
    """The sums by evaluating every sine: a block of frequencies at a time (memory linear in the
    positions)."""
    out = np.zeros((5, len(freqs)))
    block = max(1, PERIODOGRAM_CELLS // max(len(xs), 1))
    for lo in range(0, len(freqs), block):
        s, c = sines_cosines(xs, freqs[lo:lo + block])
        # Q'·(column): the part in the model's span (as (columnᵀ·Q)ᵀ: BLAS is many times faster so)
        qs, qc = (s @ q_at).T, (c @ q_at).T
        part = out[:, lo:lo + block]
        part[0] = (s * s) @ count - (qs * qs).sum(0)
        part[1] = (c * c) @ count - (qc * qc).sum(0)
        part[2] = (s * c) @ count - (qs * qc).sum(0)
        part[3] = s @ r_at - qr @ qs
        part[4] = c @ r_at - qr @ qc
    return Sums(*out)


def on_grid(xs: np.ndarray, top_frequency: float) -> tuple[np.ndarray, float] | None:
    """For sorted distinct positions (mm) on a regular grid: each one's node (an integer, the first
    at 0) and the grid's step (mm). None for fewer than GRID_POSITIONS positions, for positions that
    a node is too far from (its sine at `top_frequency`, 1/mm, would turn by more than GRID_PHASE_RAD)
    and for a grid with more than GRID_SPARSENESS nodes per position. The step is the smallest gap's:
    positions at a common step whose gaps are all two steps or more (2 and 3 steps, say) take the
    direct sums, as do gaps so long that a gap's rounding errs by half a step (about 20,000 steps at
    1e-6 mm in 0.04 mm): correct either way, only slower."""
    if len(xs) < GRID_POSITIONS:
        return None
    gaps = np.diff(xs)
    # each gap in whole steps (the smallest gap's: a position's rounding errs it by a part in 10⁵,
    # too much to count 50,000 steps from the first position at once), then the step from the travel
    whole = np.concatenate([[0.0], np.cumsum(np.round(gaps / float(np.min(gaps))))])
    step = float(xs[-1] - xs[0]) / float(whole[-1])
    off = float(np.max(np.abs(xs - xs[0] - step * whole)))  # mm
    if 2 * np.pi * top_frequency * off > GRID_PHASE_RAD or whole[-1] > GRID_SPARSENESS * len(xs):
        return None
    return whole.astype(np.int64), step


def _grid_sums(nodes: np.ndarray, step: float, dft_length: int, f0: float, frequencies: int, count: np.ndarray,
               r_at: np.ndarray, q_at: np.ndarray, qr: np.ndarray) -> Sums:
    """The sums at the frequencies f0 + k / (dft_length · step), k < `frequencies` (1/mm; `step` mm, the
    grid's; chirp_dft of the values on the grid). Positions are measured from the first: the power does not depend on the origin (a shift
    only turns each frequency's sine and cosine into each other). sin² and cos² and sin·cos are
    halves of 1 and of the cosine and sine at twice the frequency."""
    def transform(values: np.ndarray, multiple: int) -> np.ndarray:
        """Σ values · exp(−2πi · multiple · f_k · x) over the positions, for every k (values: positions ×
        columns; the result frequencies × columns)."""
        placed = np.zeros((int(nodes[-1]) + 1, values.shape[1]))
        placed[nodes] = values
        return chirp_dft(placed, frequencies, multiple * f0 * step, multiple, dft_length)

    # Σ v·exp(−iθ) = Σ v·cos θ − i Σ v·sin θ
    doubled = transform(count[:, None], 2)[:, 0]
    total = float(count.sum())
    ss, cc, sc = (total - doubled.real) / 2, (total + doubled.real) / 2, -doubled.imag / 2
    at_r = transform(r_at[:, None], 1)[:, 0]
    rs, rc = -at_r.imag, at_r.real.copy()
    block = max(1, PERIODOGRAM_CELLS // (int(nodes[-1]) + 1 + frequencies))
    for lo in range(0, q_at.shape[1], block):
        at_q = transform(q_at[:, lo:lo + block], 1)
        qs, qc = -at_q.imag, at_q.real
        ss -= (qs * qs).sum(1)
        cc -= (qc * qc).sum(1)
        sc -= (qs * qc).sum(1)
        rs -= qs @ qr[lo:lo + block]
        rc -= qc @ qr[lo:lo + block]
    return Sums(ss, cc, sc, rs, rc)


def chirp_dft(values: np.ndarray, outputs: int, start: float, stride: int, length: int) -> np.ndarray:
    """X[k] = Σₙ values[n] · exp(−2πi · n · (start + k · stride / length)), k < outputs, for each
    column of `values` (nodes × columns): a discrete Fourier transform at `outputs` evenly spaced
    frequencies alone (Bluestein's chirp z-transform: n·k = (n² + k² − (k − n)²) / 2 makes it a
    convolution, taken by FFTs of about nodes + outputs points, where a plain FFT would need
    `length` points to reach the frequency step). The chirp's phases are reduced modulo 2π in
    integers, so they stay exact however long the grid (a chirp of float k² loses about 1e-9 of the
    sums at 100,000 nodes)."""
    from scipy import fft  # (loaded already by scipy.optimize: no import time of its own)

    nodes = values.shape[0]
    size = fft.next_fast_len(nodes + outputs - 1)

    def chirp(m: np.ndarray) -> np.ndarray:  # exp(−πi · stride · m² / length), m whole
        return np.exp(-1j * np.pi * ((stride * m * m) % (2 * length)) / length)

    n = np.arange(nodes, dtype=np.int64)
    taken = fft.fft(values * (np.exp(-2j * np.pi * start * n) * chirp(n))[:, None], size, axis=0)
    spread = np.zeros(size, complex)
    spread[:outputs] = np.conj(chirp(np.arange(outputs, dtype=np.int64)))
    spread[size - nodes + 1:] = np.conj(chirp(np.arange(-(nodes - 1), 0, dtype=np.int64)))
    convolved = fft.ifft(taken * fft.fft(spread)[:, None], axis=0)[:outputs]
    return np.asarray(chirp(np.arange(outputs, dtype=np.int64))[:, None] * convolved)


def sines_cosines(x: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sin(2π·f·x) and cos(2π·f·x) (frequencies × positions) for positions x (mm) and evenly spaced
    frequencies f (1/mm): the first row from sin and cos, each next by the angle-addition rule with
    the step's sine and cosine (a multiply-add per cell: a sine and a cosine of every cell cost three
    times as much; the rounding grows by about 1e-13 per row, nothing beside a periodogram's power).
    Below RECURRENCE_POSITIONS positions a row is too short to pay for its four calls: sin and cos
    of every cell there."""
    if len(x) < RECURRENCE_POSITIONS:
        angle = 2 * np.pi * np.outer(f, x)
        return np.sin(angle), np.cos(angle)
    s, c = np.empty((len(f), len(x))), np.empty((len(f), len(x)))
    np.sin(2 * np.pi * f[0] * x, out=s[0])
    np.cos(2 * np.pi * f[0] * x, out=c[0])
    if len(f) > 1:
        step = 2 * np.pi * (f[1] - f[0]) * x
        sin_step, cos_step, part = np.sin(step), np.cos(step), np.empty(len(x))
        for k in range(1, len(f)):
            np.multiply(s[k - 1], cos_step, out=s[k])
            s[k] += np.multiply(c[k - 1], sin_step, out=part)
            np.multiply(c[k - 1], cos_step, out=c[k])
            c[k] -= np.multiply(s[k - 1], sin_step, out=part)
    return s, c

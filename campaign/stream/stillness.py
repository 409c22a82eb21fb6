"""How still a reading is over a window: a straight line fitted through the window's readings.

The trend is the change of the fitted line from the window's first sample to its last (axis unit);
the window's scatter is the standard deviation of its readings about the line (axis unit). Whether
the window still trends is judged against the log's noise (`log_noise`, one value for the log,
from successive samples), not the window's own scatter, which grows when something moves within
the window (a move beginning in its last samples). A window still trends when its trend is beyond
that noise: larger than STILL_SE standard errors of the trend that noise gives (noise alone does
so for about one window in 16 000) and larger than the noise itself (a trend below the scatter of
single readings moves the window's mean by less than half that scatter, however many samples
there are).

Used by the stream import to find where a dwell's reading stops approaching and to report how
still each capture window was.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STILL_SE = 4.0
"""Standard errors of its trend beyond which a window still trends (see the module text)."""

MIN_SAMPLES = 4
"""The fewest samples a line is fitted through (two for the line, two more for its noise)."""


@dataclass
class LineFits:
    """Line fits over windows: trend and scatter about the line (axis unit), and the lever that
    turns a reading noise into the trend's standard error (span / √(Σ(t - mean t)²), no unit)."""

    trend: np.ndarray
    scatter: np.ndarray
    lever: np.ndarray

    def still(self, noise: float) -> np.ndarray:
        """True where the window does not trend beyond `noise` (axis unit; see the module text)."""
        return np.abs(self.trend) <= np.maximum(STILL_SE * noise * self.lever, noise)


def log_noise(reading: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """The reading noise of a log (axis unit), one value: from the second differences of the
    readings in [lo, hi) (an evenly spaced white noise σ gives them σ·√6; a steady creep adds
    little), 1.4826 · their median absolute deviation / √6, up to NOISE_SAMPLES spread evenly."""
    picks = [np.arange(a + 1, b - 1, max(1, (b - a) // max(1, NOISE_SAMPLES // max(len(lo), 1))))
             for a, b in zip(lo.tolist(), hi.tolist(), strict=True) if b - a >= 3]
    if not picks:
        return 0.0
    i = np.concatenate(picks)
    second = reading[i + 1] - 2 * reading[i] + reading[i - 1]
    mad = float(np.median(np.abs(second - np.median(second))))
    spread = 1.4826 * mad if mad > 0 else float(np.std(second))  # readings coarser than their noise
    return spread / np.sqrt(6)


NOISE_SAMPLES = 200_000
"""About how many second differences `log_noise` takes from a log."""


def _fits(t_span: np.ndarray, n: np.ndarray, t_sum: np.ndarray, tt_sum: np.ndarray,
          x_sum: np.ndarray, xx_sum: np.ndarray, tx_sum: np.ndarray) -> LineFits:
    """Line fits from each window's sample count, time span (s) and sums of t, t², x, x², t·x."""
    with np.errstate(all="ignore"):
        t_ss = tt_sum - t_sum**2 / n  # s², about the window's mean time
        tx = tx_sum - t_sum * x_sum / n
        x_ss = xx_sum - x_sum**2 / n
        slope = np.where(t_ss > 0, tx / t_ss, 0.0)  # axis unit / s
        scatter = np.sqrt(np.maximum(x_ss - slope * tx, 0.0) / np.maximum(n - 2, 1))
        lever = np.where(t_ss > 0, t_span / np.sqrt(t_ss), np.inf)
    return LineFits(slope * t_span, scatter, lever)


def line_fit(time: np.ndarray, reading: np.ndarray) -> LineFits:
    """The line fitted through one window (a LineFits of one; no trend for fewer than two samples)."""
    t = time - time[0]  # s; centred so that the sums keep their precision
    x = reading - reading[0]

    def one(v: np.ndarray) -> np.ndarray:
        return np.array([float(np.sum(v))])

    return _fits(np.array([t[-1]]), np.array([float(len(t))]), one(t), one(t * t), one(x), one(x * x),
                 one(t * x))


def sliding_fits(time: np.ndarray, reading: np.ndarray, samples: int) -> tuple[LineFits, int]:
    """Line fits over windows of about `samples` consecutive samples, a sixteenth of a window
    apart: (the fits, that step in samples); window p is [p · step, p · step + the window)."""
    step = max(1, samples // SLIDES)
    blocks = len(reading) // step
    per_window = max(samples // step, 1)
    if blocks < per_window:
        return LineFits(np.zeros(0), np.zeros(0), np.zeros(0)), step
    t = time[:blocks * step] - time[0]
    x = reading[:blocks * step] - reading[0]

    def windows(v: np.ndarray) -> np.ndarray:
        sums = np.concatenate([[0.0], np.cumsum(v.reshape(blocks, step).sum(axis=1))])
        return sums[per_window:] - sums[:-per_window]

    first = np.arange(blocks - per_window + 1) * step
    span = t[first + per_window * step - 1] - t[first]
    n = np.full(len(first), float(per_window * step))
    return _fits(span, n, windows(t), windows(t * t), windows(x), windows(x * x), windows(t * x)), step


SLIDES = 16
"""Steps per window by which the still search slides its window along a dwell."""


def window_fits(time: np.ndarray, reading: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> LineFits:
    """The line fitted through reading[lo:hi] for each pair."""
    fits = [line_fit(time[a:b], reading[a:b]) for a, b in zip(lo.tolist(), hi.tolist(), strict=True)]
    return LineFits(*(np.concatenate([getattr(f, name) for f in fits]) if fits else np.zeros(0)
                      for name in ("trend", "scatter", "lever")))

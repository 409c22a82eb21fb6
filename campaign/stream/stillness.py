"""How still a reading is over a window: a straight line fitted through the window's readings.

The trend is the change of the fitted line from the window's first sample to its last (axis unit),
the noise the standard deviation of the readings about the line (axis unit), and the trend's
standard error follows from the noise and the sample times. A window still trends when its trend
is beyond the noise: larger than STILL_SE standard errors (noise alone does so for about one
window in 16 000) and larger than the noise itself (a trend below the scatter of single readings
moves the window's mean by less than half that scatter, however many samples there are).

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
    """Line fits over windows: trend and noise in axis unit, the trend's standard error (axis unit)."""

    trend: np.ndarray
    noise: np.ndarray
    trend_se: np.ndarray

    @property
    def still(self) -> np.ndarray:
        """True where the window does not trend beyond the noise."""
        return np.abs(self.trend) <= np.maximum(STILL_SE * self.trend_se, self.noise)


def _fits(t_span: np.ndarray, n: np.ndarray, t_sum: np.ndarray, tt_sum: np.ndarray,
          x_sum: np.ndarray, xx_sum: np.ndarray, tx_sum: np.ndarray) -> LineFits:
    """Line fits from each window's sample count, time span (s) and sums of t, t², x, x², t·x."""
    with np.errstate(all="ignore"):
        t_ss = tt_sum - t_sum**2 / n  # s², about the window's mean time
        tx = tx_sum - t_sum * x_sum / n
        x_ss = xx_sum - x_sum**2 / n
        slope = np.where(t_ss > 0, tx / t_ss, 0.0)  # axis unit / s
        noise = np.sqrt(np.maximum(x_ss - slope * tx, 0.0) / np.maximum(n - 2, 1))
        trend_se = np.where(t_ss > 0, noise * t_span / np.sqrt(t_ss), np.inf)
    return LineFits(slope * t_span, noise, trend_se)


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
                      for name in ("trend", "noise", "trend_se")))

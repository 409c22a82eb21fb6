"""Adaptive refinement: where linear interpolation between the targets cannot follow the mean
deviation, propose extra targets for a follow-up campaign.

Between two targets the table interpolates linearly. A function with second difference d2 over a
spacing (d2 = x̄[i-1] - 2 x̄[i] + x̄[i+1]) is missed by up to |d2|/8 between targets. Each interval
gets the larger estimate of its two ends, for the worse direction. Where that exceeds the
threshold (default: the pooled s, i.e. a quarter of the repeatability), the interval is split into
k+1 equal parts with the smallest k that brings the estimate (which falls as 1/(k+1)²) under the
threshold, at most `max_per_interval` new targets. Deviations in µm (arcsec), positions in axis
unit.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from campaign.iso230 import evaluate
from campaign.pointtable import PointTable


@dataclass
class Proposal:
    """targets: the original ones; new: the proposed ones; gaps: per interval (start, end,
    estimated interpolation error, new targets in it); threshold in deviation unit."""

    targets: list[float]
    new: list[float]
    gaps: list[tuple[float, float, float, int]]
    threshold: float

    @property
    def all_targets(self) -> list[float]:
        return sorted(set(self.targets) | set(self.new))


def interpolation_error(targets: np.ndarray, means: np.ndarray) -> np.ndarray:
    """Estimated worst linear-interpolation error per interval, deviation unit (len = targets-1).
    Non-uniform spacing: second divided differences scaled to each interval's length."""
    if len(targets) < 3:
        return np.zeros(max(len(targets) - 1, 0))
    h = np.diff(targets)
    slopes = np.diff(means) / h
    curvature = 2 * np.diff(slopes) / (h[:-1] + h[1:])  # f'' at the inner targets
    ends = np.abs(np.concatenate([[curvature[0]], curvature, [curvature[-1]]]))
    per_interval = np.maximum(ends[:-1], ends[1:])
    return per_interval * h**2 / 8


def propose(table: PointTable, threshold: float | None = None, max_per_interval: int = 3) -> Proposal:
    ev = evaluate(table)
    targets = np.array([t.target for t in ev.targets])
    sds = [s for t in ev.targets for s in (t.s_up, t.s_down) if s is not None]
    if threshold is None:
        threshold = float(np.sqrt(np.mean(np.square(sds)))) if sds else 0.0
    errors = np.zeros(len(targets) - 1)
    for suffix in ("up", "down"):
        means = [getattr(t, f"mean_{suffix}") for t in ev.targets]
        if all(m is not None for m in means):
            errors = np.maximum(errors, interpolation_error(targets, np.array(means)))
    new, gaps = [], []
    for i, err in enumerate(errors):
        k = 0
        if threshold > 0 and err > threshold:
            k = min(max_per_interval, math.ceil(math.sqrt(err / threshold)) - 1)
            k = max(k, 1)
        step = (targets[i + 1] - targets[i]) / (k + 1)
        added = [round(float(targets[i] + step * j), 6) for j in range(1, k + 1)]
        new += added
        gaps.append((float(targets[i]), float(targets[i + 1]), float(err), len(added)))
    return Proposal([float(t) for t in targets], new, gaps, float(threshold))


def follow_up_config(text: str, targets: list[float]) -> str:
    """The config text with [plan] measuring exactly `targets` (length/count/offsets removed)."""
    out, section, done = [], "", False
    for line in text.splitlines():
        header = re.match(r"\s*\[([^\]]+)\]", line)
        if header:
            if section == "plan" and not done:
                out.append(_targets_line(targets))
                done = True
            section = header.group(1).strip()
        elif section == "plan" and re.match(r"\s*(targets|start|length|count|offsets|offset_fraction)\s*=", line):
            continue
        out.append(line)
    if section == "plan" and not done:
        out.append(_targets_line(targets))
    elif not done:
        out += ["[plan]", _targets_line(targets)]
    return "\n".join(out) + "\n"


def _targets_line(targets: list[float]) -> str:
    return "targets = [" + ", ".join(repr(float(t)) for t in targets) + "]  # refined by axiscal refine"

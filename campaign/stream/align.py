"""Time alignment of a scan: the instrument's clock against the controller's, from the data.

A scan records two streams on two clocks: the controller's actual position at each PLC cycle,
stamped by the controller, and the interferometer's readings, stamped by the instrument's own
clock. The instrument clock is off by an unknown offset (tens of ms: the clocks were never set
together, and any constant delay inside either device adds to it) and runs at a slightly different
rate (tens of ppm). At 10 mm/s one millisecond is 10 µm, so the offset and the rate must be known
to microseconds before a deviation is computed.

Neither is measured separately: both come from the passes. Where the axis moves at a constant
velocity v, a timing error e shifts the deviation by v·e, the same at every position of a pass
in one direction, which a reversal value would also do. Where the axis accelerates (at each end of
each pass) the velocity runs from 0 to v over a fraction of a millimetre, in which the machine's
error hardly changes: there the deviation changes by e·Δv, and only a timing error does that. So:

1. coarse: each full move is found in both streams; the instant each crosses its middle gives one
   (controller time, instrument time) pair per move, and a line through them the first offset and
   rate (good to about deviation/velocity, a millisecond);
2. fine: in every acceleration ramp and the stretch of cruise beside it (as long as the ramp),
   the residual (reading − controller position at the mapped time) is fitted by a constant for
   the ramp, another for the cruise (an acceleration may deflect the machine) and one slope in
   position for both (the machine's error changing along the ramp; the cruise, where a timing
   error is only a constant, fixes it) plus v·(α + β·(t − t_ref)): α corrects the offset, β the
   rate. Iterated until the
   corrections vanish; the covariance of (α, β), scaled by the residuals, is the uncertainty;
3. wander: each ramp alone also gives its own offset; their scatter about the line beyond their own
   uncertainty is clock wander the line cannot follow, added to the uncertainty.

What it cannot separate: a deviation proportional to velocity (a viscous wind-up of the drive
train) looks exactly like a clock offset and is folded into it; that is then removed from the
scan's deviations too.

Times in s (controller clock unless named), positions in the axis unit (mm or deg).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from campaign.errors import InputError


@dataclass(frozen=True)
class ControllerStream:
    """The controller's actual position (axis unit) at its own times (s), increasing."""

    time_s: np.ndarray
    position: np.ndarray


@dataclass(frozen=True)
class InstrumentStream:
    """The instrument's readings (axis unit) at its own clock's stamps (s)."""

    time_s: np.ndarray
    reading: np.ndarray


@dataclass(frozen=True)
class Move:
    """One move in the controller's stream: start and end (s), start and end position (axis unit),
    cruise speed (axis unit/s, > 0), direction (+1/-1), and its two acceleration ramps (start, end s)."""

    start_s: float
    end_s: float
    start_position: float
    end_position: float
    speed: float
    direction: int
    ramps: tuple[tuple[float, float], tuple[float, float]]


@dataclass(frozen=True)
class Alignment:
    """controller time = a + b · instrument time (s). t_ref_s: the controller time the uncertainty
    is centred on (the middle of the ramps). covariance: of the offset at t_ref (s) and of β (the
    relative rate), from the ramps' fit. wander_s: RMS timing scatter of single ramps about the line
    beyond their own uncertainty, s. ramps: how many ramps were fitted; residual: RMS of the fit's
    residuals, axis unit; iterations: how many refinements it took."""

    a: float
    b: float
    t_ref_s: float
    covariance: tuple[tuple[float, float], tuple[float, float]]
    wander_s: float
    ramps: int
    residual: float
    iterations: int

    def controller_time(self, instrument_time: np.ndarray | float) -> np.ndarray:
        return self.a + self.b * np.asarray(instrument_time, dtype=float)

    @property
    def offset_s(self) -> float:
        """Instrument clock minus controller clock at t_ref, s."""
        return float((self.t_ref_s - self.a) / self.b - self.t_ref_s)

    @property
    def rate_error_ppm(self) -> float:
        """How much faster the instrument clock runs, ppm."""
        return (1.0 / self.b - 1.0) * 1e6

    @property
    def offset_uncertainty_s(self) -> float:
        """Standard uncertainty of the offset at t_ref (fit only), s."""
        return math.sqrt(self.covariance[0][0])

    @property
    def rate_uncertainty_ppm(self) -> float:
        return math.sqrt(self.covariance[1][1]) * 1e6

    def timing_uncertainty_s(self, t: np.ndarray | float) -> np.ndarray:
        """Standard uncertainty of the mapped time at controller time t (s): the fit's offset and
        rate, and the wander."""
        dt = np.asarray(t, dtype=float) - self.t_ref_s
        (c00, c01), (_, c11) = self.covariance
        return np.sqrt(np.maximum(c00 + 2 * dt * c01 + dt * dt * c11, 0.0) + self.wander_s**2)

    def as_dict(self) -> dict[str, float | int]:
        return {"offset_ms": round(self.offset_s * 1e3, 6),
                "offset_uncertainty_ms": round(self.offset_uncertainty_s * 1e3, 6),
                "rate_error_ppm": round(self.rate_error_ppm, 4),
                "rate_uncertainty_ppm": round(self.rate_uncertainty_ppm, 4),
                "wander_ms": round(self.wander_s * 1e3, 6), "ramps": self.ramps,
                "t_ref_s": round(self.t_ref_s, 3)}


def velocity(stream: ControllerStream) -> np.ndarray:
    """The controller's velocity at its samples (axis unit/s), by central differences."""
    if len(stream.time_s) < 3:
        raise InputError("the controller stream has fewer than 3 samples")
    return np.gradient(stream.position, stream.time_s)


def find_moves(stream: ControllerStream, min_fraction: float = 0.5) -> list[Move]:
    """The moves of the controller stream that cover at least `min_fraction` of the longest one
    (the scan's passes; a short positioning move is left out)."""
    t, x = stream.time_s, stream.position
    if np.any(np.diff(t) <= 0):
        raise InputError("the controller stream's times must increase")
    step = np.abs(np.diff(x))
    still = 1e-9 * max(1.0, float(np.max(np.abs(x))))  # a step of float rounding is no motion
    moving = np.concatenate([[False], step > still, [False]])
    edges = np.flatnonzero(np.diff(moving.astype(int)))
    runs = list(zip(edges[::2], edges[1::2]))  # sample i..j-1 moved towards i+1..j
    spans = [(i, j) for i, j in runs if j > i]
    if not spans:
        raise InputError("the controller stream shows no motion")
    longest = max(abs(x[j] - x[i]) for i, j in spans)
    v = velocity(stream)
    moves = []
    for i, j in spans:
        if abs(x[j] - x[i]) < min_fraction * longest:
            continue
        speed = float(np.max(np.abs(v[i:j + 1])))
        inside = np.flatnonzero(np.abs(v[i:j + 1]) >= 0.999 * speed) + i
        if len(inside) < 2:
            continue
        cruise_from, cruise_to = int(inside[0]), int(inside[-1])
        moves.append(Move(float(t[i]), float(t[j]), float(x[i]), float(x[j]), speed, 1 if x[j] > x[i] else -1,
                          ((float(t[i]), float(t[cruise_from])), (float(t[cruise_to]), float(t[j])))))
    if not moves:
        raise InputError("the controller stream shows no move at a constant velocity")
    return moves


def _instrument_moves(inst: InstrumentStream, moves: list[Move]) -> list[tuple[int, int]]:
    """The index ranges of the instrument stream where it shows each of `moves`, in order: where
    the reading travels monotonically over most of each move's distance."""
    r, t = inst.reading, inst.time_s
    found: list[tuple[int, int]] = []
    start = 0
    for m in moves:
        low, high = sorted((m.start_position, m.end_position))
        span = high - low
        inside = (r > low + 0.25 * span) & (r < high - 0.25 * span)
        idx = np.flatnonzero(inside[start:]) + start
        if len(idx) == 0:
            raise InputError(f"the instrument stream does not show the move from {m.start_position:g} to "
                             f"{m.end_position:g} (controller time {m.start_s:.3f} s)")
        gaps = np.flatnonzero(np.diff(idx) > 1)
        first_end = int(idx[gaps[0]]) if len(gaps) else int(idx[-1])
        i, j = int(idx[0]), first_end
        if (r[j] - r[i]) * m.direction <= 0 or t[j] <= t[i]:
            raise InputError(f"the instrument stream does not move like the controller at its move "
                             f"from {m.start_position:g} to {m.end_position:g}")
        found.append((i, j))
        start = j + 1
    return found


def coarse_alignment(ctrl: ControllerStream, inst: InstrumentStream, moves: list[Move],
                     rate: bool = True) -> tuple[float, float]:
    """(a, b) of controller time = a + b · instrument time, from the instants each move crosses its
    middle in both streams (`rate` False: b = 1, the clocks taken to run at the same rate)."""
    pairs = []
    for m, (i, j) in zip(moves, _instrument_moves(inst, moves)):
        middle = (m.start_position + m.end_position) / 2
        sel = (ctrl.time_s >= m.start_s) & (ctrl.time_s <= m.end_s)
        tc = float(np.interp(middle * m.direction, ctrl.position[sel] * m.direction, ctrl.time_s[sel]))
        r, ti = inst.reading[i:j + 1], inst.time_s[i:j + 1]
        order = np.argsort(r * m.direction, kind="stable")
        tau = float(np.interp(middle * m.direction, (r * m.direction)[order], ti[order]))
        pairs.append((tc, tau))
    p = np.array(pairs)
    if len(p) == 1 or not rate:
        return float(np.mean(p[:, 0] - p[:, 1])), 1.0
    b, a = np.polyfit(p[:, 1], p[:, 0], 1)
    return float(a), float(b)


def _ramp_samples(moves: list[Move], t_mapped: np.ndarray,
                  cycle_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The instrument samples (mapped to controller time) each ramp's fit uses: those inside the
    ramp, at least one PLC cycle from its ends, and those of the cruise beside it (after an
    acceleration, before a deceleration) over as long a distance as the ramp's. Returns their
    indices, the ramp each belongs to, and whether each is in the cruise."""
    index, ramp, cruise = [], [], []
    k = 0
    for m in moves:
        for side, (t0, t1) in enumerate(m.ramps):
            inside = np.flatnonzero((t_mapped > t0 + cycle_s) & (t_mapped < t1 - cycle_s))
            beside_s = max((t1 - t0) / 2, 4 * cycle_s)  # a ramp from rest covers v·(t1 - t0)/2
            if side == 0:
                beside = np.flatnonzero((t_mapped > t1 + cycle_s) & (t_mapped < t1 + cycle_s + beside_s))
            else:
                beside = np.flatnonzero((t_mapped > t0 - cycle_s - beside_s) & (t_mapped < t0 - cycle_s))
            if len(inside) >= 2 and len(beside) >= 2:
                index += [inside, beside]
                ramp += [np.full(len(inside), k), np.full(len(beside), k)]
                cruise += [np.zeros(len(inside), bool), np.ones(len(beside), bool)]
                k += 1
    if not index:
        return np.array([], dtype=int), np.array([], dtype=int), np.array([], dtype=bool)
    return np.concatenate(index), np.concatenate(ramp), np.concatenate(cruise)


def in_order(inst: InstrumentStream) -> InstrumentStream:
    """The instrument's samples in the order taken (not as they arrived), without those that have
    no reading (beam lost: NaN)."""
    keep = np.isfinite(inst.time_s) & np.isfinite(inst.reading)
    t, r = inst.time_s[keep], inst.reading[keep]
    order = np.argsort(t, kind="stable")
    return InstrumentStream(t[order], r[order])


def align(ctrl: ControllerStream, inst: InstrumentStream, max_iterations: int = 20, rate: bool = True) -> Alignment:
    """The instrument clock against the controller's, from the scan's own moves (module docstring).
    `rate` False: the offset only, the clocks taken to run at the same rate (to see what the rate
    estimate changes: `axiscal replay --offset-only`)."""
    inst = in_order(inst)
    if len(inst.time_s) < 10:
        raise InputError("the instrument stream has fewer than 10 samples with a reading")
    moves = find_moves(ctrl)
    cycle = float(np.median(np.diff(ctrl.time_s)))
    v_ctrl = velocity(ctrl)
    a, b = coarse_alignment(ctrl, inst, moves, rate)
    t_ref = float(np.mean([np.mean(r) for m in moves for r in m.ramps]))
    cov = ((math.inf, 0.0), (0.0, math.inf))
    residual, iterations = math.nan, 0
    per_ramp: list[tuple[float, float]] = []
    for iterations in range(1, max_iterations + 1):
        t = a + b * inst.time_s
        idx, ramp, cruise = _ramp_samples(moves, t, cycle)
        n_ramps = int(ramp.max()) + 1 if len(ramp) else 0
        if n_ramps < 2 or len(idx) < 3 * n_ramps + 4:
            raise InputError("too few instrument samples in the acceleration ramps to align the clocks "
                             "(a higher instrument rate or a lower acceleration gives more)")
        ti = t[idx]
        x = np.interp(ti, ctrl.time_s, ctrl.position)
        r = inst.reading[idx] - x
        v = np.interp(ti, ctrl.time_s, v_ctrl)
        # per ramp: its own constant, the cruise beside it its own, one slope in position for both
        design = np.zeros((len(idx), 3 * n_ramps + (2 if rate else 1)))
        rows = np.arange(len(idx))
        design[rows, ramp + n_ramps * cruise] = 1.0
        centre = np.array([np.mean(x[ramp == k]) for k in range(n_ramps)])
        design[rows, 2 * n_ramps + ramp] = x - centre[ramp]
        col = 3 * n_ramps
        design[:, col] = v
        if rate:
            design[:, col + 1] = v * (ti - t_ref)
        coef, *_ = np.linalg.lstsq(design, r, rcond=None)
        fit_residual = r - design @ coef
        dof = max(len(idx) - design.shape[1], 1)
        sigma2 = float(fit_residual @ fit_residual) / dof
        inv = np.linalg.pinv(design.T @ design)
        alpha = float(coef[col])
        beta = float(coef[col + 1]) if rate else 0.0
        cov = (((sigma2 * inv[col, col], sigma2 * inv[col, col + 1]),
                (sigma2 * inv[col + 1, col], sigma2 * inv[col + 1, col + 1])) if rate else
               ((sigma2 * inv[col, col], 0.0), (0.0, 0.0)))
        residual = math.sqrt(sigma2)
        # true controller time = t + alpha + beta (t - t_ref)
        a, b = (1 + beta) * a + alpha - beta * t_ref, (1 + beta) * b
        span = float(np.ptp(ti))
        per_ramp = _per_ramp_offsets(ramp, fit_residual, v, x, cruise)
        if abs(alpha) < 1e-9 and abs(beta) * span < 1e-9:
            break
    wander = _wander(per_ramp)
    return Alignment(a, b, t_ref, cov, wander, len(per_ramp), residual, iterations)


def _per_ramp_offsets(ramp: np.ndarray, residual: np.ndarray, v: np.ndarray, x: np.ndarray,
                      cruise: np.ndarray) -> list[tuple[float, float]]:
    """Each ramp's own timing error about the fitted line and its standard uncertainty (s): the
    line's residuals in that ramp and its cruise fitted like the whole (a constant each, one slope)
    plus v·e."""
    out = []
    for k in np.unique(ramp):
        sel = ramp == k
        vk, rk, xk, ck = v[sel], residual[sel], x[sel], cruise[sel]
        if len(vk) < 6 or np.ptp(vk) == 0:
            continue
        d = np.column_stack([~ck, ck, xk - np.mean(xk), vk]).astype(float)
        coef, *_ = np.linalg.lstsq(d, rk, rcond=None)
        res = rk - d @ coef
        s2 = float(res @ res) / max(len(vk) - 4, 1)
        var_e = s2 * float(np.linalg.pinv(d.T @ d)[3, 3])
        out.append((float(coef[3]), var_e))
    return out


def _wander(per_ramp: list[tuple[float, float]]) -> float:
    """RMS of the ramps' own timing errors beyond what their uncertainty explains, s."""
    if len(per_ramp) < 3:
        return 0.0
    e = np.array([p[0] for p in per_ramp])
    var = np.array([p[1] for p in per_ramp])
    excess = float(np.mean(e**2) - np.mean(var))
    return math.sqrt(excess) if excess > 0 else 0.0

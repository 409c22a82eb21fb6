"""How an axis changes from campaign to campaign: drift rates, change points, the date it leaves
its tolerance. Pure numbers (numpy, scipy's Student t); no database.

Each parameter (A, E, B, R) is a series of campaigns, each with its value y_i and its expanded
uncertainty U_i (k = 2, the campaign's own budget: campaign/uncertainty.py).

**Change points.** Between two consecutive campaigns the parameter jumped when the change, less
the drift the fit expects over the interval, is larger than the smaller of the combined expanded
uncertainty of the two, √(U_i² + U_j²), and 3.5 times their combined uncertainty between
re-checks, 3.5·√(u_i² + u_j²) (scaled by the fit's Birge ratio when the campaigns scatter more than
their u say). The budget's U holds terms common to the two campaigns (the instrument, the air),
which do not make a change between them; with the u of campaign/history/recheck.py, a reversal
jump of 2 µm is found where √(U_i² + U_j²) missed it and the jump went into A's drift. 3.5 u
rather than 2: an axis's history has some 40 intervals over its four parameters; at 2u one of
them would jump by chance in most histories, at 3u in one of eight (3 of 20 seeds of the demo's
history found a jump of R that is not there), at 3.5u in about one of fifty. The detection and the fit are iterated until
they agree (at most five rounds): a jump found becomes a step in the fit, which then says what
drift to expect. A change point's U is the combined expanded uncertainty √(U_i² + U_j²) of the
two campaigns' statements.

**Drift rate.** A weighted least-squares line over time, y = a + r·t + Σ c_j·[t ≥ t_j] (one step
c_j per change point of the parameter itself, for A, E and R, which contain the reversal, per
change point of B too, and per known step: a campaign that verified a compensation, which changes
every parameter by an amount the fit estimates), with weights 1/u_i², u_i the campaign's
uncertainty between re-checks (`Observation.u_random`: how much the parameter would scatter if
the unchanged axis were measured again, from the campaign's own points,
campaign/history/recheck.py; for a campaign recorded without it, its budget's statistics and
resolution terms), else U_i/2: a campaign with a larger u_i counts less.
The rate's standard uncertainty comes from the fit's covariance (the weights' u_i) scaled by
max(1, χ²/ν) (ν = n − p; χ²/ν is the Birge ratio squared): when the campaigns scatter about the
line more than their u_i say, the scatter sets the scale (a type A evaluation), and the coverage
factor is Student's t at 95 % for ν; otherwise the covariance is left as the u_i make it (never
shrunk below what the campaigns' uncertainties allow) and the coverage factor is k = 2. The rate
is significant when |r| > U(r). A rate needs ν ≥ 1: at least three campaigns, one more per
change point, and campaigns apart in time (a design of full rank).

**Crossing.** For A with a tolerance T: the date at which the fitted A plus the U of the last
campaign reaches T, continuing the line from the last campaign (every step in place). Its
interval: where the fit's band, ±k·σ of the fitted value, plus that U reaches T (the earliest
from the upper band, the latest from the lower). Not predictable, with the reason, when there is
no tolerance, too few campaigns, or no significant upward drift; already crossed when the last
campaign's A + U is beyond T. The prediction assumes the drift goes on as a straight line with no
new jump; it says so.

Times are in years (365.25 days) from the last campaign; values in the deviation unit (µm or
arcsec).
"""

from __future__ import annotations

import datetime as dt
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from protocols.units import unit_label

YEAR_S = 365.25 * 86400.0
HORIZON_YEARS = 50.0
"""How far ahead a crossing is looked for, years."""
MAX_ROUNDS = 5
JUMP_SIGMAS = 3.5
"""A change between consecutive campaigns beyond this many of their combined uncertainties
between re-checks (scaled by the fit's Birge ratio when above 1) is a jump."""


@dataclass(frozen=True)
class Observation:
    """One campaign's value of one parameter: when (UTC), a label (its directory), the value and
    its expanded uncertainty U (k = 2), deviation unit."""

    when: dt.datetime
    label: str
    value: float
    U: float
    u_random: float | None = None

    @property
    def weight_u(self) -> float:
        """The standard uncertainty that weighs this campaign in the fit: its random part when
        known, else U/2."""
        u = self.u_random if self.u_random else self.U / 2.0
        return max(u, 1e-9)


@dataclass(frozen=True)
class ChangePoint:
    """A jump between two consecutive campaigns: the change (after − before), its combined
    expanded uncertainty, and the change less the drift expected over the interval."""

    parameter: str
    before: Observation
    after: Observation
    jump: float
    U: float
    beyond_drift: float

    def sentence(self, unit: str) -> str:
        verb = "rose" if self.jump > 0 else "fell"
        return (f"{self.parameter} {verb} {abs(self.jump):.1f} ± {self.U:.1f} {unit} between "
                f"{self.before.when.date().isoformat()} and {self.after.when.date().isoformat()}")

    def as_json(self, unit: str) -> dict:
        return {"parameter": self.parameter, "before": _obs_json(self.before), "after": _obs_json(self.after),
                "jump": round(self.jump, 4), "U": round(self.U, 4),
                "jump_less_expected_drift": round(self.beyond_drift, 4), "unit": unit,
                "sentence": self.sentence(unit_label(unit))}


def _obs_json(o: Observation) -> dict:
    return {"date": o.when.date().isoformat(), "label": o.label, "value": round(o.value, 4), "U": round(o.U, 4)}


@dataclass
class Fit:
    """The drift of one parameter. rate and U_rate in unit per year (None when not determined,
    with `reason`); k the coverage factor used; `step_at` the index of the first campaign after
    each step in the fit."""

    parameter: str
    observations: list[Observation]
    step_at: list[int] = field(default_factory=list)
    rate: float | None = None
    U_rate: float | None = None
    k: float = 2.0
    birge: float | None = None
    dof: int = 0
    reason: str = ""
    coef: np.ndarray | None = None
    cov: np.ndarray | None = None

    @property
    def significant(self) -> bool:
        return self.rate is not None and self.U_rate is not None and abs(self.rate) > self.U_rate

    @property
    def last(self) -> Observation:
        return self.observations[-1]

    def years(self, when: dt.datetime) -> float:
        """Years from the last campaign to `when` (negative before it)."""
        return (when - self.last.when).total_seconds() / YEAR_S

    def predict(self, tau: float) -> tuple[float, float]:
        """(fitted value, its standard uncertainty) `tau` years after the last campaign, every
        step in place."""
        assert self.coef is not None and self.cov is not None
        g = np.concatenate([[1.0, tau], np.ones(len(self.step_at))])
        return float(g @ self.coef), float(math.sqrt(max(g @ self.cov @ g, 0.0)))

    def predict_many(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`predict` at many times at once: (fitted values, their standard uncertainties)."""
        assert self.coef is not None and self.cov is not None
        g = np.column_stack([np.ones_like(tau), tau] + [np.ones_like(tau)] * len(self.step_at))
        variance = np.einsum("ij,jk,ik->i", g, self.cov, g)
        return g @ self.coef, np.sqrt(np.clip(variance, 0.0, None))

    def fitted(self, tau: np.ndarray, index_from: int) -> np.ndarray:
        """The fitted line at `tau` (years from the last campaign) with the steps of the campaigns
        up to `index_from` in place (for drawing each segment)."""
        assert self.coef is not None
        active = [1.0 if at <= index_from else 0.0 for at in self.step_at]
        return self.coef[0] + self.coef[1] * tau + float(np.dot(active, self.coef[2:]))

    def as_json(self, unit: str) -> dict:
        out: dict = {"parameter": self.parameter, "campaigns": len(self.observations), "unit": unit}
        if self.rate is None:
            out.update(rate_per_year=None, U_rate_per_year=None, significant=False, reason=self.reason)
        else:
            out.update(rate_per_year=round(self.rate, 4), U_rate_per_year=round(self.U_rate or 0.0, 4),
                       k=round(self.k, 3), dof=self.dof, birge_ratio=None if self.birge is None else round(self.birge, 3),
                       significant=self.significant,
                       sentence=self.sentence(unit_label(unit)),
                       steps_between=[[self.observations[i - 1].when.date().isoformat(),
                                       self.observations[i].when.date().isoformat()] for i in self.step_at])
        return out

    def sentence(self, unit: str) -> str:
        if self.rate is None or self.U_rate is None:
            return f"{self.parameter}: drift not determined ({self.reason})"
        what = "a significant drift" if self.significant else "no significant drift"
        return (f"{self.parameter}: {self.rate:+.2f} ± {self.U_rate:.2f} {unit}/year ({what}; "
                f"{len(self.observations)} campaigns" + (f", {len(self.step_at)} jump(s) set apart)" if self.step_at else ")"))


STUDENT_975 = (12.706205, 4.302653, 3.182446, 2.776445, 2.570582, 2.446912, 2.364624, 2.306004, 2.262157, 2.228139,
               2.200985, 2.178813, 2.160369, 2.144787, 2.13145, 2.119905, 2.109816, 2.100922, 2.093024, 2.085963,
               2.079614, 2.073873, 2.068658, 2.063899, 2.059539, 2.055529, 2.051831, 2.048407, 2.04523, 2.042272)
"""Student's t at 97.5 % for 1 to 30 degrees of freedom (the two-sided 95 % coverage factor); a
history has a few tens of campaigns, and scipy takes a second to import where a plant's page
should take two (tests/test_history_drawn.py checks the table against scipy)."""


def student_975(dof: int) -> float:
    """The coverage factor for 95 % with `dof` degrees of freedom (Student's t at 97.5 %)."""
    if 1 <= dof <= len(STUDENT_975):
        return STUDENT_975[dof - 1]
    from scipy.special import stdtrit

    return float(stdtrit(dof, 0.975))


def _years(observations: list[Observation]) -> np.ndarray:
    last = observations[-1].when
    return np.array([(o.when - last).total_seconds() / YEAR_S for o in observations])


def _solve(t: np.ndarray, y: np.ndarray, u: np.ndarray,
           steps: list[int]) -> tuple[np.ndarray, np.ndarray, float, int] | None:
    """Weighted least squares: (coefficients, covariance, χ², ν); None when the design cannot
    separate its coefficients (rank-deficient: the campaigns span no time, or a segment between
    jumps has no two campaigns apart in time)."""
    bounds = [0, *steps, len(t)]
    if not any(np.ptp(t[a:b]) > 0 for a, b in itertools.pairwise(bounds) if b > a):
        return None  # no segment between the steps spans time: the rate cannot be told from the steps
    columns = [np.ones_like(t), t] + [(np.arange(len(t)) >= i).astype(float) for i in steps]
    x = np.column_stack(columns)
    w = 1.0 / u ** 2
    normal = x.T @ (w[:, None] * x)
    cov = np.linalg.inv(normal)
    coef = cov @ (x.T @ (w * y))
    residual = y - x @ coef
    return coef, cov, float(np.sum(w * residual ** 2)), len(t) - x.shape[1]


def _undetermined(obs: list[Observation], t: np.ndarray) -> str:
    """Why a rank-deficient design gives no drift."""
    if float(np.ptp(t)) == 0.0:
        return (f"the campaigns span no time: all {len(obs)} are dated "
                f"{obs[0].when.isoformat(sep=' ', timespec='minutes')} UTC")
    return "the campaigns between the jumps set apart span no time: the drift cannot be told from the jumps"


def _step_indices(obs: list[Observation], after: list[dt.datetime]) -> list[int]:
    """The index of the first campaign on or after each date (a step between it and the one
    before), each once, none at the first campaign."""
    found = set()
    for when in after:
        index = next((i for i, o in enumerate(obs) if o.when >= when), None)
        if index:
            found.add(index)
    return sorted(found)


def detect(parameter: str, observations: list[Observation], known: list[dt.datetime] | None = None) -> list[ChangePoint]:
    """The jumps of one parameter between consecutive campaigns (see the module's docstring).
    `known`: dates of known steps (a compensation verified): the change into the campaign of that
    date is a step of the fit, never reported as a jump."""
    obs = sorted(observations, key=lambda o: o.when)
    n = len(obs)
    if n < 2:
        return []
    t, y = _years(obs), np.array([o.value for o in obs])
    u = np.array([o.weight_u for o in obs])
    dt_years, jumps = np.diff(t), np.diff(y)
    combined = np.sqrt(np.array([o.U for o in obs[:-1]]) ** 2 + np.array([o.U for o in obs[1:]]) ** 2)
    between = np.sqrt(u[:-1] ** 2 + u[1:] ** 2)
    fixed = _step_indices(obs, known or [])
    rate, scale = 0.0, 1.0
    steps: list[int] = []
    for _ in range(MAX_ROUNDS):
        threshold = np.minimum(combined, JUMP_SIGMAS * scale * between)
        found = [i + 1 for i in range(n - 1) if i + 1 not in fixed and abs(jumps[i] - rate * dt_years[i]) > threshold[i]]
        in_fit = sorted(set(found) | set(fixed))
        solved = _solve(t, y, u, in_fit) if n - 2 - len(in_fit) >= 1 else None
        if solved is not None:
            rate = float(solved[0][1])
            scale = max(1.0, math.sqrt(solved[2] / solved[3]))
        if found == steps:
            break
        steps = found
    return [ChangePoint(parameter, obs[i - 1], obs[i], float(jumps[i - 1]), float(combined[i - 1]),
                        float(jumps[i - 1] - rate * dt_years[i - 1])) for i in steps]


def fit(parameter: str, observations: list[Observation], jumps: list[ChangePoint] | None = None,
        known: list[dt.datetime] | None = None) -> Fit:
    """The drift of one parameter over its campaigns, with a step at each change point in `jumps`
    (its own, or a jump of a parameter it contains: a reversal jump moves A and E) and at each
    known step (`known`: the dates of the campaigns that verified a compensation)."""
    obs = sorted(observations, key=lambda o: o.when)
    result = Fit(parameter, obs)
    n = len(obs)
    steps = _step_indices(obs, [j.after.when for j in (jumps or [])] + list(known or []))
    result.step_at = steps
    if n - 2 - len(steps) < 1:
        need = 3 + len(steps)
        result.reason = (f"too few campaigns ({n}; a drift needs at least {need}"
                         + (f" with {len(steps)} jump(s) set apart)" if steps else ")"))
        return result
    t, y = _years(obs), np.array([o.value for o in obs])
    u = np.array([o.weight_u for o in obs])
    solved = _solve(t, y, u, steps)
    if solved is None:
        result.reason = _undetermined(obs, t)
        return result
    coef, cov, chi2, dof = solved

    birge_sq = chi2 / dof
    if birge_sq > 1.0:  # the campaigns scatter more than their U says: the scatter sets the scale
        cov = cov * birge_sq
        k = student_975(dof)
    else:  # no more than their U allows: the stated U sets it, never shrunk below
        k = 2.0
    result.coef, result.cov, result.dof, result.k = coef, cov, dof, k
    result.birge = math.sqrt(birge_sq)
    result.rate = float(coef[1])
    result.U_rate = float(k * math.sqrt(cov[1, 1]))
    return result


STEPS_FROM = {"A": ("A", "B"), "E": ("E", "B"), "R": ("R", "B")}
"""Whose jumps put a step into a parameter's fit: its own, and for A, E and R (each contains the
reversal: R_i of ISO 230-2 holds |B_i|) a reversal jump too; a jump of R does not move A's line."""


def analyse(series: dict[str, list[Observation]],
            known: list[dt.datetime] | None = None) -> tuple[dict[str, Fit], list[ChangePoint]]:
    """Every parameter's change points, then its drift with a step at its own jumps (and, for A,
    E and R, at the reversal's: STEPS_FROM) and at every known step (`known`: the dates of the
    campaigns that verified a compensation, which changes every parameter)."""
    jumps = [j for parameter, obs in series.items() for j in detect(parameter, obs, known)]
    jumps.sort(key=lambda j: (j.after.when, j.parameter))
    fits = {parameter: fit(parameter, obs, [j for j in jumps if j.parameter in STEPS_FROM.get(parameter, (parameter,))],
                           known)
            for parameter, obs in series.items()}
    return fits, jumps


@dataclass
class Crossing:
    """When A + U is predicted to reach the tolerance. `state`: predicted, already, or not
    predictable (with `reason`). Dates as datetimes; `latest` None: beyond the horizon."""

    state: str
    tolerance: float | None
    reason: str = ""
    date: dt.datetime | None = None
    earliest: dt.datetime | None = None
    latest: dt.datetime | None = None
    U_assumed: float | None = None

    def sentence(self, unit: str) -> str:
        if self.state == "predicted" and self.date is not None and self.earliest is not None:
            latest = self.latest.date().isoformat() if self.latest else f"more than {HORIZON_YEARS:g} years ahead"
            return (f"A + U is predicted to reach the tolerance {self.tolerance:g} {unit} on {self.date.date().isoformat()} "
                    f"(95 % interval {self.earliest.date().isoformat()} to {latest}), if the drift goes on as a "
                    "straight line with no new jump")
        if self.state == "already":
            return f"A + U is already beyond the tolerance {self.tolerance:g} {unit}: {self.reason}"
        return f"when A leaves its tolerance is not predictable: {self.reason}"

    def as_json(self, unit: str) -> dict:
        def day(d: dt.datetime | None) -> str | None:
            return None if d is None else d.date().isoformat()

        return {"state": self.state, "predictable": self.state == "predicted", "tolerance": self.tolerance,
                "unit": unit, "date": day(self.date), "earliest": day(self.earliest), "latest": day(self.latest),
                "latest_beyond_horizon": self.state == "predicted" and self.latest is None,
                "U_assumed": None if self.U_assumed is None else round(self.U_assumed, 4),
                "reason": self.reason, "sentence": self.sentence(unit_label(unit)),
                "assumes": "the drift goes on as a straight line, no new jump, the same measurement uncertainty "
                           "as the last campaign"}


def _first_reach(func: Callable[[np.ndarray], np.ndarray], target: float, horizon: float) -> float | None:
    """The smallest tau in [0, horizon] (years) with func(tau) ≥ target, to a day; None if none.
    `func` takes and gives arrays (evaluated on a grid at once, then refined by bisection)."""
    grid = np.linspace(0.0, horizon, 2001)
    above = np.nonzero(func(grid) >= target)[0]
    if len(above) == 0:
        return None
    i = int(above[0])
    if i == 0:
        return 0.0
    lo, hi = float(grid[i - 1]), float(grid[i])
    while hi - lo > 1.0 / 365.25:
        mid = (lo + hi) / 2
        if func(np.array([mid]))[0] >= target:
            hi = mid
        else:
            lo = mid
    return hi


def crossing(a_fit: Fit, tolerance: float | None) -> Crossing:
    """When A + U reaches `tolerance` (see the module's docstring)."""
    if not a_fit.observations:  # first: with no campaign that counts, no tolerance is known either
        return Crossing("not predictable", tolerance, "no campaign that counts for the trend (see those left out)")
    if not tolerance:
        return Crossing("not predictable", None, "no tolerance on A is recorded (set [campaign] tolerance, or give "
                                                 "--tolerance)")
    last = a_fit.last
    u_future = last.U
    if last.value + u_future >= tolerance:
        return Crossing("already", tolerance, f"the last campaign ({last.when.date().isoformat()}) has A + U = "
                        f"{last.value:.2f} + {u_future:.2f}", U_assumed=u_future)
    if a_fit.rate is None:
        return Crossing("not predictable", tolerance, a_fit.reason, U_assumed=u_future)
    if not a_fit.significant or a_fit.rate <= 0:
        return Crossing("not predictable", tolerance,
                        f"no significant upward drift of A ({a_fit.rate:+.2f} ± {a_fit.U_rate:.2f} per year)",
                        U_assumed=u_future)
    k = a_fit.k

    def central(tau: np.ndarray) -> np.ndarray:
        return a_fit.predict_many(tau)[0] + u_future

    def upper(tau: np.ndarray) -> np.ndarray:
        v, s = a_fit.predict_many(tau)
        return v + k * s + u_future

    def lower(tau: np.ndarray) -> np.ndarray:
        v, s = a_fit.predict_many(tau)
        return v - k * s + u_future

    at = _first_reach(central, tolerance, HORIZON_YEARS)
    if at is None:
        return Crossing("not predictable", tolerance, f"A + U does not reach the tolerance within {HORIZON_YEARS:g} years "
                        "at the drift measured", U_assumed=u_future)
    soonest = _first_reach(upper, tolerance, HORIZON_YEARS) or 0.0
    latest = _first_reach(lower, tolerance, HORIZON_YEARS)

    def date(tau: float) -> dt.datetime:
        return last.when + dt.timedelta(seconds=tau * YEAR_S)

    return Crossing("predicted", tolerance, "", date(at), date(soonest), None if latest is None else date(latest),
                    u_future)

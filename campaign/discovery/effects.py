"""The effects discovery can name, as least-squares forms (reference.md §5).

Each effect is linear in some coefficients once its shape parameters (a period, a time constant,
a pivot or a span) are fixed: `columns` gives those coefficients' regressors averaged over each
capture's samples, `params` turns fitted coefficients back into the model's parameters, and
`shape_grid` gives starting values for the shape parameters that are searched.

Units: x mm, deviations µm, t s (or point order), w s; ppm = µm/m.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from campaign.discovery.data import CampaignData
from campaign.model import _legendre

LASER_DATUM_MM = 0.0
"""Where the laser reading is zero: the table's positions are the laser's, so an air
refractive-index error (and the material normalisation) pivots at x = 0."""

Shape = dict[str, float]
"""Shape parameters (or held parameters) of an effect by name: period_mm, tau_s, pivot_mm, ..."""

PERIOD_RANGE_MM = (2.0, 100.0)
"""Plausible screw leads searched for a periodic error, mm (at most half the travel)."""


def _mean_samples(values: np.ndarray) -> np.ndarray:
    return np.nanmean(values, axis=1)


def _span(data: CampaignData, held: Shape) -> tuple[float, float]:
    return held.get("start_mm", float(data.x.min())), held.get("end_mm", float(data.x.max()))


def _linear_scale(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    return (data.x * 1e-3)[:, None]


def _backlash(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    return (-data.d / 2)[:, None]


def _periodic(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    angle = 2 * np.pi * data.x / shape["period_mm"]
    return np.column_stack([np.sin(angle), np.cos(angle)])


def _periodic_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    return {"amplitude_um": float(math.hypot(c[0], c[1])), "period_mm": shape["period_mm"],
            "phase_rad": float(math.atan2(c[1], c[0]))}


def _warming(data: CampaignData, tau_s: float) -> np.ndarray:
    return _mean_samples(1 - np.exp(-data.t / tau_s))


def _thermal(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    f = _warming(data, shape["tau_s"])
    if "pivot_mm" in held:
        return ((data.x - held["pivot_mm"]) * 1e-3 * f)[:, None]
    return np.column_stack([data.x * 1e-3 * f, -1e-3 * f])


def _thermal_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    if "pivot_mm" in held:
        return {"growth_ppm": float(c[0]), "tau_s": shape["tau_s"], "pivot_mm": held["pivot_mm"]}
    pivot = float(c[1] / c[0]) if abs(c[0]) > 1e-12 else 0.0
    return {"growth_ppm": float(c[0]), "tau_s": shape["tau_s"], "pivot_mm": pivot}


def _hours(data: CampaignData) -> np.ndarray:
    """Each capture's time, h (per 3600 points without a time column), averaged over its samples."""
    return _mean_samples(data.t) / 3600


def _linear_drift(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    h = _hours(data)
    if "pivot_mm" in held:
        return ((data.x - held["pivot_mm"]) * 1e-3 * h)[:, None]
    return np.column_stack([data.x * 1e-3 * h, -1e-3 * h])


def _linear_drift_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    if "pivot_mm" in held:
        return {"rate_ppm_per_h": float(c[0]), "pivot_mm": held["pivot_mm"]}
    pivot = float(c[1] / c[0]) if abs(c[0]) > 1e-12 else 0.0
    return {"rate_ppm_per_h": float(c[0]), "pivot_mm": pivot}


def _linear_drift_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    """A slope change over the campaign within GROWTH_PPM; the pivot as thermal drift's."""
    hours = _duration(data) / 3600
    return {"rate_ppm_per_h": (-GROWTH_PPM / hours, GROWTH_PPM / hours), "pivot_mm": _thermal_ranges(data)["pivot_mm"]}


def _nonlinear(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    start, end = _span(data, held)
    p2, p3 = _legendre(2 * (data.x - start) / (end - start) - 1)
    return np.column_stack([p2, p3])


def _nonlinear_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    return {"p2_um": float(c[0]), "p3_um": float(c[1]), "start_mm": shape["start_mm"], "end_mm": shape["end_mm"]}


def _pd_backlash(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    return np.column_stack([-data.d / 2, -data.d * data.x * 1e-3 / 2])


def _settling(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    return (-data.d * _mean_samples(np.exp(-_waits(data) / shape["tau_s"])))[:, None]


def _waits(data: CampaignData) -> np.ndarray:
    """The sample waits since arrival, s; ValueError when the table has no capture_wait_s (settling
    is never a candidate then)."""
    if data.w is None:
        raise ValueError("settling needs the waits since arrival (capture_wait_s)")
    return data.w


def _air(data: CampaignData) -> np.ndarray:
    if data.air_index_change is None:
        raise ValueError("the air term needs the air log")
    return data.air_index_change


def _duration(data: CampaignData) -> float:
    return float(np.nanmax(data.t) - np.nanmin(data.t)) or 1.0


def _tau_grid(low: float, high: float, count: int = 24) -> list[Shape]:
    return [{"tau_s": float(v)} for v in np.geomspace(low, high, count)]


def _thermal_grid(data: CampaignData, held: Shape) -> list[Shape]:
    span = _duration(data)
    return _tau_grid(span / 30, span * 3)


def _settling_grid(data: CampaignData, held: Shape) -> list[Shape]:
    waits = _waits(data)[np.isfinite(_waits(data))]
    return _tau_grid(max(waits.min() / 10, 1e-3), waits.max() * 2)


def _environment(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
    """The slope that follows the log: the air's refractive-index change since the first point,
    x·(n/n0 - 1) (µm per unit air_factor), and the material's temperature above 20 °C,
    x·(T_m - 20) (µm per µm/m/K), both about the laser datum."""
    x = data.x - LASER_DATUM_MM
    cols = []
    if shape.get("air"):
        cols.append(x * 1e3 * _air(data))
    if shape.get("material"):
        cols.append(x * 1e-3 * (data.env["material_temp_c"] - 20.0))
    return np.column_stack(cols) if cols else np.zeros((len(data), 0))


def _environment_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    names = [k for k, flag in (("air_factor", "air"), ("alpha_ppm_per_k", "material")) if shape.get(flag)]
    return {k: float(v) for k, v in zip(names, c)}


def environment_logs(data: CampaignData) -> list[str]:
    """Which environment logs vary in this campaign: "air" and/or "material"."""
    logs = []
    if data.air_index_change is not None and np.ptp(data.air_index_change) > 0:
        logs.append("air")
    if "material_temp_c" in data.env and np.ptp(data.env["material_temp_c"]) > 0:
        logs.append("material")
    return logs


def _environment_grid(data: CampaignData, held: Shape) -> list[Shape]:
    logs = environment_logs(data)
    variants = [{log: 1.0} for log in logs]
    return variants + ([{log: 1.0 for log in logs}] if len(logs) > 1 else [])


NYQUIST_MARGIN = 1.02
"""On evenly spaced targets the shortest period looked for is this many times twice the spacing (at
exactly twice the spacing a sine can sit on its zeros at every target)."""


def even_spacing(data: CampaignData) -> float | None:
    """The spacing of evenly spaced targets, mm (None when they are not evenly spaced: any
    pattern of offsets breaks the aliases of a regular grid, which the period search then lists)."""
    targets = np.unique(np.round(data.x, 6))
    if len(targets) < 3:
        return None
    steps = np.diff(targets)
    return float(np.mean(steps)) if np.ptp(steps) < 1e-3 * np.ptp(targets) else None


def period_limits(data: CampaignData) -> tuple[float, float]:
    """The range of periods searched, mm: the plausible screw leads (PERIOD_RANGE_MM), at most half
    the travel, and on evenly spaced targets above twice their spacing (shorter periods alias onto
    longer ones there). The low end may be above the high one: nothing is looked for."""
    travel = float(np.ptp(data.x)) or 1.0
    spacing = even_spacing(data)
    low = PERIOD_RANGE_MM[0] if spacing is None else max(PERIOD_RANGE_MM[0], 2 * NYQUIST_MARGIN * spacing)
    return low, min(PERIOD_RANGE_MM[1], travel / 2)


@dataclass(frozen=True)
class EffectForm:
    """One effect's least-squares form. coefficients: names of the linear coefficients (model
    parameter names where they are one). shape: the shape parameters that may be searched.
    group: "target" (spatial: cross-validated leaving one target out) or "run" (time: one run
    out)."""

    name: str
    coefficients: tuple[str, ...]
    shape: tuple[str, ...]
    group: str
    columns: Callable[[CampaignData, Shape, Shape], np.ndarray]
    to_params: Callable[[np.ndarray, Shape, Shape], dict[str, float]] | None = None
    shape_grid: Callable[[CampaignData, Shape], list[Shape]] | None = None
    sizes: tuple[str, ...] = ()
    """The parameters (or derived quantities, campaign.discovery.fit.DERIVED) that say how large the
    effect is: each must be at least SIZE_SIGMAS standard errors for the effect to be named."""
    ranges: Callable[[CampaignData], dict[str, tuple[float, float]]] | None = None
    """Each parameter's documented physical range on this campaign (docs/error-model.md): an effect
    with a parameter outside is not named, however well it fits."""

    def physical_ranges(self, data: CampaignData) -> dict[str, tuple[float, float]]:
        return {} if self.ranges is None else self.ranges(data)

    def grid(self, data: CampaignData, held: Shape) -> list[Shape]:
        """The starting values of the searched shape parameters; ValueError for an effect with none."""
        if self.shape_grid is None:
            raise ValueError(f"{self.name} has no shape parameters to search")
        return self.shape_grid(data, held)

    def params(self, coefs: np.ndarray, shape: dict, held: dict) -> dict[str, float]:
        if self.to_params is not None:
            return self.to_params(coefs, shape, held)
        return {**{k: float(v) for k, v in zip(self.coefficients, coefs)}, **shape}


SIZE_SIGMAS = 2.0
"""An effect is named only when each of its sizes is at least this many of its standard errors."""
SCALE_PPM = 2000.0
"""The largest slope of a scale or of a reversal along the travel, µm/m (the vertical axis of Li et
al. 2022 has -1147 µm/m of scale and -641 µm/m of backlash growth)."""
GROWTH_PPM = 500.0
"""The largest thermal growth (or slope change over a campaign), µm/m: a steel screw 20 K warm grows
230 µm/m."""
SIZE_UM = 1000.0
"""The largest reversal, settling, periodic amplitude or bow coefficient, µm."""


def _travel(data: CampaignData) -> float:
    return float(np.ptp(data.x)) or 1.0


def _dwell(data: CampaignData) -> float:
    """The typical wait before a capture, s (in points without a time column: one point)."""
    if data.time_source != "time_s":
        return 1.0
    if data.w is not None and np.any(np.isfinite(data.w)):
        return float(np.nanmedian(np.nanmean(data.w, axis=1)))
    ends = np.sort(np.nanmax(data.t, axis=1))
    return float(np.median(np.diff(ends))) / 2 if len(ends) > 1 else 0.0


def _scale_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    return {"ppm": (-SCALE_PPM, SCALE_PPM)}


def _backlash_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    return {"b_um": (-SIZE_UM, SIZE_UM)}


def _periodic_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    return {"amplitude_um": (0.0, SIZE_UM), "period_mm": period_limits(data)}


def _thermal_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    """Growth within GROWTH_PPM; a time constant between the dwell and ten times the campaign; a
    pivot within two travels of the targets (further, it is the datum drifting, not the screw)."""
    lo, hi, travel = float(data.x.min()), float(data.x.max()), _travel(data)
    return {"growth_ppm": (-GROWTH_PPM, GROWTH_PPM), "tau_s": (_dwell(data), 10 * _duration(data)),
            "pivot_mm": (lo - 2 * travel, hi + 2 * travel)}


def _bow_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    return {"p2_um": (-SIZE_UM, SIZE_UM), "p3_um": (-SIZE_UM, SIZE_UM)}


def _pd_backlash_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    return {"b0_um": (-SIZE_UM, SIZE_UM), "k_ppm": (-SCALE_PPM, SCALE_PPM)}


def _settling_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    """A size within SIZE_UM and a time constant from 1 ms to ten times the longest wait."""
    waits = _waits(data)
    return {"e0_um": (-SIZE_UM, SIZE_UM), "tau_s": (1e-3, 10 * float(np.nanmax(waits)))}


ENVIRONMENT_RANGES = {"air_factor": (-0.5, 1.5), "alpha_ppm_per_k": (-5.0, 30.0)}
"""Physically plausible environment coefficients: the share of the air index change the reading
carries (0 to 1, with room for noise), and an expansion coefficient, µm/m per K (invar to
aluminium and beyond)."""


def _environment_ranges(data: CampaignData) -> dict[str, tuple[float, float]]:
    return dict(ENVIRONMENT_RANGES)


FORMS: dict[str, EffectForm] = {f.name: f for f in (
    EffectForm("linear_scale", ("ppm",), (), "target", _linear_scale, sizes=("ppm",), ranges=_scale_ranges),
    EffectForm("backlash", ("b_um",), (), "target", _backlash, sizes=("b_um",), ranges=_backlash_ranges),
    EffectForm("periodic_lead", ("sin_um", "cos_um"), ("period_mm",), "target", _periodic,
               _periodic_params, sizes=("amplitude_um",), ranges=_periodic_ranges),
    EffectForm("thermal_drift", ("growth_ppm", "growth_pivot"), ("tau_s",), "run", _thermal,
               _thermal_params, _thermal_grid, sizes=("growth_ppm",), ranges=_thermal_ranges),
    EffectForm("linear_drift", ("rate_ppm_per_h", "rate_pivot"), (), "run", _linear_drift, _linear_drift_params,
               sizes=("rate_ppm_per_h",), ranges=_linear_drift_ranges),
    EffectForm("nonlinear_lead", ("p2_um", "p3_um"), (), "target", _nonlinear, _nonlinear_params,
               sizes=("bow_rms_um",), ranges=_bow_ranges),
    EffectForm("position_dependent_backlash", ("b0_um", "k_ppm"), (), "target", _pd_backlash,
               sizes=("k_ppm",), ranges=_pd_backlash_ranges),
    EffectForm("settling", ("e0_um",), ("tau_s",), "target", _settling, None, _settling_grid,
               sizes=("e0_um",), ranges=_settling_ranges),
    EffectForm("environment", ("air_factor", "alpha_ppm_per_k"), (), "run", _environment,
               _environment_params, _environment_grid, sizes=("air_factor", "alpha_ppm_per_k"),
               ranges=_environment_ranges),
)}
"""Effect name -> its form, in the order candidates are listed."""



STEP_RISE = 2 * math.log(9)
"""A logistic 1/(1 + e^(-z)) rises from 10 % to 90 % over this many units of z."""


def local_shape(x: np.ndarray, centre_mm: float | np.ndarray, width_mm: float, kind: str = "bump") -> np.ndarray:
    """A local shape of height 1 at centre_mm: a smooth bump width_mm wide at half its height (a
    Gaussian), or a step (kind "step") rising from 0 to 1 over width_mm (10 % to 90 %, a logistic)
    about centre_mm: the shapes discovery gives an error outside its vocabulary
    (campaign.discovery.local)."""
    if kind == "step":
        z = np.clip((x - centre_mm) * STEP_RISE / max(width_mm, 1e-9), -60.0, 60.0)
        return 1.0 / (1.0 + np.exp(-z))
    return np.exp(-4 * math.log(2) * ((x - centre_mm) / width_mm) ** 2)


def _local_columns(kind: str, by_direction: bool) -> Callable[[CampaignData, Shape, Shape], np.ndarray]:
    def columns(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
        g = local_shape(data.x, shape["centre_mm"], shape["width_mm"], kind)
        if by_direction:
            return np.column_stack([g * (data.d > 0), g * (data.d < 0)])
        return g[:, None]
    return columns


def region_basis(x: np.ndarray, start_mm: float, end_mm: float, pieces: int, open_end: bool = True,
                 open_start: bool = False) -> np.ndarray:
    """A local term whose shape follows the data over [start_mm, end_mm]: cubic B-splines on `pieces`
    equal intervals, without the two that are not flat at the start (so the term and its slope are
    zero there and before it). open_end: each is held at its end value beyond the end (a step's level
    goes on); otherwise the two not flat at the end go too, and the term is zero after it (a bump of
    any shape). open_start: the two at the start stay (a region that begins at the first target, where
    nothing is measured before it). pieces + 3 columns less two for each closed side (pieces at least
    2 when both are closed)."""
    from scipy.interpolate import BSpline

    pieces = max(int(pieces), 1 if open_end or open_start else 2)
    inner = np.linspace(start_mm, end_mm, pieces + 1)
    knots = np.r_[[start_mm] * 3, inner, [end_mm] * 3]
    u = np.clip(np.asarray(x, dtype=float), start_mm, end_mm)
    cols = BSpline.design_matrix(u, knots, 3).toarray()
    if not open_start:
        cols = cols[:, 2:]
        cols[np.asarray(x) < start_mm] = 0.0
    return cols if open_end else cols[:, :-2]


def _region_columns(side: int) -> Callable[[CampaignData, Shape, Shape], np.ndarray]:
    def columns(data: CampaignData, shape: Shape, held: Shape) -> np.ndarray:
        g = region_basis(data.x, shape["start_mm"], shape["end_mm"], int(shape["pieces"]), shape["open_end"] > 0,
                         shape.get("open_start", 0.0) > 0)
        return g if side == 0 else g * (data.d * side > 0)[:, None]
    return columns


def _region_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    grid = np.linspace(shape["start_mm"], shape["end_mm"], 201)
    values = region_basis(grid, shape["start_mm"], shape["end_mm"], int(shape["pieces"]), shape["open_end"] > 0,
                         shape.get("open_start", 0.0) > 0) @ c
    k = int(np.argmax(np.abs(values)))
    return {"peak_um": float(values[k]), "peak_at_mm": float(grid[k]), "level_after_um": float(values[-1]),
            **shape}


LOCAL_FORMS: dict[str, EffectForm] = {f.name: f for f in (
    EffectForm("local_error", ("amplitude_um",), (), "target", _local_columns("bump", False)),
    EffectForm("local_error_by_direction", ("plus_um", "minus_um"), (), "target", _local_columns("bump", True)),
    EffectForm("local_error_step", ("amplitude_um",), (), "target", _local_columns("step", False)),
    EffectForm("local_error_step_by_direction", ("plus_um", "minus_um"), (), "target", _local_columns("step", True)),
    EffectForm("local_region", (), (), "target", _region_columns(0), _region_params),
    EffectForm("local_region_plus", (), (), "target", _region_columns(1), _region_params),
    EffectForm("local_region_minus", (), (), "target", _region_columns(-1), _region_params),
)}
"""Not in the vocabulary: the local terms discovery adds for an error no effect of the model has the
shape of (a screw defect, a worn zone, a joint between two sections): a bump or a step, in both
directions or one amplitude per direction; or, over a region the locator found
(campaign.discovery.unexplained), a spline whose shape follows the data (local_region, in both
directions, or _plus / _minus for one). Their centre and width (mm) are found by their own search
(campaign.discovery.local) and held in the term's shape; only the amplitudes are fitted with the
model. A second or third one on the same axis is named with "#2", "#3". Never a candidate, never in
the saved model."""


def form_of(name: str) -> EffectForm:
    """The least-squares form of a term in the model: a vocabulary effect or a local error."""
    return FORMS[name] if name in FORMS else LOCAL_FORMS[name.split("#")[0]]


SHAPE_KEYS = ("period_mm", "tau_s", "pivot_mm", "start_mm", "end_mm")
"""Parameters held when the model file gives them although the effect is refitted."""


def fixed_shape(name: str, data: CampaignData, held: dict) -> dict[str, float]:
    """Shape parameters that are not searched: the span of the nonlinear lead (default: the
    targets' range)."""
    if name == "nonlinear_lead":
        start, end = _span(data, held)
        return {"start_mm": start, "end_mm": end}
    return {}

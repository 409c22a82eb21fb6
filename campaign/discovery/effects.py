"""The effects discovery can name, as least-squares forms (reference.md §5): thin lookups into the
effects' registry (campaign/effects/, one module per effect), and the local terms discovery gives
an error outside that vocabulary.

Each effect is linear in some coefficients once its shape parameters (a period, a time constant,
a pivot or a span) are fixed: `columns` gives those coefficients' regressors averaged over each
capture's samples, `params` turns fitted coefficients back into the model's parameters, and
`shape_grid` gives starting values for the shape parameters that are searched.

Units: x mm, deviations µm, t s (or point order), w s; ppm = µm/m.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from campaign.effects import RegistryView
from campaign.effects.base import (
    GROWTH_PPM,
    LASER_DATUM_MM,
    NYQUIST_MARGIN,
    PERIOD_RANGE_MM,
    SCALE_PPM,
    SIZE_SIGMAS,
    SIZE_UM,
    EffectForm,
    Samples,
    Shape,
    even_spacing,
    period_limits,
)
from campaign.effects.environment import ENVIRONMENT_RANGES, environment_logs

FORMS: RegistryView[EffectForm] = RegistryView(lambda e: e.form)
"""Effect name -> its form, in the order candidates are listed: every registered effect that has
one (campaign/effects/; the simulator's own effects have none)."""

__all__ = [
    "ENVIRONMENT_RANGES",
    "GROWTH_PPM",
    "LASER_DATUM_MM",
    "NYQUIST_MARGIN",
    "PERIOD_RANGE_MM",
    "SCALE_PPM",
    "SIZE_SIGMAS",
    "SIZE_UM",
    "EffectForm",
    "Shape",
    "environment_logs",
    "even_spacing",
    "period_limits",
]


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


def _local_columns(kind: str, by_direction: bool) -> Callable[[Samples, Shape, Shape], np.ndarray]:
    def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
        g = local_shape(data.x, shape["centre_mm"], shape["width_mm"], kind)
        if by_direction:
            return np.column_stack([g * (data.d > 0), g * (data.d < 0)])
        return g[:, None]
    return columns


def _target_columns(by_direction: bool) -> Callable[[Samples, Shape, Shape], np.ndarray]:
    def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
        x = np.round(data.x, 6)  # that target's points alone, or those of it and the next (last_mm)
        g = ((x >= round(shape["centre_mm"], 6)) & (x <= round(shape.get("last_mm", shape["centre_mm"]), 6))).astype(float)
        if by_direction:
            return np.column_stack([g * (data.d > 0), g * (data.d < 0)])
        return g[:, None]
    return columns


def _cubic_basis(x: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The four cubic B-splines not zero at each x inside the knots (Cox-de Boor, vectorised): the
    first one's column per x, and their values (len(x) × 4)."""
    span = np.clip(np.searchsorted(knots, x, side="right") - 1, 3, len(knots) - 5)
    values = np.zeros((len(x), 4))
    values[:, 0] = 1.0
    left, right = np.zeros((len(x), 4)), np.zeros((len(x), 4))
    for d in range(1, 4):
        left[:, d] = x - knots[span + 1 - d]
        right[:, d] = knots[span + d] - x
        saved = np.zeros(len(x))
        for r in range(d):
            temp = values[:, r] / (right[:, r + 1] + left[:, d - r])
            values[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, d - r] * temp
        values[:, d] = saved
    return span - 3, values


def region_basis(x: np.ndarray, start_mm: float, end_mm: float, pieces: int, open_end: bool = True,
                 open_start: bool = False, offset_level: bool = False) -> np.ndarray:
    """A local term whose shape follows the data over [start_mm, end_mm]: cubic B-splines on `pieces`
    equal intervals, without the two that are not flat at the start (so the term and its slope are
    zero there and before it). open_end: each is held at its end value beyond the end (a step's level
    goes on); otherwise the two not flat at the end go too, and the term is zero after it (a bump of
    any shape). open_start: the two at the start stay (a region that begins at the first target, where
    nothing is measured before it). pieces + 3 columns less two for each closed side (pieces at least
    2 when both are closed), less the first when both are open and `offset_level`: in both directions
    they then sum to one everywhere, the offset's column (a rank lost, charged as a parameter, and on a
    dense table a fit through the SVD of the whole design each time); without the first the term is
    zero at and before the start, where the offset holds the level, so its peak and level after are
    measured from the level at the first target. (In one direction they sum to that direction's
    indicator, which the offset does not span: all stay.)"""
    pieces = max(int(pieces), 1 if open_end or open_start else 2)
    inner = np.linspace(start_mm, end_mm, pieces + 1)
    knots = np.r_[[start_mm] * 3, inner, [end_mm] * 3]
    x = np.asarray(x, dtype=float)
    cols = np.zeros((len(x), pieces + 3))
    inside = (x > start_mm) & (x < end_mm)  # outside, a clamped spline holds its end values: 1 in the end column
    if np.any(inside):
        at = np.flatnonzero(inside)
        first, values = _cubic_basis(x[at], knots)
        for r in range(4):
            cols[at, first + r] = values[:, r]
    cols[x <= start_mm, 0] = 1.0
    cols[x >= end_mm, -1] = 1.0
    if not open_start:
        cols = cols[:, 2:]
        cols[np.asarray(x) < start_mm] = 0.0
    elif open_end and offset_level:
        cols = cols[:, 1:]
    return cols if open_end else cols[:, :-2]


def region_basis_of(x: np.ndarray, shape: Shape) -> np.ndarray:
    """region_basis at positions x (mm) with a region term's shape: start_mm, end_mm, pieces, open_end,
    open_start and offset_level (1.0 or 0.0; the last two may be absent: 0)."""
    return region_basis(x, shape["start_mm"], shape["end_mm"], int(shape["pieces"]), shape["open_end"] > 0,
                        shape.get("open_start", 0.0) > 0, shape.get("offset_level", 0.0) > 0)


def _region_columns(side: int) -> Callable[[Samples, Shape, Shape], np.ndarray]:
    def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
        g = region_basis_of(data.x, shape)
        return g if side == 0 else g * (data.d * side > 0)[:, None]
    return columns


def _region_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    grid = np.linspace(shape["start_mm"], shape["end_mm"], 201)
    values = region_basis_of(grid, shape) @ c
    k = int(np.argmax(np.abs(values)))
    return {"peak_um": float(values[k]), "peak_at_mm": float(grid[k]), "level_after_um": float(values[-1]),
            **shape}


LOCAL_FORMS: dict[str, EffectForm] = {f.name: f for f in (
    EffectForm("local_error", ("amplitude_um",), (), "target", _local_columns("bump", False)),
    EffectForm("local_error_by_direction", ("plus_um", "minus_um"), (), "target", _local_columns("bump", True)),
    EffectForm("local_error_step", ("amplitude_um",), (), "target", _local_columns("step", False)),
    EffectForm("local_error_step_by_direction", ("plus_um", "minus_um"), (), "target", _local_columns("step", True)),
    EffectForm("local_error_target", ("amplitude_um",), (), "target", _target_columns(False)),
    EffectForm("local_error_target_by_direction", ("plus_um", "minus_um"), (), "target", _target_columns(True)),
    EffectForm("local_region", (), (), "target", _region_columns(0), _region_params),
    EffectForm("local_region_plus", (), (), "target", _region_columns(1), _region_params),
    EffectForm("local_region_minus", (), (), "target", _region_columns(-1), _region_params),
)}
"""Not in the vocabulary: the local terms discovery adds for an error no effect of the model has the
shape of (a screw defect, a worn zone, a joint between two sections): a bump or a step, in both
directions or one amplitude per direction; a departure at one target alone (local_error_target: an error
narrower than the targets' spacing, or that target's own), or at two neighbouring targets together (last_mm
in its shape); or, over a region the locator found
(campaign.discovery.unexplained), a spline whose shape follows the data (local_region, in both
directions, or _plus / _minus for one). Their centre and width (mm) are found by their own search
(campaign.discovery.local) and held in the term's shape; only the amplitudes are fitted with the
model. A second or third one on the same axis is named with "#2", "#3". Never a candidate, never in
the saved model."""


HELD_PREFIX = "held_"
"""The name of a term that holds what an unresolved group shows (campaign.discovery.held.hold_unresolved)
is this and the name of the group's effect whose form it has: in the fit, never named, never saved."""


PERIOD_KEY: RegistryView[str] = RegistryView(lambda e: e.period)
"""Effect -> its shape parameter that is a period along the travel (each effect's `period`:
periodic_lead's period_mm): searched over the periodogram's peaks, within period_limits, its aliases
listed."""


def period_key(name: str) -> str | None:
    """The period parameter of the term `name` (an effect's, or one held for an unresolved group), if
    it is periodic."""
    return PERIOD_KEY.get(name.removeprefix(HELD_PREFIX))


def form_of(name: str) -> EffectForm:
    """The least-squares form of a term in the model: a vocabulary effect (held for an unresolved
    group too: HELD_PREFIX) or a local error."""
    base = name.removeprefix(HELD_PREFIX)
    return FORMS[base] if base in FORMS else LOCAL_FORMS[name.split("#")[0]]


SHAPE_KEYS = ("period_mm", "tau_s", "pivot_mm", "start_mm", "end_mm")
"""Parameters held when the model file gives them although the effect is refitted."""


def fixed_shape(name: str, data: Samples, held: dict) -> dict[str, float]:
    """Shape parameters that are not searched: the span of the nonlinear lead (default: the
    targets' range); each effect's form says (EffectForm.fixed_shape)."""
    form = FORMS.get(name)
    return {} if form is None or form.fixed_shape is None else form.fixed_shape(data, held)

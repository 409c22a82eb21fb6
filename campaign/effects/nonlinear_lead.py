"""nonlinear_lead: a bow of the lead along the travel (Legendre P2 and P3 over a span)."""

from __future__ import annotations

import math

import numpy as np

from campaign.effects.base import SIZE_UM, Effect, EffectForm, Ranges, Samples, Shape, legendre, span_ends


def span(data: Samples, held: Shape) -> tuple[float, float]:
    return held.get("start_mm", float(data.x.min())), held.get("end_mm", float(data.x.max()))


def bow(p: dict[str, float], x: np.ndarray) -> np.ndarray:
    p2, p3 = legendre(2 * (x - p["start_mm"]) / (p["end_mm"] - p["start_mm"]) - 1)
    return p["p2_um"] * p2 + p["p3_um"] * p3


def columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    start, end = span(data, held)
    p2, p3 = legendre(2 * (data.x - start) / (end - start) - 1)
    return np.column_stack([p2, p3])


def to_params(c: np.ndarray, shape: Shape, held: Shape) -> dict[str, float]:
    return {"p2_um": float(c[0]), "p3_um": float(c[1]), "start_mm": shape["start_mm"], "end_mm": shape["end_mm"]}


def ranges(data: Samples) -> Ranges:
    return {"p2_um": (-SIZE_UM, SIZE_UM), "p3_um": (-SIZE_UM, SIZE_UM)}


def fixed_shape(data: Samples, held: Shape) -> Shape:
    """The span the polynomials cover: the model's, or the targets' range."""
    start, end = span(data, held)
    return {"start_mm": start, "end_mm": end}


EFFECT = Effect(
    "nonlinear_lead", 50, {"p2_um": "Legendre P2 coefficient, µm", "p3_um": "Legendre P3 coefficient, µm",
                           "start_mm": "start of the travel the polynomials span, mm",
                           "end_mm": "end of that travel, mm"},
    lambda p, x, d, t, w: bow(p, x),
    EffectForm("nonlinear_lead", ("p2_um", "p3_um"), (), "target", columns, to_params,
               sizes=("bow_rms_um",), ranges=ranges, fixed_shape=fixed_shape),
    defaults={"p3_um": 0.0}, check=span_ends,
    derived=lambda p: {"bow_rms_um": math.sqrt(p["p2_um"] ** 2 / 5 + p["p3_um"] ** 2 / 7)})

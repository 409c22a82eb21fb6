"""The measurement uncertainty of a campaign's results, as a budget (GUM method of ISO/TR 230-9,
with the contributors ISO 230-2:2014 annex A names for a laser measurement of linear positioning).

Each term is a standard uncertainty u (deviation unit: µm, or arcsec on a rotary axis) with where
its input came from: the config (a certificate, the sensors' specifications), the measurement, or a
default that is named as such. The expanded uncertainty is U = k·√(Σ u²) with k = 2.

Linear axis, over the measured span L (mm) of the targets:

| term | u |
|---|---|
| laser wavelength (length measurement) | U_cert/2 · L, U_cert from the certificate in µm/m |
| air refractive index | L · √Σ (∂n/∂q · U_q/2)² over air temperature, pressure and humidity (∂n/∂q from the Edlén equation of campaign/edlen.py at the measured air), plus the equation's own 1e-8 |
| dead path | the dead path length · the same index uncertainty |
| material temperature | α · L · U_T/2 when the readings are normalised to 20 °C; without normalisation the uncorrected expansion α · L · |T̄ − 20 °C| counts as a rectangular bound (/√3) |
| expansion coefficient | L · |T̄ − 20 °C| · h_α/√3, h_α the half-width of the coefficient's range |
| misalignment (cosine error) | the cosine error w²/(2L) of a lateral beam walk w over the travel, rectangular (/√3) |
| reading resolution | r/√12 |
| statistics of the result (finite runs) | for A: √2 · √((s/√n)² + (2s/√(2(n−1)))²), the uncertainty of a mean and of its 2s band, at both extremes; s the largest s_i, n the runs |

E takes the same terms with the means only (√2 · s/√n); B and R only the statistics and the
resolution (the length terms are the same in both directions and cancel in B; R is 4s):
u(B) = √2 · s/√n, u(R) = 4s/√(2(n−1)).

Rotary axis: the instrument's angular uncertainty from its certificate, the resolution and the
statistics.

Where a term cannot be evaluated (no material temperature and no normalisation: the expansion is
unknown), the budget says so in `missing`, and a verdict that relies on it is not judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from campaign.config import Config
from campaign.edlen import REFERENCE_TEMPERATURE_C, refractive_index
from campaign.iso230 import Evaluation
from campaign.pointtable import PointTable
from campaign.specs import EnvironmentSpec, InstrumentSpec
from protocols.units import unit_label

K = 2.0
"""Coverage factor of the expanded uncertainty (about 95 %)."""

EDLEN_RELATIVE = 1e-8
"""Standard uncertainty of the updated Edlén equation itself, relative (Birch & Downs give about
1e-8 for the equation; it is small beside the sensors)."""

TYPICAL = {"wavelength_uncertainty_ppm": 0.5, "angle_uncertainty_arcsec": 1.0}
"""Values used when the config gives no certificate value: typical laser specifications, named as
defaults in the budget so that nobody mistakes them for a certificate."""


@dataclass(frozen=True)
class Term:
    """One contributor: its name, standard uncertainty u (deviation unit), the parameters it applies
    to (A, E, B, R) and where its input came from."""

    name: str
    u: float
    applies: tuple[str, ...]
    source: str

    def as_dict(self) -> dict:
        return {"name": self.name, "u": round(self.u, 4), "applies_to": list(self.applies), "source": self.source}


@dataclass(frozen=True)
class Budget:
    """The uncertainty budget. expanded: parameter -> U (k = 2), deviation unit. missing: terms that
    could not be evaluated, with why (a verdict that needs them is not judged)."""

    unit: str
    terms: tuple[Term, ...]
    expanded: dict[str, float]
    missing: tuple[str, ...] = ()
    k: float = K
    notes: tuple[str, ...] = field(default=())

    def as_json(self) -> dict:
        out: dict[str, object] = {f"U_{key}_{self.unit}": round(value, 4) for key, value in self.expanded.items()}
        out.update(k=self.k, unit=self.unit, terms=[t.as_dict() for t in self.terms], missing=list(self.missing),
                   notes=list(self.notes))
        return out


def _setting(config: Config | None, section: str, key: str) -> Any:
    """The value of `key` in the config's instrument or environment spec, or the spec's default when
    there is no config."""
    spec: InstrumentSpec | EnvironmentSpec
    if section == "instrument":
        spec = config.instrument if config is not None else InstrumentSpec()
    else:
        spec = config.environment if config is not None else EnvironmentSpec()
    return getattr(spec, key)


def _source(config: Config | None, section: str, key: str, what: str) -> str:
    if config is None:
        return f"{what}: default ({section}.{key}; no config)"
    return f"{what}: config {section}.{key}"


def _mean_of(table: PointTable, column: str) -> float | None:
    values = table.optional.get(column)
    return float(np.mean(values)) if values is not None and len(values) else None


def _statistics(ev: Evaluation) -> tuple[float, float, int] | None:
    """(u of a mean, u of a 2s band, runs) from the largest s_i; None without scatter."""
    sds = [s for t in ev.targets for s in (t.s_up, t.s_down) if s is not None]
    n = ev.runs
    if not sds or n < 2:
        return None
    s = max(sds)
    return s / math.sqrt(n), 2 * s / math.sqrt(2 * (n - 1)), n


def budget(table: PointTable, ev: Evaluation, config: Config | None = None) -> Budget:
    """The uncertainty budget of `ev`, the evaluation of `table`; inputs from `config` (None: the
    schema's defaults, named so)."""
    terms: list[Term] = []
    missing: list[str] = []
    notes: list[str] = []
    linear = table.kind == "linear"
    res = _setting(config, "instrument", "resolution")
    terms.append(Term("reading resolution", res / math.sqrt(12), ("A", "E", "B", "R"),
                      _source(config, "instrument", "resolution", f"{res:g} {unit_label(ev.unit)}")))
    if linear:
        _length_terms(table, ev, config, terms, missing, notes)
    else:
        given = _setting(config, "instrument", "angle_uncertainty_arcsec")
        value = TYPICAL["angle_uncertainty_arcsec"] if given is None else given
        source = (f"{value:g} arcsec (k = 2): " + ("a typical specification, NOT from a certificate "
                  "(set instrument.angle_uncertainty_arcsec)" if given is None else "config instrument."
                  "angle_uncertainty_arcsec"))
        terms.append(Term("instrument (angle)", value / K, ("A", "E"), source))
    stats = _statistics(ev)
    if stats is None:
        missing.append("statistics: no scatter (fewer than 2 runs)")
    else:
        u_mean, u_band, n = stats
        terms.append(Term("statistics: the means (finite runs)", math.sqrt(2) * u_mean, ("E", "B"),
                          f"√2 · s/√n, s = largest s_i, n = {n} runs (measured)"))
        terms.append(Term("statistics: the means and 2s bands (finite runs)",
                          math.sqrt(2) * math.hypot(u_mean, u_band), ("A",),
                          f"√2 · √((s/√n)² + (2s/√(2(n−1)))²), n = {n} runs (measured)"))
        terms.append(Term("statistics: 4s (finite runs)", 2 * u_band, ("R",),
                          f"4s/√(2(n−1)), n = {n} runs (measured)"))
    expanded = {key: K * math.sqrt(sum(t.u ** 2 for t in terms if key in t.applies)) for key in ("A", "E", "B", "R")}
    if stats is None:  # every parameter rests on the scatter: without it no U can be stated, not a smaller one
        expanded = {}
    return Budget(ev.unit, tuple(terms), expanded, tuple(missing), K, tuple(notes))


def _length_terms(table: PointTable, ev: Evaluation, config: Config | None, terms: list[Term],
                  missing: list[str], notes: list[str]) -> None:
    span_mm = float(np.max(table.target) - np.min(table.target))
    per_ppm = span_mm * 1e-3  # µm per µm/m over the span
    given = _setting(config, "instrument", "wavelength_uncertainty_ppm")
    ppm = TYPICAL["wavelength_uncertainty_ppm"] if given is None else given
    source = (f"{ppm:g} µm/m (k = 2) over {span_mm:g} mm: " + ("a typical specification, NOT from a certificate "
              "(set instrument.wavelength_uncertainty_ppm)" if given is None else
              "certificate (config instrument.wavelength_uncertainty_ppm)"))
    terms.append(Term("laser wavelength", ppm / K * per_ppm, ("A", "E"), source))

    air = {q: _mean_of(table, q) for q in ("air_temp_c", "air_pressure_hpa", "humidity_pct")}
    t_c = air["air_temp_c"] if air["air_temp_c"] is not None else 20.0
    p_hpa = air["air_pressure_hpa"] if air["air_pressure_hpa"] is not None else 1013.25
    rh = air["humidity_pct"] if air["humidity_pct"] is not None else 50.0
    if None in air.values():
        notes.append("air sensitivities taken at 20 °C, 1013.25 hPa, 50 % RH where the table has no air column")
    wavelength = _setting(config, "environment", "wavelength_nm")
    n0 = refractive_index(t_c, p_hpa * 100, rh, wavelength)
    sensitivities = {
        "air_temp": (refractive_index(t_c + 0.5, p_hpa * 100, rh, wavelength) - refractive_index(
            t_c - 0.5, p_hpa * 100, rh, wavelength), "air_temp_uncertainty_c", "°C"),
        "air_pressure": ((refractive_index(t_c, (p_hpa + 0.5) * 100, rh, wavelength) - refractive_index(
            t_c, (p_hpa - 0.5) * 100, rh, wavelength)), "air_pressure_uncertainty_hpa", "hPa"),
        "humidity": ((refractive_index(t_c, p_hpa * 100, rh + 0.5, wavelength) - refractive_index(
            t_c, p_hpa * 100, rh - 0.5, wavelength)), "humidity_uncertainty_pct", "% RH"),
    }
    u_n_sq, parts = EDLEN_RELATIVE ** 2, []
    for name, (per_unit, key, unit) in sensitivities.items():
        expanded = _setting(config, "environment", key)
        u_n_sq += (per_unit * expanded / K) ** 2
        parts.append(f"{name.replace('_', ' ')} ±{expanded:g} {unit} (k = 2, {abs(per_unit) * 1e6:.3f} µm/m "
                     f"per {unit})")
    u_n = math.sqrt(u_n_sq)
    terms.append(Term("air refractive index", u_n * span_mm * 1e3, ("A", "E"),
                      f"Edlén at {t_c:.2f} °C, {p_hpa:.1f} hPa, {rh:.0f} % RH (n = {n0:.9f}); " + "; ".join(parts)
                      + (" (config environment.*_uncertainty)" if config is not None else " (defaults)")))
    dead = _setting(config, "instrument", "dead_path_mm")
    if dead:
        terms.append(Term("dead path", u_n * dead * 1e3, ("A", "E"),
                          _source(config, "instrument", "dead_path_mm", f"{dead:g} mm")))

    alpha = _setting(config, "environment", "expansion_ppm_per_k")
    material = _mean_of(table, "material_temp_c")
    normalised = bool(_setting(config, "environment", "normalise_to_20c"))
    if normalised or material is not None:
        delta = 0.0 if material is None else abs(material - REFERENCE_TEMPERATURE_C)
        if normalised:
            u_t = _setting(config, "environment", "material_temp_uncertainty_c") / K
            terms.append(Term("material temperature", alpha * per_ppm * u_t, ("A", "E"),
                              f"readings normalised to 20 °C; α = {alpha:g} µm/m·K, sensor ±{u_t * K:g} °C (k = 2)"))
        else:
            terms.append(Term("uncorrected expansion", alpha * per_ppm * delta / math.sqrt(3), ("A", "E"),
                              f"not normalised to 20 °C: α = {alpha:g} µm/m·K × |{material:.2f} − 20| °C over "
                              f"{span_mm:g} mm, rectangular"))
        h_alpha = _setting(config, "environment", "expansion_uncertainty_ppm_per_k")
        terms.append(Term("expansion coefficient", per_ppm * delta * h_alpha / math.sqrt(3), ("A", "E"),
                          f"±{h_alpha:g} µm/m·K at |T̄ − 20 °C| = {delta:.2f} K, rectangular"))
    else:
        missing.append("material temperature: the table has none and the readings are not normalised to 20 °C, "
                       "so the thermal expansion of the axis is unknown (record the material temperature)")

    walk = _setting(config, "instrument", "misalignment_mm")
    if span_mm > 0 and walk:
        cosine_um = walk ** 2 / (2 * span_mm) * 1e3
        terms.append(Term("misalignment (cosine error)", cosine_um / math.sqrt(3), ("A", "E"),
                          _source(config, "instrument", "misalignment_mm",
                                  f"beam walk {walk:g} mm over {span_mm:g} mm: {cosine_um:.3f} µm, rectangular")))

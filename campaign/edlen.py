"""Refractive index of air and the two corrections that turn a laser reading into a length at 20 °C.

The refractive index is the updated Edlén equation (Birch & Downs 1993/1994) in the form NIST's
EMToolbox uses, with the IAPWS-IF97 saturation vapour pressure of water (reference.md §6).

Units: temperatures in °C, pressures in Pa, relative humidity in %, CO2 in ppm (µmol/mol),
wavelengths in nm (vacuum wavelength), positions in mm, corrections in µm, expansion coefficients
in ppm/K (µm/m/K).

How a laser reading is corrected: the instrument counts fringes of the vacuum wavelength λ and
reports `fringes·λ/(2·n_ref)`, where n_ref is the index it assumed (1 for a "vacuum" reading).
The length in the real air is `fringes·λ/(2·n)`, so the reading scales by `n_ref/n`
(`air_correction_factor`). The material (thermal) normalisation then reduces the length to what it
would be with the machine at 20 °C. Both are stored per point as offsets in µm so that a recording
can show and undo each one (`apply_corrections_mm`, `undo_corrections_mm`).
"""

from __future__ import annotations

import math

REFERENCE_TEMPERATURE_C = 20.0
"""ISO 1: the reference temperature for lengths, °C."""

_IF97_K = (
    1167.05214528,
    -724213.167032,
    -17.0738469401,
    12020.8247025,
    -3232555.03223,
    14.9151086135,
    -4823.26573616,
    405113.405421,
    -0.238555575678,
    650.175348448,
)


def saturation_pressure_pa(t_c: float) -> float:
    """Saturation vapour pressure of water over liquid water at t_c (°C), in Pa (IAPWS-IF97)."""
    k1, k2, k3, k4, k5, k6, k7, k8, k9, k10 = _IF97_K
    t_k = t_c + 273.15
    omega = t_k + k9 / (t_k - k10)
    a = omega**2 + k1 * omega + k2
    b = k3 * omega**2 + k4 * omega + k5
    c = k6 * omega**2 + k7 * omega + k8
    return 1e6 * (2 * c / (-b + math.sqrt(b * b - 4 * a * c))) ** 4


def refractive_index(
    t_c: float,
    p_pa: float,
    rh_pct: float,
    wavelength_nm: float = 633.0,
    co2_ppm: float = 450.0,
) -> float:
    """Refractive index n of moist air (dimensionless).

    t_c: air temperature, °C. p_pa: air pressure, Pa. rh_pct: relative humidity, %.
    wavelength_nm: vacuum wavelength, nm. co2_ppm: CO2 content, ppm.

    The default 633 nm reproduces NIST's reference table (which states λ = 633 nm) to within
    5e-10; 632.991 nm (the HeNe vacuum wavelength) is also within 6e-10 of it.
    """
    sigma2 = (1000.0 / wavelength_nm) ** 2  # σ², µm⁻²
    n_s = (8342.54 + 2406147 / (130 - sigma2) + 15998 / (38.9 - sigma2)) * 1e-8
    n_x = n_s * (1 + 0.534e-6 * (co2_ppm - 450))
    n_tp = p_pa * n_x / 96095.43 * (1 + 1e-8 * (0.601 - 0.00972 * t_c) * p_pa) / (1 + 0.003661 * t_c)
    vapour_pa = rh_pct / 100 * saturation_pressure_pa(t_c)
    return 1 + n_tp - (292.75 / (t_c + 273.15)) * vapour_pa * (3.7345 - 0.0401 * sigma2) * 1e-10


def air_correction_factor(
    t_c: float,
    p_pa: float,
    rh_pct: float,
    reference_index: float = 1.0,
    wavelength_nm: float = 633.0,
    co2_ppm: float = 450.0,
) -> float:
    """The factor n_ref/n (dimensionless) by which a reading computed for the index
    `reference_index` (1.0: the instrument reports vacuum lengths) must be multiplied to give the
    length in air at t_c (°C), p_pa (Pa), rh_pct (%). Slightly below 1 for a vacuum reading."""
    return reference_index / refractive_index(t_c, p_pa, rh_pct, wavelength_nm, co2_ppm)


def air_correction_um(position_mm: float, factor: float) -> float:
    """The air correction, µm, to add to a reading of position_mm (mm from the laser datum),
    given the factor from `air_correction_factor`."""
    return position_mm * (factor - 1) * 1000.0


def thermal_normalisation_um(position_mm: float, material_temp_c: float, alpha_ppm_per_k: float) -> float:
    """The correction, µm, to add to a length of position_mm (mm from the laser datum) measured on
    material at material_temp_c (°C) with expansion coefficient alpha_ppm_per_k (ppm/K) so that it
    becomes the length at 20 °C. Linear in the temperature difference (the quadratic term is
    below 1e-9 of the length for |ΔT| < 10 K)."""
    delta_k = material_temp_c - REFERENCE_TEMPERATURE_C
    return -position_mm * alpha_ppm_per_k * 1e-6 * delta_k * 1000.0


def apply_corrections_mm(raw_position_mm: float, air_um: float, thermal_um: float) -> float:
    """The corrected position, mm, from the raw reading (mm) and the two stored corrections (µm)."""
    return raw_position_mm + (air_um + thermal_um) / 1000.0


def undo_corrections_mm(corrected_position_mm: float, air_um: float, thermal_um: float) -> float:
    """The raw reading, mm, back from a corrected position (mm) and the two stored corrections (µm)."""
    return corrected_position_mm - (air_um + thermal_um) / 1000.0

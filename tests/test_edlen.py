"""The refractive index of air against NIST's reference values (reference.md §6)."""

import pytest

from campaign.edlen import (
    air_correction_factor,
    air_correction_um,
    apply_corrections_mm,
    refractive_index,
    saturation_pressure_pa,
    thermal_normalisation_um,
    undo_corrections_mm,
)

NIST_TABLE = [  # t °C, RH %, p Pa, n at 633 nm and 450 ppm CO2
    (20, 0, 101325, 1.000271799),
    (20, 100, 100000, 1.000267394),
    (40, 75, 120000, 1.000299406),
    (50, 0, 100000, 1.000243270),
    (20, 50, 101325, 1.000271374),
]


@pytest.mark.parametrize("t_c, rh_pct, p_pa, n_nist", NIST_TABLE)
def test_refractive_index_matches_nist_table(t_c, rh_pct, p_pa, n_nist):
    assert refractive_index(t_c, p_pa, rh_pct) == pytest.approx(n_nist, abs=1e-9)


def test_saturation_pressure_at_20_c():
    assert saturation_pressure_pa(20.0) == pytest.approx(2339.2, abs=0.1)


def test_sensitivities_to_temperature_pressure_and_humidity():
    n0 = refractive_index(20.0, 101325.0, 50.0)
    per_kelvin_ppm = (refractive_index(21.0, 101325.0, 50.0) - n0) * 1e6
    per_hpa_ppm = (refractive_index(20.0, 101425.0, 50.0) - n0) * 1e6
    per_rh_pct_ppm = (refractive_index(20.0, 101325.0, 60.0) - n0) * 1e6 / 10
    assert per_kelvin_ppm == pytest.approx(-0.95, abs=0.03)
    assert per_hpa_ppm == pytest.approx(0.27, abs=0.01)
    assert per_rh_pct_ppm == pytest.approx(-0.0085, abs=0.001)


def test_co2_raises_the_index_slightly():
    assert refractive_index(20, 101325, 50, co2_ppm=900) > refractive_index(20, 101325, 50)


def test_air_correction_factor_shortens_a_vacuum_reading():
    factor = air_correction_factor(20.0, 101325.0, 50.0)
    assert factor == pytest.approx(1 / 1.000271374, abs=1e-9)
    # 1000 mm read as vacuum length is about 271 µm too long in standard air
    assert air_correction_um(1000.0, factor) == pytest.approx(-271.3, abs=0.1)


def test_air_correction_factor_relative_to_a_reference_index():
    n = refractive_index(22.0, 98000.0, 40.0)
    assert air_correction_factor(22.0, 98000.0, 40.0, reference_index=n) == pytest.approx(1.0, abs=1e-15)


def test_thermal_normalisation_of_steel():
    # 1000 mm of steel (11.5 ppm/K) at 21 °C is 11.5 µm longer than at 20 °C
    assert thermal_normalisation_um(1000.0, 21.0, 11.5) == pytest.approx(-11.5)
    assert thermal_normalisation_um(1000.0, 20.0, 11.5) == 0.0
    assert thermal_normalisation_um(-500.0, 18.0, 11.5) == pytest.approx(-11.5)


def test_corrections_apply_and_undo():
    raw_mm = 812.3456
    air_um = air_correction_um(raw_mm, air_correction_factor(23.0, 99000.0, 45.0))
    thermal_um = thermal_normalisation_um(raw_mm, 21.7, 11.5)
    corrected = apply_corrections_mm(raw_mm, air_um, thermal_um)
    assert corrected == pytest.approx(raw_mm + (air_um + thermal_um) / 1000, abs=1e-12)
    assert undo_corrections_mm(corrected, air_um, thermal_um) == pytest.approx(raw_mm, abs=1e-12)

"""The deviation of a captured point: the reading corrected for the air and normalised to 20 °C
(linear axes, when the config asks), minus the target. Pure code, used by the executor while a
campaign runs and by replay on a recorded raw stream.
"""

from __future__ import annotations

from campaign.edlen import air_correction_factor, air_correction_um, thermal_normalisation_um
from campaign.measure.capture import Captured
from campaign.specs import EnvironmentSpec
from protocols.hardware import InstrumentError
from protocols.units import DEVIATION_SCALE


def corrections_um(spec: EnvironmentSpec, position: float, env: dict[str, float | None]) -> tuple[float, float]:
    """(air correction, material normalisation to 20 °C) in µm for a reading at `position` (mm),
    from the environment `env` (instrument values first, the spec's fixed values otherwise)."""
    air = material = 0.0
    if spec.air_correction == "edlen":
        t = env.get("air_temp_c") if env.get("air_temp_c") is not None else spec.air_temp_c
        p = env.get("air_pressure_hpa") if env.get("air_pressure_hpa") is not None else spec.air_pressure_hpa
        h = env.get("humidity_pct") if env.get("humidity_pct") is not None else spec.humidity_pct
        if t is None or p is None or h is None:
            raise InstrumentError("air correction needs air temperature, pressure and humidity")
        factor = air_correction_factor(t, p * 100.0, h, 1.0, spec.wavelength_nm, spec.co2_ppm)
        air = air_correction_um(position, factor)
    if spec.normalise_to_20c:
        material_temp_c = env.get("material_temp_c")
        if material_temp_c is None:
            raise InstrumentError("normalisation to 20 °C needs the material temperature")
        material = thermal_normalisation_um(position, material_temp_c, spec.expansion_ppm_per_k)
    return air, material


def point_deviation(spec: EnvironmentSpec, unit: str, target: float, got: Captured) -> tuple[float, float, float]:
    """(deviation in µm or arcsec, air correction µm, material correction µm) of a capture on an
    axis in `unit` (mm or deg). The corrections apply to linear lengths only; a rotary axis gets none."""
    if unit == "deg":
        return (got.position - target) * DEVIATION_SCALE["deg"], 0.0, 0.0
    air, material = corrections_um(spec, got.position, got.env)
    corrected = got.position + (air + material) / 1000.0
    return (corrected - target) * DEVIATION_SCALE["mm"], air, material

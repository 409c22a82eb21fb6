"""The axis error model: a set of named effects (reference.md §5).

The simulated machine uses it to decide where the axis really is, and discovery fits it to a
measured point table. Both read and write the same TOML form, one table per effect:

    [effects.linear_scale]
    ppm = -10.5            # µm per m of travel

The deviation e (µm, measured - commanded) is the sum of the effects, evaluated at the commanded
position x (mm), approach direction d (+1 or -1), time t since campaign start (s) and the wait
since arrival at the target, w (s). For a rotary axis read mm as degree and µm as arcsec.
`noise` is not a deterministic effect: its sigmas are used by the simulator only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from campaign.errors import InputError, read_toml
from campaign.specs import SimSpec, plain

EFFECT_PARAMS: dict[str, dict[str, str]] = {
    "linear_scale": {"ppm": "cumulative lead error, µm/m"},
    "backlash": {"b_um": "lost motion at reversal, µm (e = -d*b/2)"},
    "periodic_lead": {"amplitude_um": "amplitude, µm", "period_mm": "period (screw lead), mm",
                      "phase_rad": "phase at x = 0, rad"},
    "thermal_drift": {"growth_ppm": "steady-state screw growth, µm/m", "tau_s": "time constant, s",
                      "pivot_mm": "fixed bearing position, mm"},
    "nonlinear_lead": {"p2_um": "Legendre P2 coefficient, µm", "p3_um": "Legendre P3 coefficient, µm",
                       "start_mm": "start of the travel the polynomials span, mm",
                       "end_mm": "end of that travel, mm"},
    "position_dependent_backlash": {"b0_um": "backlash at x = 0, µm", "k_ppm": "growth along the axis, µm/m"},
    "settling": {"e0_um": "deviation left at arrival, µm (decays)", "tau_s": "settling time constant, s"},
    "local_defect": {"amplitude_um": "peak deviation, µm", "centre_mm": "where it peaks, mm",
                     "width_mm": "full width at half the peak, mm",
                     "direction": "0: both directions; +1 or -1: only when approached from that side, 1"},
    "noise": {"sigma_um": "per-approach positioning scatter, µm",
              "reading_sigma_um": "per-sample instrument noise, µm"},
}
"""Effect name -> parameter name -> meaning with unit. `local_defect` is for the simulated machine
only: discovery's vocabulary (campaign/discovery/effects.py FORMS) leaves it out on purpose, so that
the tests can show what discovery does with an error it has no name for."""

DEFAULTS: dict[str, dict[str, float]] = {
    "periodic_lead": {"phase_rad": 0.0},
    "thermal_drift": {"pivot_mm": 0.0},
    "nonlinear_lead": {"p3_um": 0.0},
    "position_dependent_backlash": {"b0_um": 0.0},
    "local_defect": {"direction": 0.0},
    "noise": {"reading_sigma_um": 0.0},
}


def _legendre(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (3 * u**2 - 1) / 2, (5 * u**3 - 3 * u) / 2


def effect_um(name: str, p: dict[str, float], x: ArrayLike, d: ArrayLike, t: ArrayLike, w: ArrayLike) -> np.ndarray:
    """The deviation one effect adds, µm, at commanded position x (mm), direction d (±1), time t
    (s) and wait since arrival w (s). Arguments broadcast as numpy arrays."""
    x, d, t, w = (np.asarray(a, dtype=float) for a in (x, d, t, w))
    if name == "linear_scale":
        return p["ppm"] * x * 1e-3
    if name == "backlash":
        return -d * p["b_um"] / 2
    if name == "periodic_lead":
        return p["amplitude_um"] * np.sin(2 * np.pi * x / p["period_mm"] + p["phase_rad"])
    if name == "thermal_drift":
        return p["growth_ppm"] * 1e-3 * (x - p["pivot_mm"]) * (1 - np.exp(-t / p["tau_s"]))
    if name == "nonlinear_lead":
        u = 2 * (x - p["start_mm"]) / (p["end_mm"] - p["start_mm"]) - 1
        p2, p3 = _legendre(u)
        return p["p2_um"] * p2 + p["p3_um"] * p3
    if name == "position_dependent_backlash":
        return -d * (p["b0_um"] + p["k_ppm"] * x * 1e-3) / 2
    if name == "settling":
        return -d * p["e0_um"] * np.exp(-w / p["tau_s"])
    if name == "local_defect":
        reach = np.clip((x - p["centre_mm"]) / p["width_mm"], -1.0, 1.0)  # cos² is half at width/2
        side = 1.0 if p["direction"] == 0 else (d == np.sign(p["direction"])).astype(float)
        return p["amplitude_um"] * np.cos(np.pi * reach / 2) ** 2 * side
    if name == "noise":
        return np.zeros(np.broadcast(x, d, t, w).shape)
    raise KeyError(name)


@dataclass
class ErrorModel:
    """Effect name -> its parameters (see EFFECT_PARAMS for names and units)."""

    effects: dict[str, dict[str, float]] = field(default_factory=dict)

    def deviation_um(self, x: ArrayLike, d: ArrayLike, t: ArrayLike = 0.0, w: ArrayLike = math.inf) -> np.ndarray:
        """The deterministic deviation, µm (noise excluded). See `effect_um` for the arguments."""
        total = np.zeros(np.broadcast(np.asarray(x), np.asarray(d), np.asarray(t), np.asarray(w)).shape)
        for name, params in self.effects.items():
            total = total + effect_um(name, params, x, d, t, w)
        return total

    @property
    def sigma_um(self) -> float:
        return self.effects.get("noise", {}).get("sigma_um", 0.0)

    @property
    def reading_sigma_um(self) -> float:
        return self.effects.get("noise", {}).get("reading_sigma_um", 0.0)

    def to_toml(self) -> str:
        lines = []
        for name, params in self.effects.items():
            lines.append(f"[effects.{name}]")
            for key, value in params.items():
                lines.append(f"{key} = {float(value)!r}  # {EFFECT_PARAMS[name][key]}")
            lines.append("")
        return "\n".join(lines)


def model_from_dict(data: dict, where: str, require_all: bool = True) -> ErrorModel:
    """Build a model from a parsed `{"effects": {...}}` table. With `require_all=False` a parameter
    left out is allowed (discovery fits it) and simply absent from the result."""
    effects_table = data.get("effects", {})
    extra = set(data) - {"effects"}
    if extra:
        raise InputError(f"{where}: unknown key '{min(extra)}' (expected [effects.NAME] tables)")
    if not isinstance(effects_table, dict):
        raise InputError(f"{where}: 'effects' must be a table of [effects.NAME] tables")
    effects: dict[str, dict[str, float]] = {}
    for name, params in effects_table.items():
        if name not in EFFECT_PARAMS:
            raise InputError(f"{where}: unknown effect 'effects.{name}' (known: {', '.join(EFFECT_PARAMS)})")
        if not isinstance(params, dict):
            raise InputError(f"{where}: 'effects.{name}' must be a table")
        merged = dict(DEFAULTS.get(name, {}))
        for key, value in params.items():
            if key not in EFFECT_PARAMS[name]:
                raise InputError(f"{where}: unknown key 'effects.{name}.{key}' "
                                 f"(known: {', '.join(EFFECT_PARAMS[name])})")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(f"{where}: 'effects.{name}.{key}' must be a finite number")
            merged[key] = float(value)
        missing = [k for k in EFFECT_PARAMS[name] if k not in merged]
        if require_all and missing:
            raise InputError(f"{where}: 'effects.{name}' is missing '{missing[0]}'")
        if name == "local_defect" and "direction" in merged and merged["direction"] not in (-1.0, 0.0, 1.0):
            raise InputError(f"{where}: 'effects.local_defect.direction' must be 0, 1 or -1")
        for key in ("period_mm", "tau_s", "width_mm"):
            if key in merged and merged[key] <= 0:
                raise InputError(f"{where}: 'effects.{name}.{key}' must be > 0")
        if name == "nonlinear_lead" and {"start_mm", "end_mm"} <= set(merged) \
                and merged["end_mm"] <= merged["start_mm"]:
            raise InputError(f"{where}: 'effects.{name}.end_mm' must be > start_mm")
        if name == "noise" and any(v < 0 for v in merged.values()):
            raise InputError(f"{where}: 'effects.noise' sigmas must be >= 0")
        effects[name] = merged
    return ErrorModel(effects)


def read_model(path: str | Path, require_all: bool = True) -> ErrorModel:
    """Read a model TOML file; InputError with the file and key on any problem."""
    return model_from_dict(read_toml(path, "a model TOML file"), str(path), require_all)


SHIPPED_MODELS = Path(__file__).resolve().parent.parent / "data" / "models"
"""The error models shipped with axiscal (data/models/NAME.toml): `[sim] model = "NAME"` names one,
so that a config copied anywhere still finds it."""


def is_model_name(value: str) -> bool:
    """Whether `[sim] model = value` names a shipped model (no folder, no .toml) rather than a file."""
    return "/" not in value and "\\" not in value and not value.endswith(".toml")


def model_path(sim: SimSpec) -> Path:
    """The file `[sim] model` names: a shipped model's name (no folder, no .toml: SHIPPED_MODELS), or
    a path (relative to the config's directory). InputError saying it is the simulated machine's
    model file that is missing, and what names the shipped models have."""
    name = sim.model
    shipped = sorted(p.stem for p in SHIPPED_MODELS.glob("*.toml"))
    if is_model_name(name):
        if name not in shipped:
            raise InputError(f"{sim.source}: [sim] model '{name}': no shipped error model of that name "
                             f"(shipped: {', '.join(shipped) or 'none found'}; or give a .toml file)")
        return SHIPPED_MODELS / f"{name}.toml"
    path = Path(sim.base_dir) / name
    if not path.is_file():
        raise InputError(f"{sim.source}: [sim] model: the simulated machine's error model {path} is missing "
                         f"(a path is relative to the config's folder; a shipped model is named without one: "
                         f"{', '.join(shipped)})")
    return path


def sim_model(sim: SimSpec) -> ErrorModel:
    """The simulated machine's error model from a campaign's [sim] spec: its `model` (a shipped
    model's name or a file relative to the config's directory, `model_path`) and/or inline
    [sim.effects]."""
    model = ErrorModel()
    if sim.model:
        model = read_model(model_path(sim))
    if sim.effects is not None:
        inline = model_from_dict({"effects": plain(sim.effects)}, f"{sim.source}: [sim.effects]")
        model.effects.update(inline.effects)
    return model

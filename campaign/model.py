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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from campaign.errors import InputError, read_toml
from campaign.specs import SimSpec, plain

Deviation = Callable[[dict[str, float], np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""An effect's deviation, µm: (its parameters, x mm, d ±1, t s, w s) -> e, broadcast."""


@dataclass(frozen=True)
class Effect:
    """One effect the simulated axis can have: its parameters (name -> meaning with unit), the
    defaults of those that may be left out, the deviation it adds, and whether discovery has it in
    its vocabulary (campaign/discovery/effects.py FORMS) or it is for the simulator only (an error
    discovery must locate without a name for it)."""

    name: str
    params: dict[str, str]
    deviation: Deviation
    defaults: dict[str, float] = field(default_factory=dict)
    simulator_only: bool = False


def _legendre(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (3 * u**2 - 1) / 2, (5 * u**3 - 3 * u) / 2


def _side(p: dict[str, float], d: np.ndarray) -> np.ndarray | float:
    """1 where the effect acts: both directions (direction 0) or only the one approached from."""
    return 1.0 if p.get("direction", 0.0) == 0 else (d == np.sign(p["direction"])).astype(float)


def _bow(p: dict[str, float], x: np.ndarray) -> np.ndarray:
    p2, p3 = _legendre(2 * (x - p["start_mm"]) / (p["end_mm"] - p["start_mm"]) - 1)
    return p["p2_um"] * p2 + p["p3_um"] * p3


def _defect(p: dict[str, float], x: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A raised cosine, full width at half height width_mm, its two sides stretched by 1 ± skew, and
    growing linearly in time by growth_per_h of its size per hour."""
    skew = p.get("skew", 0.0)
    half = np.where(x < p["centre_mm"], 1 - skew, 1 + skew) * p["width_mm"]
    reach = np.clip((x - p["centre_mm"]) / half, -1.0, 1.0)  # cos² is half at width/2
    grown = 1 + p.get("growth_per_h", 0.0) * t / 3600
    return p["amplitude_um"] * np.cos(np.pi * reach / 2) ** 2 * _side(p, d) * grown


def _step(p: dict[str, float], x: np.ndarray, d: np.ndarray) -> np.ndarray:
    """A rise of height_um centred at at_mm over rise_mm (a smooth step: 0 before, height after)."""
    u = np.clip((x - p["at_mm"]) / p["rise_mm"] + 0.5, 0.0, 1.0)
    return p["height_um"] * (3 * u**2 - 2 * u**3) * _side(p, d)


def _partial_wave(p: dict[str, float], x: np.ndarray) -> np.ndarray:
    inside = (x >= p["start_mm"]) & (x <= p["end_mm"])
    return p["amplitude_um"] * np.sin(2 * np.pi * x / p["period_mm"] + p["phase_rad"]) * inside


EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("linear_scale", {"ppm": "cumulative lead error, µm/m"},
           lambda p, x, d, t, w: p["ppm"] * x * 1e-3),
    Effect("backlash", {"b_um": "lost motion at reversal, µm (e = -d*b/2)"},
           lambda p, x, d, t, w: -d * p["b_um"] / 2),
    Effect("periodic_lead", {"amplitude_um": "amplitude, µm", "period_mm": "period (screw lead), mm",
                             "phase_rad": "phase at x = 0, rad"},
           lambda p, x, d, t, w: p["amplitude_um"] * np.sin(2 * np.pi * x / p["period_mm"] + p["phase_rad"]),
           {"phase_rad": 0.0}),
    Effect("thermal_drift", {"growth_ppm": "steady-state screw growth, µm/m", "tau_s": "time constant, s",
                             "pivot_mm": "fixed bearing position, mm"},
           lambda p, x, d, t, w: p["growth_ppm"] * 1e-3 * (x - p["pivot_mm"]) * (1 - np.exp(-t / p["tau_s"])),
           {"pivot_mm": 0.0}),
    Effect("nonlinear_lead", {"p2_um": "Legendre P2 coefficient, µm", "p3_um": "Legendre P3 coefficient, µm",
                              "start_mm": "start of the travel the polynomials span, mm",
                              "end_mm": "end of that travel, mm"},
           lambda p, x, d, t, w: _bow(p, x), {"p3_um": 0.0}),
    Effect("position_dependent_backlash", {"b0_um": "backlash at x = 0, µm", "k_ppm": "growth along the axis, µm/m"},
           lambda p, x, d, t, w: -d * (p["b0_um"] + p["k_ppm"] * x * 1e-3) / 2, {"b0_um": 0.0}),
    Effect("settling", {"e0_um": "deviation left at arrival, µm (decays)", "tau_s": "settling time constant, s"},
           lambda p, x, d, t, w: -d * p["e0_um"] * np.exp(-w / p["tau_s"])),
    Effect("local_defect", {"amplitude_um": "peak deviation, µm", "centre_mm": "where it peaks, mm",
                            "width_mm": "full width at half the peak, mm",
                            "direction": "0: both directions; +1 or -1: only when approached from that side, 1",
                            "skew": "the side above the centre is 1 + skew times as wide, the side below "
                                    "1 - skew (-0.9 to 0.9), 1",
                            "growth_per_h": "growth of the size in time, a share of it per hour, 1/h"},
           lambda p, x, d, t, w: _defect(p, x, d, t), {"direction": 0.0, "skew": 0.0, "growth_per_h": 0.0},
           simulator_only=True),
    Effect("second_local_defect", {"amplitude_um": "peak deviation, µm", "centre_mm": "where it peaks, mm",
                                   "width_mm": "full width at half the peak, mm",
                                   "direction": "0: both directions; +1 or -1: only when approached from that "
                                                "side, 1",
                                   "skew": "as local_defect's, 1", "growth_per_h": "as local_defect's, 1/h"},
           lambda p, x, d, t, w: _defect(p, x, d, t), {"direction": 0.0, "skew": 0.0, "growth_per_h": 0.0},
           simulator_only=True),
    Effect("local_step", {"height_um": "the deviation after the step less before it, µm",
                          "at_mm": "the middle of the rise, mm", "rise_mm": "the length of the rise, mm",
                          "direction": "0: both directions; +1 or -1: only when approached from that side, 1"},
           lambda p, x, d, t, w: _step(p, x, d), {"direction": 0.0}, simulator_only=True),
    Effect("partial_wave", {"amplitude_um": "amplitude, µm", "period_mm": "period, mm",
                            "phase_rad": "phase at x = 0, rad", "start_mm": "where the wave starts, mm",
                            "end_mm": "where it ends, mm"},
           lambda p, x, d, t, w: _partial_wave(p, x), {"phase_rad": 0.0}, simulator_only=True),
    Effect("linear_drift", {"rate_ppm_per_h": "slope change per hour, µm/m per h",
                            "pivot_mm": "where the slope pivots, mm"},
           lambda p, x, d, t, w: p["rate_ppm_per_h"] * 1e-3 * (x - p["pivot_mm"]) * t / 3600,
           {"pivot_mm": 0.0}),
    Effect("noise", {"sigma_um": "per-approach positioning scatter, µm",
                     "reading_sigma_um": "per-sample instrument noise, µm"},
           lambda p, x, d, t, w: np.zeros(np.broadcast(x, d, t, w).shape), {"reading_sigma_um": 0.0}),
)}
"""Effect name -> the effect. The ones marked simulator_only are left out of discovery's
vocabulary on purpose, so that the tests can show what discovery does with an error it has no name
for (it must locate it)."""

EFFECT_PARAMS: dict[str, dict[str, str]] = {name: e.params for name, e in EFFECTS.items()}
"""Effect name -> parameter name -> meaning with unit."""
DEFAULTS: dict[str, dict[str, float]] = {name: e.defaults for name, e in EFFECTS.items() if e.defaults}
"""Effect name -> the parameters that may be left out and their values."""
SHAPE_LIMITS = {"skew": (-0.9, 0.9)}
"""Parameters with a bounded range (checked when a model is read)."""


def effect_um(name: str, p: dict[str, float], x: ArrayLike, d: ArrayLike, t: ArrayLike, w: ArrayLike) -> np.ndarray:
    """The deviation one effect adds, µm, at commanded position x (mm), direction d (±1), time t
    (s) and wait since arrival w (s). Arguments broadcast as numpy arrays."""
    x, d, t, w = (np.asarray(a, dtype=float) for a in (x, d, t, w))
    return np.asarray(EFFECTS[name].deviation(p, x, d, t, w), dtype=float) * np.ones(np.broadcast(x, d, t, w).shape)


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
        if "direction" in merged and merged["direction"] not in (-1.0, 0.0, 1.0):
            raise InputError(f"{where}: 'effects.{name}.direction' must be 0, 1 or -1")
        for key, (low, high) in SHAPE_LIMITS.items():
            if key in merged and not low <= merged[key] <= high:
                raise InputError(f"{where}: 'effects.{name}.{key}' must be between {low:g} and {high:g}")
        for key in ("period_mm", "tau_s", "width_mm", "rise_mm"):
            if key in merged and merged[key] <= 0:
                raise InputError(f"{where}: 'effects.{name}.{key}' must be > 0")
        if name in ("nonlinear_lead", "partial_wave") and {"start_mm", "end_mm"} <= set(merged) \
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

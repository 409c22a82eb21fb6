"""The axis error model: a set of named effects (reference.md §5), each defined in its own module
of the effects' registry (campaign/effects/), which this module reads and nothing else.

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

from campaign.effects import RegistryView
from campaign.effects.base import Effect
from campaign.errors import InputError, read_toml
from campaign.specs import SimSpec, plain

EFFECTS: RegistryView[Effect] = RegistryView(lambda e: e if e.simulated else None)
"""Effect name -> the effect, for every registered effect the simulated machine has (campaign/effects/,
one module each: its parameters, defaults, the values a model file may give, its deviation). The
ones without a least-squares form (Effect.simulator_only) are left out of discovery's vocabulary on
purpose, so that the tests can show what discovery does with an error it has no name for (it must
locate it)."""

EFFECT_PARAMS: RegistryView[dict[str, str]] = RegistryView(lambda e: e.params if e.simulated else None)
"""Effect name -> parameter name -> meaning with unit."""
DEFAULTS: RegistryView[dict[str, float]] = RegistryView(lambda e: e.defaults if e.simulated and e.defaults else None)
"""Effect name -> the parameters that may be left out and their values."""


def effect_um(name: str, p: dict[str, float], x: ArrayLike, d: ArrayLike, t: ArrayLike, w: ArrayLike) -> np.ndarray:
    """The deviation one effect adds, µm, at commanded position x (mm), direction d (±1), time t
    (s) and wait since arrival w (s). Arguments broadcast as numpy arrays."""
    x, d, t, w = (np.asarray(a, dtype=float) for a in (x, d, t, w))
    deviation = EFFECTS[name].deviation
    assert deviation is not None  # EFFECTS holds the simulated effects only
    values = np.asarray(deviation(p, x, d, t, w), dtype=float)
    shape = np.broadcast(x, d, t, w).shape
    # an effect that ignores some arguments is spread to their shape (the simulator's one point a tick
    # is already the shape: no copy)
    return values if values.shape == shape else values * np.ones(shape)


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

    def deviation_at(self, x: float, d: float, t: float, w: float) -> float:
        """deviation_um at one point, µm: the simulator's call at every tick, on Python floats (the
        same operations in the same order, without deviation_um's arrays and broadcasting)."""
        total = 0.0
        for name, params in self.effects.items():
            deviation = EFFECTS[name].deviation
            assert deviation is not None  # EFFECTS holds the simulated effects only
            total = total + float(deviation(params, x, d, t, w))  # type: ignore[arg-type]
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
        wrong = EFFECTS[name].errors(merged)  # the values its module allows
        if wrong:
            raise InputError(f"{where}: {wrong}")
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

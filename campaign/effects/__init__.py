"""The effects an axis can have, one module each, in one registry (docs/error-model.md).

Every module of this package but `base` defines `EFFECT`, an `Effect` (campaign/effects/base.py):
its parameters with their units and the values a model file may give, the deviation the simulated
machine adds, the least-squares form discovery fits (with its shape grid and documented physical
ranges), its rivals and how to tell them apart, and its part of a follow-up. The modules are found
when this package is imported: adding an effect is adding one module (its test, its doc).

The simulator (through campaign.model) and discovery read the same objects, and only through this
registry. An effect without a form is the simulator's only (discovery has no name for it, on
purpose); one without a deviation is discovery's only (`environment`).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterator, Mapping
from typing import TypeVar

from campaign.effects.base import Effect, EffectForm

_REGISTRY: dict[str, Effect] = {}

V = TypeVar("V")


def register(effect: Effect) -> Effect:
    """Add an effect to the registry, listed by its `order`; ValueError if its name is taken."""
    if effect.name in _REGISTRY:
        raise ValueError(f"an effect named {effect.name} is registered already")
    ranked = sorted([*_REGISTRY.values(), effect], key=lambda e: e.order)
    _REGISTRY.clear()
    _REGISTRY.update((e.name, e) for e in ranked)
    return effect


def unregister(name: str) -> None:
    """Take an effect out of the registry (a test's own effect, when the test ends)."""
    del _REGISTRY[name]


def effect(name: str) -> Effect:
    """The registered effect of that name; KeyError if there is none."""
    return _REGISTRY[name]


def effects() -> tuple[Effect, ...]:
    """Every registered effect, in their order."""
    return tuple(_REGISTRY.values())


class RegistryView(Mapping[str, V]):
    """A live read-only mapping over the registry: effect name -> what `pick` takes of it, for the
    effects where that is not None (an effect registered later is in it at once)."""

    def __init__(self, pick: Callable[[Effect], V | None]) -> None:
        self._pick = pick

    def __getitem__(self, name: str) -> V:
        found = _REGISTRY.get(name)
        value = None if found is None else self._pick(found)
        if value is None:
            raise KeyError(name)
        return value

    def __iter__(self) -> Iterator[str]:
        return (e.name for e in _REGISTRY.values() if self._pick(e) is not None)

    def __len__(self) -> int:
        return sum(1 for _ in self)


REGISTRY: RegistryView[Effect] = RegistryView(lambda e: e)
"""Effect name -> the registered effect (live)."""


def _load() -> None:
    for module in pkgutil.iter_modules(__path__):
        if module.name != "base":
            register(importlib.import_module(f"{__name__}.{module.name}").EFFECT)


_load()

__all__ = ["REGISTRY", "Effect", "EffectForm", "RegistryView", "effect", "effects", "register", "unregister"]

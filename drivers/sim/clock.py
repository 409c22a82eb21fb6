"""Simulated time for the simulated machine.

`SimClock.sleep(dt)` advances simulated time by dt seconds and lets every part of the simulated
machine (PLC scan, interferometer output) catch up, in the order they were attached. With
`speed=None` no real time passes; with `speed=N` the clock also really waits dt/N seconds, so a
campaign runs N times faster than real time (slow enough to interrupt by hand).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

Listener = Callable[[float], None]
"""Called with the new simulated time, s, after each advance."""


class ListeningClock(Protocol):
    """A clock parts can listen to: the simulated clock, or LinuxCNC's wall clock (drivers/clock.py)."""

    def attach(self, listener: Listener) -> None: ...
    def detach(self, listener: Listener) -> None: ...
    def now(self) -> float: ...


class SimClock:
    """A clock whose time only moves when someone sleeps. Times in s, starting at `start_s`."""

    def __init__(self, start_s: float = 0.0, speed: float | None = None):
        if speed is not None and speed <= 0:
            raise ValueError("speed must be > 0")
        self._t = float(start_s)
        self.speed = speed
        self._listeners: list[Listener] = []

    def attach(self, listener: Listener) -> None:
        """Call `listener(t)` after every advance of simulated time."""
        self._listeners.append(listener)

    def detach(self, listener: Listener) -> None:
        if listener in self._listeners:
            self._listeners.remove(listener)

    def now(self) -> float:
        return self._t

    def sleep(self, seconds: float) -> None:
        if seconds <= 0:
            return
        if self.speed is not None:
            time.sleep(seconds / self.speed)
        self._t += seconds
        for listener in list(self._listeners):
            listener(self._t)

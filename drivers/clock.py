"""The real-time clock used on real hardware. The simulated clock is in drivers/sim/clock.py."""

import time
from collections.abc import Callable


class RealClock:
    """Wall time: `now()` is time.monotonic() in s, `sleep(s)` really waits."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class ListenedClock:
    """Wall time from 0 at creation, s; after every sleep the attached listeners get the new time
    (the simulated laser beside a real-time controller emits its readings from there)."""

    def __init__(self) -> None:
        self._start = time.monotonic()
        self._listeners: list[Callable[[float], None]] = []

    def attach(self, listener: Callable[[float], None]) -> None:
        self._listeners.append(listener)

    def detach(self, listener: Callable[[float], None]) -> None:
        if listener in self._listeners:
            self._listeners.remove(listener)

    def now(self) -> float:
        return time.monotonic() - self._start

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)
        t = self.now()
        for listener in list(self._listeners):
            listener(t)

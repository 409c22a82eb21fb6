"""The real-time clock used on real hardware. The simulated clock is in drivers/sim/clock.py."""

import time


class RealClock:
    """Wall time: `now()` is time.monotonic() in s, `sleep(s)` really waits."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

"""A simulated laser interferometer behind a pseudo-terminal, for the real serial driver to open.

The simulated machine supplies `measure(t)`: a dict with `position` (axis unit, mm or deg) and
optionally `signal_pct` (%, default 100), `air_temp_c` (°C), `air_pressure_hpa` (hPa),
`humidity_pct` (% RH) and `material_temp_c` (°C) at simulated time t (s).

Stream mode: attached to the SimClock, it writes one line per sample instant k/rate_hz that passed
since the last advance. Writes never block; a line the pty cannot take is dropped and counted in
`dropped_lines`, like an instrument whose output buffer overflows. Query mode: a daemon thread
answers every request (`fmt.request`) with the reading at `clock.now()`.

Fault hooks: `beam_break`, `inject_garbage`, `split_next_line`, `disappear`.
"""

from __future__ import annotations

import math
import os
import select
import threading
import tty
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from drivers.sim.clock import ListeningClock
from drivers.sim.scan_streams import InstrumentClock
from protocols.hardware import Reading
from protocols.serial_line import LineFormat, format_line

Measure = Callable[[float], dict[str, Any]]

_EPSILON_S = 1e-9
"""Sample instants up to this much later than the clock still count as passed, s."""


class SimInterferometer:
    """Writes readings in format fmt to a pty; `port_name` is the device to open with pyserial."""

    def __init__(
        self,
        clock: ListeningClock,
        measure: Measure,
        fmt: LineFormat | None = None,
        rate_hz: float = 10.0,
        mode: str = "stream",
        own_clock: InstrumentClock | None = None,
        seed: int = 0,
    ):
        if mode not in ("stream", "query"):
            raise ValueError(f"mode must be 'stream' or 'query', not {mode!r}")
        if not rate_hz > 0:
            raise ValueError("rate_hz must be > 0")
        self.clock = clock
        self.measure = measure
        self.fmt = fmt or LineFormat()
        self.rate_hz = rate_hz
        self.mode = mode
        self.dropped_lines = 0
        """Lines the pty could not take (stream mode)."""
        self._beam_breaks: list[tuple[float, float]] = []
        self._pending_garbage = b""
        self._split_next = False
        self._held_back = b""
        self._lock = threading.Lock()  # serialises writes to the master between clock and thread

        self._master_fd, self._slave_fd = os.openpty()
        tty.setraw(self._slave_fd)
        os.set_blocking(self._master_fd, False)
        self.port_name = os.ttyname(self._slave_fd)
        self._open = True
        self._thread: threading.Thread | None = None
        self.own_clock = own_clock
        """Stream mode: the instrument's own sample clock (its stamps, their jitter, the latency to
        the PC); None: it samples and stamps on the controller's clock, with no latency."""
        self._rng = np.random.default_rng([seed, 33])
        self._in_flight: list[tuple[float, bytes]] = []  # (arrival at the PC s, line)
        if mode == "stream":
            start = clock.now() if own_clock is None else float(own_clock.reading(clock.now()))
            self._next_sample = math.floor(start * rate_hz + _EPSILON_S) + 1
            clock.attach(self._on_advance)
        else:
            self._wake_r, self._wake_w = os.pipe()
            self._thread = threading.Thread(
                target=self._answer_queries, name="sim-interferometer", daemon=True
            )
            self._thread.start()

    # -- fault hooks ------------------------------------------------------------------------

    def beam_break(self, start_s: float, end_s: float) -> None:
        """The beam is interrupted from start_s to end_s (sim time, s): signal 0 %, beam not OK."""
        self._beam_breaks.append((start_s, end_s))

    def inject_garbage(self, text: str) -> None:
        """Write text (latin-1) as raw bytes just before the next line."""
        self._pending_garbage += text.encode("latin-1")

    def split_next_line(self) -> None:
        """Write only the first half of the next line now and the rest just before the line after it,
        so the driver sees a partial line in between."""
        self._split_next = True

    def disappear(self) -> None:
        """The instrument is unplugged: the pty is closed and the port vanishes."""
        self.close()

    # -- readings ---------------------------------------------------------------------------

    def reading_at(self, t: float) -> Reading:
        """The reading the instrument gives at sim time t (s)."""
        values = dict(self.measure(t))
        if any(start <= t <= end for start, end in self._beam_breaks):
            values["signal_pct"] = 0.0
        signal_pct = float(values.pop("signal_pct", 100.0))
        position = float(values.pop("position"))
        return Reading(
            time_s=t,
            position=position,
            signal_ok=signal_pct >= self.fmt.signal_threshold_pct,
            signal_pct=signal_pct,
            **values,
        )

    def _on_advance(self, t: float) -> None:
        if self.own_clock is not None:
            self._on_advance_own_clock(t, self.own_clock)
            return
        while self._open and self._next_sample / self.rate_hz <= t + _EPSILON_S:
            sample_t = self._next_sample / self.rate_hz
            self._next_sample += 1
            self._send(format_line(self.reading_at(sample_t), self.fmt).encode("ascii"))

    def _on_advance_own_clock(self, t: float, own: InstrumentClock) -> None:
        """Samples at the instrument clock's ticks up to t (s, controller time), each measured
        where the axis was when it was really taken and stamped with the instrument's time; each
        reaches the pty its latency later."""
        while self._open:
            stamp = self._next_sample / self.rate_hz
            taken = float(own.controller_time(stamp))
            if taken > t + _EPSILON_S:
                break
            self._next_sample += 1
            if own.sample_jitter_s:
                taken = min(t, taken + float(self._rng.normal(0.0, own.sample_jitter_s)))
            reading = replace(self.reading_at(taken), time_s=stamp)
            self._in_flight.append((taken + own.latency_s, format_line(reading, self.fmt).encode("ascii")))
        while self._open and self._in_flight and self._in_flight[0][0] <= t + _EPSILON_S:
            self._send(self._in_flight.pop(0)[1])

    def _send(self, line: bytes) -> None:
        data = self._pending_garbage + self._held_back + line
        self._pending_garbage = self._held_back = b""
        if self._split_next:
            self._split_next = False
            half = len(data) - len(line) // 2
            data, self._held_back = data[:half], data[half:]
        with self._lock:
            if not self._open:
                return
            try:
                written = os.write(self._master_fd, data)
            except BlockingIOError:
                written = 0
        if written < len(data):
            self.dropped_lines += 1

    def _answer_queries(self) -> None:
        request = self.fmt.request.encode("ascii")
        received = b""
        while True:
            ready, _, _ = select.select([self._master_fd, self._wake_r], [], [])
            if self._wake_r in ready:
                return
            try:
                received += os.read(self._master_fd, 4096)
            except BlockingIOError:
                continue
            except OSError:
                return
            while request in received:
                _, _, received = received.partition(request)
                self._send(format_line(self.reading_at(self.clock.now()), self.fmt).encode("ascii"))

    # -- lifetime ---------------------------------------------------------------------------

    def close(self) -> None:
        """Stop writing and answering, and close the pty. Safe to call twice."""
        with self._lock:
            if not self._open:
                return
            self._open = False
        if self._thread is not None:
            os.write(self._wake_w, b"x")
            self._thread.join()
            os.close(self._wake_r)
            os.close(self._wake_w)
        else:
            self.clock.detach(self._on_advance)
        os.close(self._master_fd)
        os.close(self._slave_fd)

"""Device notifications of the simulated PLC, sent as a TwinCAT runtime sends them.

A client asks for a notification (ADS Add Device Notification) on any range it could read: index
group, offset and length, a transmission mode, a cycle time and a maximum delay. The PLC then
pushes ADS Device Notification packets (command 8) to that client over its own TCP connection:

- cyclic (mode 3): the value is sampled every cycle time; on change (mode 4): it is sampled every
  cycle time and kept only when it differs from the last one kept. Sampling happens at the PLC's
  scans (simulated time): a cycle time of 0, or shorter than the time between two scans, samples
  at every scan;
- the first sample is the value at the time of the request;
- a sample is sent at the latest `max delay` after it was taken: samples wait while the oldest one
  waiting is younger than that, then go together, one stamp per sample time (a delay of 0 sends
  each at the scan that took it). A notification's samples go earlier when the values waiting
  reach WAITING_LIMIT_BYTES, so a long delay (up to 2³² × 100 ns, 429 s) on a large range holds
  no more than that. A client's due samples of several notifications share a packet;
- the times on the wire are in 100 ns, as pyads, ads-client and Beckhoff's AdsLib send them
  (Beckhoff's protocol page says ms; the clients, tested against real PLCs, send 100 ns);
- the timestamp of a sample is a Windows FILETIME: the wall-clock time the PLC was created plus the
  simulated time since its start;
- a notification lives until the client deletes it (ADS Delete Device Notification) or its
  connection ends.

The table holds no lock of its own: the PLC calls it under the lock that guards its memory, and
sends what it returns after releasing that lock.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

CYCLIC, ON_CHANGE = 3, 4
"""ADSTRANS_SERVERCYCLE and ADSTRANS_SERVERONCHA, the transmission modes served."""
DEVICE_NOTIFICATION = 8
NOTIFICATION_FLAGS = 0x0004
"""AMS state flags of a notification: an ADS command sent as a request, over TCP."""
TICKS_PER_S = 10_000_000
"""The wire's time unit is 100 ns."""
FILETIME_AT_UNIX_EPOCH = 116_444_736_000_000_000
"""100-ns intervals from 1601-01-01 (FILETIME's origin) to 1970-01-01."""
TIME_TOLERANCE_S = 1e-9
"""Simulated times this close count as equal (scan times are sums of float steps)."""
WAITING_LIMIT_BYTES = 64 * 1024
"""A notification's samples go, whatever their maximum delay, once the values waiting hold this
many bytes (at least one sample)."""


class NotificationSink(Protocol):
    """Where a client's notification packets go: its TCP connection."""

    def send_notification(self, packet: bytes) -> None: ...


@dataclass
class Subscription:
    """One notification of one client: what to sample (group, offset, length in bytes), how
    (on_change, cycle_s and max_delay_s in s), and the AMS addresses of its packets (`route`: the
    client's Net ID and port, then the PLC's, 16 bytes)."""

    handle: int
    sink: NotificationSink
    route: bytes
    group: int
    offset: int
    length: int
    on_change: bool
    cycle_s: float
    max_delay_s: float
    next_check_s: float
    last: bytes
    waiting: list[tuple[float, bytes]] = field(default_factory=list)
    """Samples taken and not sent yet: (simulated time s, value)."""

    def due(self, t_s: float) -> bool:
        """The waiting samples go at simulated time t_s: the oldest waited the maximum delay, or
        they reached WAITING_LIMIT_BYTES."""
        return bool(self.waiting) and (t_s - self.waiting[0][0] >= self.max_delay_s
                                       or len(self.waiting) * self.length >= WAITING_LIMIT_BYTES)


class Notifications:
    """Every client's notifications on one PLC. `epoch_s`: the wall-clock time (s since 1970) that
    simulated time 0 stands for."""

    def __init__(self, epoch_s: float):
        self.epoch_s = epoch_s
        self._epoch_ticks = round(epoch_s * TICKS_PER_S)
        self._subscriptions: dict[int, Subscription] = {}
        self._next_handle = 1

    def __len__(self) -> int:
        return len(self._subscriptions)

    def add(self, sink: NotificationSink, route: bytes, group: int, offset: int, length: int, mode: int,
            cycle_ticks: int, max_delay_ticks: int, value: bytes, t_s: float) -> int:
        """A new notification whose first sample is `value` at simulated time t_s; its handle."""
        handle, self._next_handle = self._next_handle, self._next_handle + 1
        cycle_s = cycle_ticks / TICKS_PER_S
        self._subscriptions[handle] = Subscription(
            handle, sink, route, group, offset, length, mode == ON_CHANGE, cycle_s, max_delay_ticks / TICKS_PER_S,
            next_check_s=t_s + cycle_s, last=value, waiting=[(t_s, value)])
        return handle

    def count(self, sink: NotificationSink) -> int:
        """How many notifications the client holds."""
        return sum(1 for s in self._subscriptions.values() if s.sink is sink)

    def delete(self, handle: int, sink: NotificationSink) -> bool:
        """Delete the client's notification `handle`; False when it has none of that handle."""
        subscription = self._subscriptions.get(handle)
        if subscription is None or subscription.sink is not sink:
            return False
        del self._subscriptions[handle]
        return True

    def drop(self, sink: NotificationSink) -> None:
        """Delete every notification of a client whose connection ended."""
        for handle in [h for h, s in self._subscriptions.items() if s.sink is sink]:
            del self._subscriptions[handle]

    def collect(self, t_s: float, read: Callable[[int, int, int], bytes] | None) -> list[tuple[NotificationSink, bytes]]:
        """Sample what is due at simulated time t_s with `read` (group, offset, length -> bytes;
        None: sample nothing, only send what waited long enough), and the packets now due, one
        per client."""
        if read is not None:
            for s in self._subscriptions.values():
                if t_s >= s.next_check_s - TIME_TOLERANCE_S:
                    self._sample(s, t_s, read)
        due: dict[int, list[tuple[Subscription, float, bytes]]] = {}
        sinks: dict[int, tuple[NotificationSink, bytes]] = {}
        for s in self._subscriptions.values():
            if s.due(t_s):
                key = id(s.sink)
                sinks.setdefault(key, (s.sink, s.route))
                due.setdefault(key, []).extend((s, at, value) for at, value in s.waiting)
                s.waiting = []
        return [(sinks[key][0], self._packet(sinks[key][1], samples)) for key, samples in due.items()]

    @staticmethod
    def _sample(s: Subscription, t_s: float, read: Callable[[int, int, int], bytes]) -> None:
        if s.cycle_s > 0:  # the next check on the cycle's grid, past t_s
            passed = math.floor((t_s - s.next_check_s) / s.cycle_s + TIME_TOLERANCE_S)
            s.next_check_s += (passed + 1) * s.cycle_s
        try:
            value = read(s.group, s.offset, s.length)
        except Exception:  # noqa: BLE001 (the range is gone, e.g. a released handle: nothing to send)
            return
        if s.on_change and value == s.last:
            return
        s.last = value
        s.waiting.append((t_s, value))

    def _packet(self, route: bytes, samples: list[tuple[Subscription, float, bytes]]) -> bytes:
        """An AMS/TCP packet carrying ADS Device Notification: one stamp per sample time."""
        stamps: dict[float, list[tuple[int, bytes]]] = {}
        for s, at, value in samples:
            stamps.setdefault(at, []).append((s.handle, value))
        body = struct.pack("<I", len(stamps))
        for at in sorted(stamps):
            body += struct.pack("<QI", self.filetime(at), len(stamps[at]))
            body += b"".join(struct.pack("<II", handle, len(value)) + value for handle, value in stamps[at])
        data = struct.pack("<I", len(body)) + body
        ams = route + struct.pack("<HHIII", DEVICE_NOTIFICATION, NOTIFICATION_FLAGS, len(data), 0, 0) + data
        return struct.pack("<HI", 0, len(ams)) + ams

    def filetime(self, t_s: float) -> int:
        """The FILETIME (100 ns since 1601) of simulated time t_s."""
        return FILETIME_AT_UNIX_EPOCH + self._epoch_ticks + round(t_s * TICKS_PER_S)

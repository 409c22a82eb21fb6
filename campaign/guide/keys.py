"""The operator's keys for `axiscal guide`: single keys from the terminal, and Ctrl-C.

`Keys` puts the terminal in cbreak mode (no Enter needed, no echo; Ctrl-C still sends SIGINT) and
reads one key at a time on a background thread; the terminal mode is restored on exit. `CtrlC`
turns SIGINT into an abort, and a second one into an immediate halt.
"""

from __future__ import annotations

import os
import queue
import select
import signal
import termios
import threading
import tty
from collections.abc import Callable
from types import FrameType
from typing import TYPE_CHECKING, Self

from campaign.measure import Control

if TYPE_CHECKING:
    from campaign.guide.dashboard import Dashboard


class Keys:
    """Single keys from terminal `fd` in cbreak mode, read on a daemon thread; the terminal mode is
    restored on exit. Keys go to `on_key`, or to `ask` while a prompt waits for one."""

    def __init__(self, on_key: Callable[[str], None], fd: int = 0):
        self.on_key, self.fd = on_key, fd
        self._answers: queue.Queue[str] | None = None
        self._wake_r, self._wake_w = os.pipe()
        self._saved = termios.tcgetattr(fd)
        self._thread = threading.Thread(target=self._read, name="guide-keys", daemon=True)

    def __enter__(self) -> Self:
        tty.setcbreak(self.fd)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        os.write(self._wake_w, b"x")
        self._thread.join(timeout=1.0)
        termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
        os.close(self._wake_r)
        os.close(self._wake_w)

    def _read(self) -> None:
        while True:
            ready, _, _ = select.select([self.fd, self._wake_r], [], [])
            if self._wake_r in ready:
                return
            key = os.read(self.fd, 1).decode("latin-1").lower()
            answers = self._answers
            if answers is not None:
                answers.put(key)
            else:
                self.on_key(key)

    def ask(self, choices: dict[str, str], control: Control) -> str:
        """Wait for one of the keys in `choices` and return its meaning; "abort" when an abort is
        requested meanwhile (Ctrl-C)."""
        self._answers = queue.Queue()
        try:
            while not control.abort_requested():
                try:
                    key = self._answers.get(timeout=0.1)
                except queue.Empty:
                    continue
                if key in choices:
                    return choices[key]
            return "abort"
        finally:
            self._answers = None


class CtrlC:
    """SIGINT while the axis may move. The first aborts like `a`: the executor halts the axis at its
    next tick (within one sample period, 0.1 s by default), flushes and marks the campaign
    interrupted; the stop record, the summary and the resume line follow. The second only says that
    this is under way: a signal handler must not talk to the controller itself (it would interrupt
    the main thread in the middle of its own exchange with it, or of the simulated PLC's scan, and
    wait on it: a hang) nor raise in the middle of the stop record. A third is the way out when
    something does not stop: KeyboardInterrupt wherever the program is (the record keeps every point
    written; `axiscal resume` continues it). `then`: the handler left in place at the exit, so that a
    Ctrl-C pressed as the campaign ends meets it, not the one before (the guide's, which says and ignores
    it while the summary is written; a second Ctrl-C 50 ms after the first came after the campaign had
    stopped and before the guide held it, and the guide ended with "error: interrupted" and no summary);
    None: the one before."""

    def __init__(self, dashboard: Dashboard, then: Callable[[int, FrameType | None], None] | None = None) -> None:
        self.dashboard, self.count, self.then = dashboard, 0, then

    def __enter__(self) -> Self:
        self.previous = signal.signal(signal.SIGINT, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        signal.signal(signal.SIGINT, self.then or self.previous)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        if self.count == 1:
            self.dashboard.abort("Ctrl-C")
            return
        if self.count == 2:
            self.dashboard.say("second Ctrl-C: already stopping, the axis halts at the next tick; "
                               "the summary and the resume line follow (a third Ctrl-C quits at once)")
            return
        raise KeyboardInterrupt

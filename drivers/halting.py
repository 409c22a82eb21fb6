"""close() as the drivers of a controller axis do it (AdsAxis, EpicsAxis): halt the axis when it
is moving, unless in read-only mode (a dry run commands nothing), then disconnect, once."""

from __future__ import annotations

from protocols.hardware import AxisStatus


class HaltsOnClose:
    """A base giving an axis driver its close(). The driver sets `read_only` and `_closed` (False)
    when it is made, and has status(), halt() and _disconnect()."""

    read_only: bool
    _closed: bool

    def status(self) -> AxisStatus:
        raise NotImplementedError

    def halt(self) -> None:
        raise NotImplementedError

    def _disconnect(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Halt the axis if it is moving (not in read-only mode), then disconnect, also when the
        halt fails; closing again does nothing."""
        if self._closed:
            return
        try:
            if not self.read_only and self.status().busy:
                self.halt()
        finally:
            self._closed = True
            self._disconnect()

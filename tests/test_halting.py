"""close() of the controller axis drivers (drivers/halting.py, shared by AdsAxis and EpicsAxis):
halt when moving unless read-only, disconnect always, once. A stand-in driver records what close()
asked of it (the ADS and EPICS machine tests close the real drivers)."""

import pytest

from drivers.halting import HaltsOnClose
from protocols.hardware import AxisError, AxisStatus


class Recorded(HaltsOnClose):
    def __init__(self, busy: bool, read_only: bool = False, lost: bool = False):
        self.busy, self.read_only, self.lost, self._closed = busy, read_only, lost, False
        self.asked: list[str] = []

    def status(self) -> AxisStatus:
        self.asked.append("status")
        if self.lost:
            raise AxisError("no answer", 0)
        return AxisStatus(busy=self.busy, done=not self.busy, error=False, error_id=0, actual_position=0.0,
                          enabled=True, homed=True)

    def halt(self) -> None:
        self.asked.append("halt")

    def _disconnect(self) -> None:
        self.asked.append("disconnect")


@pytest.mark.parametrize("busy, read_only, asked", [
    (True, False, ["status", "halt", "disconnect"]),
    (False, False, ["status", "disconnect"]),
    (True, True, ["disconnect"]),  # a dry run commands nothing, not even a halt
])
def test_close_halts_a_moving_axis_unless_read_only_then_disconnects_once(busy, read_only, asked):
    axis = Recorded(busy, read_only)
    axis.close()
    axis.close()
    assert axis.asked == asked


def test_close_disconnects_also_when_the_status_read_fails():
    axis = Recorded(True, lost=True)
    with pytest.raises(AxisError):
        axis.close()
    assert axis.asked == ["status", "disconnect"]
    axis.close()
    assert axis.asked == ["status", "disconnect"]

"""AdsAxis with the real pyads client against the loopback ADS test server, SimPLC behind it.

Time is simulated: the tests move the SimClock between status polls, so the PLC scans only when a
test lets time pass. Nothing here depends on wall time.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import pytest

from drivers.ads_axis import AdsAxis
from drivers.factory import serve_on_free_loopback
from drivers.sim.ads_server import SimAdsServer
from drivers.sim.clock import SimClock
from drivers.sim.plc import SimPLC
from protocols import plc_contract
from protocols.hardware import AxisError, AxisStatus
from protocols.plc_contract import CompTable, PlcErrorId

CONTROL = plc_contract.control_symbols(1)
COMP = plc_contract.comp_symbols(1)
POLL_S = 0.05


@dataclass
class Machine:
    clock: SimClock
    plc: SimPLC
    server: SimAdsServer
    axis: AdsAxis


@pytest.fixture
def machine():
    threads_before = threading.active_count()
    clock = SimClock()
    plc = SimPLC(axis=1, max_velocity=50.0, acceleration=200.0)
    clock.attach(plc.scan)
    server = serve_on_free_loopback(plc)  # a loopback address of its own: tests run side by side
    axis = None
    try:
        axis = AdsAxis(server.net_id, server.ip, axis=1, timeout_s=0.5, retry_wait_s=0.05)
        yield Machine(clock, plc, server, axis)
    finally:
        if axis is not None:
            axis.close()
        server.stop()
    assert threading.active_count() == threads_before, "a server thread was left running"


def wait_until_idle(m: Machine, limit_s: float = 30.0) -> AxisStatus:
    """Let simulated time pass in POLL_S steps until the axis is not busy."""
    end = m.clock.now() + limit_s
    while m.clock.now() < end:
        m.clock.sleep(POLL_S)
        status = m.axis.status()
        if not status.busy:
            return status
    raise AssertionError(f"axis still busy after {limit_s} s of simulated time")


@pytest.mark.machine
def test_move_reaches_target_and_reports_done(machine):
    m = machine
    assert m.axis.status() == AxisStatus(False, False, False, 0, 0.0, True, True)
    m.axis.start_move(25.0, 10.0)
    m.clock.sleep(1.0)
    moving = m.axis.status()
    assert moving.busy and not moving.done
    assert 0.0 < moving.actual_position < 25.0
    assert m.plc.arrival_time is None

    status = wait_until_idle(m)
    assert status.done and not status.error and status.error_id == 0
    assert status.actual_position == 25.0
    # sent at t = 0; two 0.05 s ramps at 200 mm/s², 24.5 mm at 10 mm/s
    assert m.plc.arrival_time == pytest.approx(2.55)
    assert m.plc.last_direction == 1

    m.axis.start_move(5.0, 20.0)
    status = wait_until_idle(m)
    assert status.done and status.actual_position == 5.0
    assert m.plc.last_direction == -1


@pytest.mark.machine
def test_injected_drive_error_stops_the_move_and_is_kept_until_reset(machine):
    m = machine
    m.axis.start_move(30.0, 10.0)
    m.clock.sleep(1.0)
    m.plc.inject_error(0x4550)
    status = m.axis.status()
    assert status.error and status.error_id == 0x4550
    assert not status.busy and not status.done
    stopped_at = status.actual_position
    assert 0.0 < stopped_at < 30.0
    m.clock.sleep(1.0)
    assert m.axis.status().actual_position == stopped_at

    with pytest.raises(AxisError) as refused:
        m.axis.start_move(30.0, 10.0)
    assert refused.value.error_id == 0x4550

    m.axis.reset()
    m.clock.sleep(POLL_S)
    assert not m.axis.status().error
    m.axis.start_move(30.0, 10.0)
    status = wait_until_idle(m)
    assert status.done and status.actual_position == 30.0


@pytest.mark.machine
@pytest.mark.parametrize("velocity", [0.0, -1.0, 50.1])
def test_move_with_bad_velocity_is_refused_by_the_plc(machine, velocity):
    m = machine
    m.axis.start_move(10.0, velocity)
    m.clock.sleep(POLL_S)
    status = m.axis.status()
    assert status.error and status.error_id == PlcErrorId.INVALID_VELOCITY
    assert not status.busy and status.actual_position == 0.0


@pytest.mark.machine
def test_move_while_drive_disabled_is_refused_by_the_plc(machine):
    m = machine
    m.plc.enabled = False
    m.clock.sleep(POLL_S)
    assert not m.axis.status().enabled
    m.axis.start_move(10.0, 10.0)
    m.clock.sleep(POLL_S)
    status = m.axis.status()
    assert status.error and status.error_id == PlcErrorId.NOT_ENABLED


@pytest.mark.machine
def test_halt_during_a_move_stops_short_of_the_target(machine):
    m = machine
    m.axis.start_move(40.0, 20.0)
    m.clock.sleep(0.5)
    at_halt = m.axis.status().actual_position
    m.axis.halt()
    status = wait_until_idle(m)
    assert not status.done and not status.error
    assert at_halt < status.actual_position < 40.0
    m.clock.sleep(1.0)
    assert m.axis.status().actual_position == status.actual_position
    m.axis.halt()  # harmless at rest, and twice
    m.clock.sleep(POLL_S)
    assert not m.axis.status().error


@pytest.mark.machine
def test_close_halts_a_moving_axis(machine):
    m = machine
    m.axis.start_move(40.0, 20.0)
    m.clock.sleep(0.5)
    m.axis.close()
    assert m.plc.value(CONTROL["bHalt"].name) is True
    m.clock.sleep(2.0)
    assert m.plc.value(plc_contract.status_symbols(1)["bBusy"].name) is False
    assert m.plc.setpoint_position(m.clock.now()) < 40.0
    with pytest.raises(AxisError):
        m.axis.status()


@pytest.mark.parametrize(
    "name",
    [
        "GVL_Axiscal.astAxes[1].stStatus.bDone",  # status belongs to the PLC
        "GVL_Axiscal.astAxes[2].stControl.bExecute",  # another axis
        "MAIN.bAnything",
    ],
)
@pytest.mark.machine
def test_write_to_a_symbol_outside_the_contract_is_refused(machine, name):
    with pytest.raises(ValueError):
        machine.axis._write(name, True)
    machine.clock.sleep(POLL_S)
    assert machine.axis.status().done is False


@pytest.mark.machine
def test_read_only_mode_reads_status_and_refuses_every_write(machine):
    m = machine
    dry = AdsAxis(m.server.net_id, m.server.ip, axis=1, read_only=True, timeout_s=0.5)
    try:
        assert dry.status().enabled
        for write in (
            lambda: dry.start_move(10.0, 10.0),
            dry.halt,
            dry.reset,
            lambda: dry.write_comp_table(_table()),
        ):
            with pytest.raises(AxisError, match="read-only"):
                write()
        m.clock.sleep(POLL_S)
        assert not m.axis.status().busy
        assert m.plc.value(CONTROL["bHalt"].name) is False
        assert m.plc.value(CONTROL["fPosition"].name) == 0.0
    finally:
        dry.close()


@pytest.mark.machine
def test_status_recovers_after_the_plc_connection_is_lost(machine):
    m = machine
    m.axis.start_move(20.0, 10.0)
    m.clock.sleep(0.5)
    before = m.axis.status()
    m.server.stop()
    m.server.start()
    after = m.axis.status()  # the old TCP connection is dead: only the reconnect gets here
    assert after == before
    m.clock.sleep(POLL_S)
    assert m.axis.status().actual_position > before.actual_position


@pytest.mark.machine
def test_unreachable_plc_raises_axis_error_without_error_id(machine):
    machine.server.stop()
    with pytest.raises(AxisError) as lost:
        machine.axis.status()
    assert lost.value.error_id == 0
    machine.server.start()
    assert machine.axis.status().enabled


def _table(points: int = 11, enabled: bool = True) -> CompTable:
    return CompTable(
        forward=tuple(0.001 * i for i in range(points)),
        reverse=tuple(-0.0005 * i + 0.002 for i in range(points)),
        start=-10.0,
        spacing=2.5,
        overrun=5.0,
        max_rate=0.01,
        max_accel=0.1,
        enabled=enabled,
    )


@pytest.mark.machine
def test_comp_table_write_and_read_back(machine):
    m = machine
    assert m.axis.read_comp_table() is None
    table = _table()
    m.axis.write_comp_table(table)
    assert m.axis.read_comp_table() == table
    assert m.plc.value(COMP["nPoints"].name) == 11
    assert m.plc.value(COMP["bEnable"].name) is True
    assert m.plc.value(COMP["afForward"].name)[11:] == [0.0] * 245

    full = _table(points=plc_contract.MAX_COMP_POINTS, enabled=False)
    m.axis.write_comp_table(full)
    assert m.axis.read_comp_table() == full


@pytest.mark.machine
def test_write_of_the_wrong_size_is_refused_like_twincat_and_the_plc_keeps_scanning(machine):
    """A client that writes 8 bytes into the 2-byte eCommand gets 0x705 (invalid size), as from
    TwinCAT; the variable keeps its value and the PLC goes on answering and moving."""
    import pyads

    m = machine
    name = CONTROL["eCommand"].name
    raw = pyads.Connection(m.server.net_id, 851, m.server.ip)
    raw.open()
    try:
        raw.set_timeout(500)
        handle = raw.get_handle(name)
        with pytest.raises(pyads.ADSError) as refused:
            raw.write_by_name("", 7, pyads.PLCTYPE_LREAL, handle=handle)
        assert refused.value.err_code == 0x705
        raw.release_handle(handle)
        assert m.plc.value(name) == 0
        with pytest.raises(pyads.ADSError) as unknown:
            raw.read_by_name("MAIN.bNoSuchSymbol", pyads.PLCTYPE_BOOL)
        assert unknown.value.err_code == 0x710
    finally:
        raw.close()
    m.clock.sleep(POLL_S)
    m.axis.start_move(5.0, 10.0)
    assert wait_until_idle(m).actual_position == 5.0


@pytest.mark.machine
def test_a_link_that_stays_down_gives_the_hint_once_and_no_library_log_line(machine, capfd):
    """Every failed read used to repeat the whole hint, and the ADS library wrote its own line
    ("<date>+0000 Info: connection closed by remote") to stderr from its receive thread."""
    import time

    machine.axis.status()
    machine.server.stop()
    time.sleep(0.3)  # the library's receive thread sees the closed socket
    messages = []
    for _ in range(3):
        with pytest.raises(AxisError) as lost:
            machine.axis.status()
        messages.append(str(lost.value))
    assert "the usual causes" in messages[0]
    assert all("the usual causes" not in m and "still not answering" in m for m in messages[1:])
    machine.server.start()
    assert machine.axis.status().enabled
    machine.server.stop()
    with pytest.raises(AxisError) as again:
        machine.axis.status()
    assert "the usual causes" in str(again.value)  # a new loss after it answered: said in full again
    machine.server.start()
    assert "connection closed by remote" not in capfd.readouterr().err

"""The real pyserial driver against a pty fed by SimInterferometer (no mocked serial port)."""

import os
import threading

import pytest

from drivers.serial_interferometer import SerialInterferometer
from drivers.sim.clock import SimClock
from drivers.sim.interferometer import SimInterferometer
from protocols.hardware import InstrumentError
from protocols.serial_line import LineFormat


def measure(t: float) -> dict:
    """A slide moving at 10 mm/s in a steady room."""
    return {
        "position": 10.0 * t,
        "signal_pct": 80.0,
        "air_temp_c": 20.5,
        "air_pressure_hpa": 1012.0,
        "humidity_pct": 45.0,
        "material_temp_c": 20.2,
    }


@pytest.fixture
def rig():
    """(clock, sim, driver) factory; everything it makes is closed after the test."""
    made = []

    def make(mode="stream", fmt=None, rate_hz=10.0, timeout_s=2.0, driver_mode=None):
        clock = SimClock()
        sim = SimInterferometer(clock, measure, fmt=fmt, rate_hz=rate_hz, mode=mode)
        made.append(sim)
        driver = SerialInterferometer(sim.port_name, 115200, fmt, driver_mode or mode, timeout_s)
        made.append(driver)
        return clock, sim, driver

    yield make
    for thing in reversed(made):
        thing.close()


@pytest.mark.machine
def test_stream_readings_arrive_as_the_clock_advances(rig):
    clock, sim, driver = rig()
    assert driver.poll() == []
    clock.sleep(1.0)
    readings = driver.poll()
    assert [r.time_s for r in readings] == pytest.approx([0.1 * k for k in range(1, 11)])
    assert [r.position for r in readings] == pytest.approx([1.0 * k for k in range(1, 11)])
    assert all(r.signal_ok and r.signal_pct == 80.0 for r in readings)
    assert readings[0].air_temp_c == 20.5 and readings[0].material_temp_c == 20.2
    assert driver.poll() == []
    clock.sleep(0.05)
    assert driver.poll() == []
    clock.sleep(0.05)
    assert [r.time_s for r in driver.poll()] == pytest.approx([1.1])
    assert driver.skipped_lines == 0 and sim.dropped_lines == 0


@pytest.mark.machine
def test_partial_line_is_kept_until_the_rest_arrives(rig):
    clock, sim, driver = rig()
    sim.split_next_line()
    clock.sleep(0.1)
    assert driver.poll() == []
    clock.sleep(0.1)
    assert [r.time_s for r in driver.poll()] == pytest.approx([0.1, 0.2])
    assert driver.skipped_lines == 0


@pytest.mark.machine
def test_garbage_is_skipped_counted_and_never_returned(rig):
    clock, sim, driver = rig()
    clock.sleep(0.1)
    sim.inject_garbage("\x00\xff#!garbage\r\n")
    sim.inject_garbage("POS,0.15,1.5,80,,,,*00\r\n")  # bad checksum
    clock.sleep(0.1)
    sim.inject_garbage("POS,0.25,2.5,80,,")  # no line end: runs into the next line
    clock.sleep(0.2)
    readings = driver.poll()
    assert [r.time_s for r in readings] == pytest.approx([0.1, 0.2, 0.4])
    assert driver.skipped_lines == 3


@pytest.mark.machine
def test_endless_garbage_without_line_end_is_dropped(rig):
    clock, sim, driver = rig()
    sim.inject_garbage("x" * 3000)
    clock.sleep(0.1)
    assert driver.poll() == []
    assert driver.skipped_lines == 1
    clock.sleep(0.1)
    assert [r.time_s for r in driver.poll()] == pytest.approx([0.2])


@pytest.mark.machine
def test_beam_break_gives_readings_with_signal_not_ok(rig):
    clock, sim, driver = rig()
    sim.beam_break(0.25, 0.45)
    clock.sleep(0.6)
    readings = driver.poll()
    assert [r.signal_ok for r in readings] == [True, True, False, False, True, True]
    assert readings[2].signal_pct == 0.0


@pytest.mark.machine
def test_beam_break_with_a_flag_only_format(rig):
    fmt = LineFormat.from_dict({"fields": ["time_s", "position", "beam_ok"]}, "test")
    clock, sim, driver = rig(fmt=fmt)
    sim.beam_break(0.15, 0.25)
    clock.sleep(0.3)
    readings = driver.poll()
    assert [r.signal_ok for r in readings] == [True, False, True]
    assert all(r.signal_pct is None for r in readings)


@pytest.mark.machine
def test_drain_discards_pending_input(rig):
    clock, sim, driver = rig()
    sim.split_next_line()
    clock.sleep(0.3)
    driver.poll()
    clock.sleep(0.2)  # the rest of the split line and two more lines are waiting
    driver.drain()
    clock.sleep(0.1)
    assert [r.time_s for r in driver.poll()] == pytest.approx([0.6])
    assert driver.skipped_lines == 0


@pytest.mark.machine
def test_overflowing_pty_drops_lines_but_the_stream_recovers(rig):
    clock, sim, driver = rig(rate_hz=1000.0)
    clock.sleep(100.0)  # 100 000 lines and nobody reading
    assert sim.dropped_lines > 0
    assert driver.poll()  # what the pty held when it overflowed
    driver.drain()
    clock.sleep(0.01)
    assert [r.time_s for r in driver.poll()] == pytest.approx([100.001 + 0.001 * k for k in range(10)])


@pytest.mark.machine
def test_query_mode_answers_with_the_reading_at_clock_now(rig):
    clock, _, driver = rig(mode="query")
    clock.sleep(2.5)
    (reading,) = driver.poll()
    assert reading.time_s == 2.5 and reading.position == pytest.approx(25.0)
    clock.sleep(0.5)
    assert [r.time_s for r in driver.poll()] == [3.0]


@pytest.mark.machine
def test_query_mode_garbage_answer_gives_no_reading(rig):
    _, sim, driver = rig(mode="query")
    sim.inject_garbage("!!\n")
    assert driver.poll() == []  # the garbage line comes first and ends the read
    assert driver.skipped_lines == 1
    assert len(driver.poll()) == 1


@pytest.mark.machine
def test_query_without_answer_raises_instrument_error(rig):
    # the simulator streams (and its clock stands still), so nobody answers the request
    _, _, driver = rig(mode="stream", driver_mode="query", timeout_s=0.2)
    with pytest.raises(InstrumentError, match="did not answer"):
        driver.poll()


@pytest.mark.machine
@pytest.mark.parametrize("mode", ["stream", "query"])
def test_vanished_port_raises_instrument_error(rig, mode):
    clock, sim, driver = rig(mode=mode)
    clock.sleep(0.1)
    driver.poll()
    sim.disappear()
    clock.sleep(0.1)
    with pytest.raises(InstrumentError):
        driver.poll()


def test_opening_a_missing_port_raises_instrument_error():
    with pytest.raises(InstrumentError):
        SerialInterferometer("/dev/does-not-exist-axiscal", 115200)


@pytest.mark.machine
@pytest.mark.parametrize("mode", ["stream", "query"])
def test_no_fds_or_threads_leak(mode):
    fds_before = len(os.listdir("/proc/self/fd"))
    threads_before = threading.active_count()
    for _ in range(5):
        clock = SimClock()
        sim = SimInterferometer(clock, measure, mode=mode)
        driver = SerialInterferometer(sim.port_name, 115200, mode=mode)
        clock.sleep(0.3)
        assert driver.poll()
        driver.close()
        sim.close()
        sim.close()
        driver.close()
    assert len(os.listdir("/proc/self/fd")) == fds_before
    assert threading.active_count() == threads_before

"""SimPLC's motion, driven directly through its PLC variables (no ADS server)."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from drivers.sim.clock import SimClock
from drivers.sim.plc import SimPLC
from protocols import plc_contract, plc_layout
from protocols.plc_contract import Command

CONTROL = plc_contract.control_symbols(1)
STATUS = plc_contract.status_symbols(1)


def _write(plc: SimPLC, member: str, value) -> None:
    """What the ADS server does for a client's write."""
    symbol = CONTROL[member]
    place = plc_layout.resolve(symbol.name)
    plc.memory[place.offset:place.offset + place.size] = plc._encode(symbol, value)


def _move(plc: SimPLC, target: float, velocity: float) -> None:
    _write(plc, "fPosition", target)
    _write(plc, "fVelocity", velocity)
    _write(plc, "eCommand", int(Command.MOVE_ABSOLUTE))
    _write(plc, "bExecute", True)


positions = st.floats(-500, 500)
velocities = st.floats(0.1, 100)
accelerations = st.floats(1, 2000)


@given(positions, positions, velocities, accelerations)
def test_a_move_is_a_smooth_trapezoid_that_ends_exactly_at_the_target(start, target, velocity, accel):
    clock = SimClock()
    plc = SimPLC(max_velocity=100.0, acceleration=accel, position=start)
    clock.attach(plc.scan)
    _move(plc, target, velocity)
    plc.scan(0.0)
    assert plc.value(CONTROL["bExecute"].name) is False  # taken and cleared

    distance = abs(target - start)
    duration = (
        distance / velocity + velocity / accel
        if distance >= velocity**2 / accel
        else 2 * math.sqrt(distance / accel)
    )
    dt = duration / 200 if duration else 1e-3
    previous = start
    for i in range(1, 202):
        p = plc.setpoint_position(i * dt)
        step = p - previous
        assert abs(step) <= velocity * dt * (1 + 1e-6) + 1e-9  # never faster than commanded
        assert step * (target - start) >= -1e-9  # never backwards
        previous = p
    assert plc.setpoint_position(duration * 1.01 + 1e-9) == target

    clock.sleep(duration + 1e-3)
    assert plc.value(STATUS["bDone"].name) is True
    assert plc.value(STATUS["fActPosition"].name) == target
    assert plc.arrival_time is not None and math.isclose(plc.arrival_time, duration, abs_tol=1e-9)


@given(velocities, accelerations, st.floats(0.05, 0.95))
def test_a_halt_brakes_at_the_acceleration_and_stops_short(velocity, accel, fraction):
    clock = SimClock()
    plc = SimPLC(max_velocity=100.0, acceleration=accel)
    clock.attach(plc.scan)
    target = 100.0
    _move(plc, target, velocity)
    clock.sleep(1e-3)
    t_halt = fraction * (target / velocity)
    clock.sleep(t_halt - clock.now())
    p_halt = plc.setpoint_position(t_halt)
    _write(plc, "bHalt", True)
    clock.sleep(velocity / accel + 1.0)
    assert plc.value(STATUS["bBusy"].name) is False
    assert plc.value(STATUS["bDone"].name) is False
    stop = plc.value(STATUS["fActPosition"].name)
    assert p_halt <= stop <= p_halt + velocity**2 / (2 * accel) + 1e-9
    assert stop <= target


def test_correction_shifts_the_setpoint_only():
    plc = SimPLC(position=10.0)
    plc.correction = -0.002
    plc.scan(0.1)
    assert plc.setpoint_position(0.1) == 10.0 - 0.002
    assert plc.value(STATUS["fActPosition"].name) == 10.0


def test_a_move_to_where_the_axis_is_keeps_the_direction():
    clock = SimClock()
    plc = SimPLC(position=10.0)
    clock.attach(plc.scan)
    _move(plc, 5.0, 10.0)
    clock.sleep(2.0)
    assert plc.last_direction == -1
    _move(plc, 5.0, 10.0)
    clock.sleep(0.1)
    assert plc.last_direction == -1
    assert plc.value(STATUS["bDone"].name) is True


def test_unknown_command_is_an_error_until_reset():
    plc = SimPLC()
    _write(plc, "eCommand", 9)
    _write(plc, "bExecute", True)
    plc.scan(0.01)
    assert plc.value(STATUS["nErrorId"].name) == plc_contract.PlcErrorId.UNKNOWN_COMMAND
    _write(plc, "bReset", True)
    plc.scan(0.02)
    assert plc.value(STATUS["bError"].name) is False

"""The opener wiring the ADS, EPICS and LinuxCNC machines share (drivers/factory.py): a real axis
with the laser on a serial port, and the simulated laser beside whatever serves the axis. What was
opened is closed again when a later part fails (no server is started)."""

from __future__ import annotations

from pathlib import Path

import pytest

from campaign.commands.demo import demo_config_text
from campaign.config import parse_config
from campaign.errors import InputError
from drivers.factory import sim_hardware, sim_machine, with_serial_laser


class Closed:
    """An axis stand-in that only records that it was closed (nothing moves in these tests)."""

    def __init__(self, log: list[str]) -> None:
        self.log = log

    def close(self) -> None:
        self.log.append("axis")


def test_a_real_axis_is_closed_again_when_the_lasers_port_cannot_be_opened(tmp_path):
    port = tmp_path / "no-such-tty"
    text = demo_config_text().replace('[instrument]\ntype = "sim"', f'[instrument]\ntype = "serial"\nport = "{port}"')
    spec = parse_config(text, "real.toml").driver
    log: list[str] = []
    with pytest.raises(InputError, match=rf"real.toml: instrument.port: cannot open {port}"):
        with_serial_laser(spec, Closed(log))  # type: ignore[arg-type]  # only close() is called
    assert log == ["axis"]


@pytest.mark.machine  # opens the simulated laser's pty
def test_the_simulated_laser_and_what_runs_are_closed_in_reverse_when_the_axis_cannot_open():
    spec = parse_config(demo_config_text(), "demo.toml").driver
    clock, _, physics = sim_machine(spec, None, None, 12.5, 0.0, False, 1)
    assert abs(physics.true_position(0.0, with_reading_noise=False) - 12.5) < 0.01  # where it was asked to start
    log: list[str] = []
    closers = [lambda: log.append("server")]

    def refused():
        assert Path(closers[1].__self__.port_name).exists()  # the laser's pty is open by now
        raise OSError("the controller refused the connection")

    with pytest.raises(OSError, match="refused"):
        sim_hardware(spec, clock, physics, refused, closers)
    laser = closers[1].__self__
    assert log == ["server"] and not Path(laser.port_name).exists()  # the laser's pty is closed too

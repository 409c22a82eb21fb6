"""Stress: 20 consecutive simulated campaigns in one process leak no threads, sockets or file
handles; one 24-hour campaign in simulated time with thermal drift completes."""

import os
import threading

import numpy as np
import pytest

from campaign.config import parse_config
from campaign.measure.session import start_campaign
from campaign.pointtable import read_points
from drivers.factory import open_hardware

SMALL = """
[axis]
soft_limit_min = -5.0
soft_limit_max = 105.0
max_velocity = 50.0
[plan]
targets = [0.0, 50.0, 100.0]
overrun = 2.0
cycles = 1
dwell_s = 0.5
velocity = 40.0
[capture]
average_s = 0.2
[sim.effects.linear_scale]
ppm = 10.0
[sim.effects.noise]
sigma_um = 0.3
"""

DAY = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 610.0
max_velocity = 50.0
[plan]
length = 600.0
count = 11
overrun = 5.0
cycles = 59
dwell_s = 60.0
velocity = 8.0
[instrument]
rate_hz = 1.0
[capture]
average_s = 5.0
[sim.effects.linear_scale]
ppm = -12.0
[sim.effects.thermal_drift]
growth_ppm = 25.0
tau_s = 21600.0
pivot_mm = 0.0
[sim.effects.noise]
sigma_um = 0.3
"""


def resources():
    fds = os.listdir("/proc/self/fd")
    sockets = 0
    for fd in fds:
        try:
            sockets += os.readlink(f"/proc/self/fd/{fd}").startswith("socket:")
        except OSError:
            pass
    return threading.active_count(), len(fds), sockets


FAULTED = {  # fault paths must release everything too: the port vanishes, the PLC goes away
    5: "serial_gone = { at_s = 3.0 }",
    10: "ads_lost = { at_s = 3.0, duration_s = 20.0 }",
    15: "disk_full = { at_s = 3.0 }",
}


@pytest.mark.machine
def test_twenty_campaigns_leak_nothing(tmp_path):
    config = parse_config(SMALL, "small.toml")
    start_campaign(config, tmp_path / "warm", opener=open_hardware)  # first use loads libraries that keep their own handles
    before = resources()
    for i in range(20):
        if i in FAULTED:
            text = SMALL.replace("[axis]", "[axis_driver]\nreconnect_s = 2.0\n[axis]") + \
                f"[sim.faults]\n{FAULTED[i]}\n"
            outcome = start_campaign(parse_config(text, "faulted.toml"), tmp_path / f"c{i}", opener=open_hardware)
            assert outcome.status == "interrupted", outcome.message
        else:
            outcome = start_campaign(config, tmp_path / f"c{i}", opener=open_hardware)
            assert outcome.status == "completed" and outcome.points == 6
    after = resources()
    assert after == before, f"threads, fds, sockets before {before}, after {after}"


@pytest.mark.machine
def test_24_hour_campaign_with_thermal_drift(tmp_path):
    config = parse_config(DAY, "day.toml")
    outcome = start_campaign(config, tmp_path / "day", opener=open_hardware)
    assert outcome.status == "completed" and outcome.points == outcome.planned == 59 * 22
    assert outcome.duration_s > 24 * 3600
    table = read_points(tmp_path / "day" / "points.csv")
    slopes = [np.polyfit(table.target[table.run == r], table.deviation[table.run == r], 1)[0] * 1000
              for r in (1, 30, 59)]  # µm/m
    # the screw grows: the slope climbs from -12 µm/m towards -12 + 25 µm/m, pivoting at 0 mm
    assert slopes[0] < slopes[1] < slopes[2]
    assert 8.0 < slopes[2] < 14.0
    assert table.optional["time_s"][-1] > 24 * 3600

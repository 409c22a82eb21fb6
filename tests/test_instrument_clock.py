"""The simulated instrument's own clock ([sim] instrument_*, issue 33 item 2): its samples are taken
at its own ticks, stamped with its own time (an offset and a rate error against the controller's),
and reach the PC a latency later, through the pty and the real serial driver."""

import numpy as np
import pytest

from drivers.serial_interferometer import SerialInterferometer
from drivers.sim.clock import SimClock
from drivers.sim.interferometer import SimInterferometer
from drivers.sim.scan_streams import InstrumentClock
from protocols.serial_line import LineFormat


@pytest.mark.machine
@pytest.mark.parametrize("offset_s, rate_ppm, latency_s", [(0.043, 61.0, 0.012), (-0.027, -35.0, 0.0)])
def test_samples_carry_the_instruments_own_stamps_and_arrive_a_latency_later(offset_s, rate_ppm, latency_s):
    clock = SimClock(100.0)
    own = InstrumentClock(offset_s=offset_s, rate_error_ppm=rate_ppm, latency_s=latency_s)
    sim = SimInterferometer(clock, lambda t: {"position": t}, LineFormat(), 200.0, "stream", own_clock=own)
    port = SerialInterferometer(sim.port_name, 115200, LineFormat(), "stream", 1.0)
    try:
        got = []
        for _ in range(400):  # 2 s in 5-ms steps
            clock.sleep(0.005)
            now = clock.now()
            for r in port.poll():
                got.append((now, r.time_s, r.position))
    finally:
        port.close()
        sim.close()
    arrived, stamp, taken = (np.array(c) for c in zip(*got))
    assert len(got) >= 395  # 200 Hz of the instrument's clock over 2 s, less the latency
    assert np.allclose(np.diff(stamp), 1 / 200.0, atol=1e-9)  # its own ticks
    assert np.allclose(stamp, offset_s + (1 + rate_ppm * 1e-6) * taken, atol=1e-9)  # its own time
    assert np.all(arrived >= taken + latency_s - 1e-9) and np.all(arrived < taken + latency_s + 0.005 + 1e-9)

"""The controller's position stream (issue 33 item 1): ADS device notifications of fActPosition from
the simulated PLC through the real pyads client, one sample per PLC cycle, each with the PLC's own
time stamp; what a scan aligns the instrument's stream against."""

import numpy as np
import pytest

from campaign.config import config_with, load_config
from drivers.factory import open_hardware
from protocols.hardware import AxisError, StreamingAxis
from tests.conftest import ROOT


@pytest.mark.machine
def test_the_position_stream_carries_every_plc_cycle_with_the_plc_time():
    config = config_with(load_config(ROOT / "campaign" / "demo.toml"), {"instrument": {"rate_hz": 500.0}})
    hw, parts = open_hardware(config.driver)
    assert parts is not None
    try:
        axis = hw.axis
        streaming: StreamingAxis = axis  # type: ignore[assignment]  # the ADS axis is one
        stream = streaming.stream_positions(0.0, 0.02)
        epoch = parts.plc.handler.notifications.epoch_s
        axis.start_move(20.0, 10.0)
        samples: list[tuple[float, float]] = []
        step = 0.002
        truth: dict[float, float] = {}  # the PLC's position after each scan, by simulated time
        for _ in range(1300):  # 2.6 s: the 2.05-s move and a rest
            hw.clock.sleep(step)
            truth[round(hw.clock.now(), 6)] = parts.plc.setpoint_position(hw.clock.now())
            samples += stream.take()
        import time
        time.sleep(0.2)  # the last packet (at most 20 ms of PLC time late) reaches the client
        samples += stream.take()
        stream.close()
        t = np.array([s[0] for s in samples]) - epoch
        x = np.array([s[1] for s in samples])
        assert len(samples) >= 1290  # one per PLC scan (one scan per clock step)
        assert np.all(np.diff(t) > 0) and np.allclose(np.diff(t)[1:], step, atol=2e-7)  # the PLC's own stamps
        at_scans = [(truth[round(ti, 6)], xi) for ti, xi in zip(t, x) if round(ti, 6) in truth]
        assert len(at_scans) >= len(samples) - 1  # every stamp is a scan's time (the first: the request's)
        assert max(abs(a - b) for a, b in at_scans) < 1e-9  # the position the PLC had then
        moving = (x > 0.5) & (x < 19.5)
        assert np.allclose(np.diff(x[moving]) / np.diff(t[moving]), 10.0, rtol=1e-3)
        assert x[-1] == pytest.approx(20.0)
        assert stream.take() == []
    finally:
        hw.close()


@pytest.mark.machine
def test_a_position_stream_ends_with_the_connection():
    config = load_config(ROOT / "campaign" / "demo.toml")
    hw, _ = open_hardware(config.driver)
    try:
        stream = hw.axis.stream_positions()  # type: ignore[attr-defined]
        hw.clock.sleep(0.1)
        hw.axis._disconnect()  # type: ignore[attr-defined]  # what a lost connection does
        with pytest.raises(AxisError, match="ended with the connection"):  # after what had arrived, if any
            for _ in range(2):
                stream.take()
    finally:
        hw.close()


@pytest.mark.machine
def test_a_deleted_notification_keeps_its_native_callback():
    """The ADS library's dispatch thread may be inside a notification's callback while the
    notification is deleted; pyads frees the callback on deletion, so the stream keeps it alive (a
    lost connection crashed the process about once in 200 streams without it)."""
    import gc
    import weakref

    import pyads

    config = load_config(ROOT / "campaign" / "demo.toml")
    hw, _ = open_hardware(config.driver)
    try:
        before = set(pyads.pyads_ex.callback_store)
        stream = hw.axis.stream_positions()  # type: ignore[attr-defined]
        added = [c for key, c in pyads.pyads_ex.callback_store.items() if key not in before]
        assert len(added) == 1
        callback = weakref.ref(added[0])
        del added
        hw.axis._disconnect()  # type: ignore[attr-defined]  # deletes the notification
        assert not set(pyads.pyads_ex.callback_store) - before  # pyads let go of it
        del stream
        gc.collect()
        assert callback() is not None
    finally:
        hw.close()

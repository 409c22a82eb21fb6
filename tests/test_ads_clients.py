"""The simulated PLC under ADS clients we did not write (issue 26 item 5): ads-client (npm, installed
by tests/setup_system.sh) with its default connect, five pipelined reads in ten rounds and a
notification on the moving axis; ads-async (PyPI) decoding what the PLC sends, a notification
included. The hand-built packets and the notification rules in detail: tests/test_ads_framing.py,
tests/test_ads_notifications.py."""

from __future__ import annotations

import json
import shutil
import socket
import struct
import subprocess
import time
from itertools import pairwise
from pathlib import Path

import pytest
from ads_async import constants, protocol, structs

from drivers.ads_axis import AdsAxis
from drivers.factory import serve_on_free_loopback
from drivers.sim.ads_device import GVL_OFFSET, PLC_DATA_GROUP
from drivers.sim.clock import SimClock
from drivers.sim.plc import SimPLC
from protocols import plc_layout

pytestmark = pytest.mark.machine
NODE_DIR = Path(__file__).parent / "ads_client"
needs_ads_client = pytest.mark.skipif(
    shutil.which("node") is None or not (NODE_DIR / "node_modules" / "ads-client").exists(),
    reason="needs node and ads-client (tests/setup_system.sh installs it with npm)")
POSITION = "GVL_Axiscal.astAxes[1].stStatus.fActPosition"


@pytest.fixture
def machine():
    """A simulated PLC on its own loopback address, its clock, and the project's pyads axis on it."""
    clock = SimClock()
    plc = SimPLC(axis=1, max_velocity=50.0, acceleration=200.0)
    clock.attach(plc.scan)
    server = serve_on_free_loopback(plc)
    axis = AdsAxis(server.net_id, server.ip, axis=1, timeout_s=1.0)
    yield plc, clock, server, axis
    axis.close()
    server.stop()


def move(axis: AdsAxis, clock: SimClock, target: float, velocity: float, step_s: float = 0.01) -> float:
    """Move there in simulated time and stand for 0.3 s more; the simulated time it took, s."""
    start = clock.now()
    axis.start_move(target, velocity)
    clock.sleep(step_s)
    while axis.status().busy:
        clock.sleep(step_s)
    for _ in range(round(0.3 / step_s)):
        clock.sleep(step_s)
    return clock.now() - start


def assert_default_connect(connection: dict) -> None:
    """ads-client connected without skipping anything, saw TwinCAT and the runtime in Run and the
    runtime's symbol version, from port 10000 and from the runtime's first notifications."""
    assert (connection["rawClient"], connection["allowHalfOpen"]) == (False, False)
    system = connection["tcSystemState"]
    assert (system["adsStateStr"], system["deviceState"], system["version"], system["revision"], system["build"]) == (
        "Run", 1, 3, 1, 4024)
    assert connection["plcRuntimeState"]["adsStateStr"] == "Run" and connection["plcSymbolVersion"] == 1


@needs_ads_client
def test_ads_client_default_connect_and_five_pipelined_reads_in_ten_of_ten_rounds(machine):
    plc, _, server, _ = machine
    run = subprocess.run(["node", str(NODE_DIR / "pipeline.js"), server.ip, server.net_id], capture_output=True,
                         text=True, timeout=120, check=False)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert_default_connect(out["connection"])
    rounds = out["rounds"]
    assert len(rounds) == 10
    assert all(r["inFlight"] >= 5 for r in rounds)  # the five were sent before any answer came
    assert [r["got"] == r["sent"] for r in rounds] == [True] * 10, rounds
    assert len({v for r in rounds for v in r["sent"]}) == 50 and out["clientErrors"] == []
    deadline = time.monotonic() + 3.0
    while len(plc.handler.notifications) and time.monotonic() < deadline:  # its watches end with it
        time.sleep(0.05)
    assert len(plc.handler.notifications) == 0


@needs_ads_client
def test_ads_client_notification_follows_the_move_once_per_cycle_on_change(machine):
    _, clock, server, axis = machine
    node = subprocess.Popen(["node", str(NODE_DIR / "notify.js"), server.ip, server.net_id, "50"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert node.stdout is not None and node.stdin is not None
        assert node.stdout.readline() == "subscribed\n", node.stderr.read() if node.stderr else ""
        took_s = move(axis, clock, 20.0, 20.0)  # 1.1 s of motion (0.1-s ramps at 200 mm/s²), 0.3 s still
        time.sleep(0.3)  # the last packets reach the client
        out, err = node.communicate("done\n", timeout=60)
    finally:
        node.kill()
    assert node.returncode == 0, err
    result = json.loads(out)
    assert_default_connect(result["connection"])
    times_ms = [t for t, _ in result["samples"]]
    positions = [p for _, p in result["samples"]]
    assert positions[0] == 0.0 and positions[-1] == 20.0  # the value when subscribed, then the arrival
    assert all(b > a for a, b in pairwise(positions))  # on change: each one new
    assert all(b - a >= 49 for a, b in pairwise(times_ms))  # at most one per 50-ms cycle
    assert 21 <= len(positions) <= 24 and took_s >= 1.4  # about one per cycle over the 1.1-s move
    assert times_ms[-1] - times_ms[0] <= 1150 and result["clientErrors"] == []


class AdsAsyncClient:
    """ads-async's protocol layer (its requests, its decoding) on a plain socket. Its asyncio client
    cannot be used on Python 3.11: waiting for a reply, it passes a coroutine to asyncio.wait,
    which Python 3.11 refuses (TypeError), so every request fails."""

    def __init__(self, ip: str, net_id: str):
        self.sock = socket.create_connection((ip, 48898), timeout=3.0)
        self.connection = protocol.ClientConnection(our_address=self.sock.getsockname(), our_net_id="127.0.0.1.1.9",
                                                    their_address=(ip, 48898))
        self.circuit = self.connection.get_circuit(net_id)
        self.net_id = net_id
        self.notifications: list[structs.AdsNotificationStream] = []

    def ask(self, item, port: int = 851):
        invoke_id, data = self.circuit.request_to_wire(item, target=(self.net_id, port))
        self.sock.sendall(data)
        while True:
            for header, reply in self.connection.received_data(self.sock.recv(65536)):
                if header.command_id == constants.AdsCommandId.DEVICE_NOTIFICATION:
                    self.notifications.append(reply)
                elif header.invoke_id == invoke_id:
                    return header, reply

    def receive(self, seconds: float) -> None:
        """Collect notifications for a while."""
        self.sock.settimeout(seconds)
        try:
            while True:
                for header, reply in self.connection.received_data(self.sock.recv(65536)):
                    assert header.command_id == constants.AdsCommandId.DEVICE_NOTIFICATION
                    self.notifications.append(reply)
        except TimeoutError:
            pass

    def samples(self, handle: int) -> list[tuple[object, float]]:
        return [(stamp.timestamp, struct.unpack("<d", sample.data)[0]) for stream in self.notifications
                for stamp in stream.stamps for sample in stamp.samples if sample.notification_handle == handle]


def test_ads_async_connects_reads_and_subscribes(machine):
    plc, clock, server, axis = machine
    client = AdsAsyncClient(server.ip, server.net_id)
    try:
        _, info = client.ask(client.circuit.get_device_information())
        assert (info.result, info.name, info.version_tuple) == (0, "Plc30 App", (3, 1, 4024))
        _, system = client.ask(client.circuit.get_device_information(), port=10000)
        assert (system.result, system.name) == (0, "TwinCAT System")
        move(axis, clock, 12.5, 20.0)
        _, handle = client.ask(client.circuit.get_symbol_handle_by_name(POSITION))
        handle = handle.as_handle_response().handle
        _, by_handle = client.ask(client.circuit.get_value_by_handle(handle, 8))
        offset = GVL_OFFSET + plc_layout.require(POSITION).offset
        _, by_index = client.ask(structs.AdsReadRequest(PLC_DATA_GROUP, offset, 8))
        assert struct.unpack("<d", by_handle.data) == struct.unpack("<d", by_index.data) == (12.5,)

        _, added = client.ask(client.circuit.add_notification_by_index(
            PLC_DATA_GROUP, offset, 8, constants.AdsTransmissionMode.SERVERONCHA, max_delay=0, cycle_time=0))
        assert added.result == 0 and added.handle != 0  # result and handle: the 8 bytes it decodes
        move(axis, clock, 20.0, 25.0)
        client.receive(0.3)
        samples = client.samples(added.handle)
        positions = [p for _, p in samples]
        assert positions[0] == 12.5 and positions[-1] == 20.0 and len(positions) > 20
        assert all(b > a for a, b in pairwise(positions))
        times = [t for t, _ in samples]
        assert all(b > a for a, b in pairwise(times))  # FILETIMEs it reads as datetimes
        _, deleted = client.ask(client.circuit.remove_notification(added.handle))
        assert deleted.result == 0 and len(plc.handler.notifications) == 0

        _, refused = client.ask(client.circuit.add_notification_by_index(0x1234, 0, 4))
        assert (refused.result, refused.handle) == (constants.AdsError.DEVICE_INVALIDGRP, 0)
        # issue 32: Beckhoff's code for a transmission mode the PLC does not serve, as ads-async names it
        _, client_side = client.ask(client.circuit.add_notification_by_index(
            PLC_DATA_GROUP, offset, 8, constants.AdsTransmissionMode.CLIENTCYCLE))
        assert (client_side.result, client_side.handle) == (constants.AdsError.DEVICE_TRANSMODENOTSUPP, 0)
        # and a sum read asking for 100 MiB is refused as a plain read of it is (it was answered 0
        # with 100 MiB of zeros); the connection goes on
        entry = struct.pack("<III", PLC_DATA_GROUP, offset, 100 << 20)
        sum_read = structs.AdsReadWriteRequest(constants.AdsIndexGroup.SUMUP_READ, 1, 4 + (100 << 20), len(entry))
        sum_read.data = entry
        _, too_much = client.ask(sum_read)
        assert (too_much.result, too_much.data) == (constants.AdsError.DEVICE_INVALIDSIZE, b"")
        _, again = client.ask(structs.AdsReadRequest(PLC_DATA_GROUP, offset, 8))
        assert again.result == 0 and struct.unpack("<d", again.data) == (20.0,)
    finally:
        client.sock.close()

"""The simulated PLC frames ADS by the AMS/TCP length, as TwinCAT does (issue 26 item 5): a request
split over two TCP sends is answered, several requests in one send are each answered in order,
a client that drops its connection leaves one log line, not a traceback, and so does a router
command. A notification's reply and first sample come on the same stream. Raw sockets, requests
built by hand (tests/ads_wire.py): mostly ADS Read State (command 4)."""

from __future__ import annotations

import logging
import socket
import struct
import time

import pytest

from drivers.factory import serve_on_free_loopback
from drivers.sim.ads_device import GVL_OFFSET
from drivers.sim.plc import SimPLC
from protocols import plc_layout
from tests import ads_wire as w

pytestmark = pytest.mark.machine

READ_STATE = w.READ_STATE
read_state = w.read_state


def answers(sock: socket.socket, count: int, timeout_s: float = 3.0) -> list[int]:
    """The invoke ids of the next `count` answers, in the order they came."""
    sock.settimeout(timeout_s)
    data = b""
    ids: list[int] = []
    while len(ids) < count:
        data += sock.recv(65536)
        while len(data) >= 6 and len(data) >= 6 + struct.unpack_from("<I", data, 2)[0]:
            length = struct.unpack_from("<I", data, 2)[0]
            packet, data = data[:6 + length], data[6 + length:]
            command, = struct.unpack_from("<H", packet, 6 + 16)
            error, = struct.unpack_from("<I", packet, 6 + 24)
            assert command == READ_STATE and error == 0
            ids.append(struct.unpack_from("<I", packet, 6 + 28)[0])
    return ids


@pytest.fixture
def plc_server():
    server = serve_on_free_loopback(SimPLC(axis=1, max_velocity=50.0, acceleration=200.0))
    yield server
    server.stop()


def test_a_request_split_over_two_sends_is_answered(plc_server):
    packet = read_state(plc_server.net_id, 7)
    with socket.create_connection((plc_server.ip, plc_server.port)) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.sendall(packet[:20])
        time.sleep(0.3)  # the server has seen the first part alone
        sock.sendall(packet[20:])
        assert answers(sock, 1) == [7]


def test_five_requests_in_one_send_are_each_answered_in_order_ten_rounds(plc_server):
    with socket.create_connection((plc_server.ip, plc_server.port)) as sock:
        for round_ in range(10):
            ids = list(range(round_ * 5 + 1, round_ * 5 + 6))
            sock.sendall(b"".join(read_state(plc_server.net_id, i) for i in ids))
            assert answers(sock, 5) == ids


@pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")
def test_an_abrupt_disconnect_is_one_log_line(plc_server, caplog, capfd):
    caplog.set_level(logging.WARNING, logger="drivers.sim.ads_server")
    sock = socket.create_connection((plc_server.ip, plc_server.port))
    sock.sendall(read_state(plc_server.net_id, 1))
    assert answers(sock, 1) == [1]
    sock.sendall(read_state(plc_server.net_id, 2))  # unread answer: the close below sends a reset
    time.sleep(0.2)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    sock.close()
    time.sleep(0.5)
    assert "Traceback" not in capfd.readouterr().err
    dropped = [r.getMessage() for r in caplog.records if "dropped the connection" in r.getMessage()]
    assert len(dropped) == 1 and "\n" not in dropped[0]
    with socket.create_connection((plc_server.ip, plc_server.port)) as again:  # still serving
        again.sendall(read_state(plc_server.net_id, 3))
        assert answers(again, 1) == [3]


def test_a_notification_is_result_and_handle_then_its_first_sample_and_a_refused_one_is_8_bytes(plc_server):
    """AddDeviceNotification (command 6): Beckhoff's reply layout (result, handle) whether served or
    refused; a served one's first sample follows on the same connection as command 8."""
    position = GVL_OFFSET + plc_layout.require("GVL_Axiscal.astAxes[1].stStatus.fActPosition").offset
    with socket.create_connection((plc_server.ip, plc_server.port)) as sock:
        sock.settimeout(3.0)
        sock.sendall(w.add_notification(plc_server.net_id, 0x4040, 0, 4, 4, 0.0, 0.1, invoke_id=9)
                     + w.add_notification(plc_server.net_id, 0x4040, position, 8, 4, 0.0, 0.1, invoke_id=10))
        stream, packets = b"", []
        while len(packets) < 3:
            stream += sock.recv(65536)
            whole, stream = w.split(stream)
            packets += [w.parse(p) for p in whole]
    refused, served, first = packets
    assert (refused.invoke_id, refused.command, refused.data) == (9, 6, struct.pack("<II", 0x703, 0))
    result, handle = struct.unpack("<II", served.data)
    assert (served.invoke_id, result, len(served.data)) == (10, 0, 8) and handle != 0
    assert (first.command, first.invoke_id, first.target) == (8, 0, w.CLIENT)
    ((_, [(sample_handle, raw)]),) = w.stamps(first.data)
    assert sample_handle == handle and struct.unpack("<d", raw) == (0.0,)


def test_a_router_command_is_one_warning_and_the_connection_goes_on(plc_server, caplog):
    """A client without its own AMS Net ID asks the router for a port (AMS/TCP command 0x1000);
    a PLC reached over the network does not serve it."""
    caplog.set_level(logging.WARNING, logger="drivers.sim.ads_server")
    with socket.create_connection((plc_server.ip, plc_server.port)) as sock:
        sock.sendall(struct.pack("<HIH", 0x1000, 2, 0) + w.read_state(plc_server.net_id, 4))
        assert answers(sock, 1) == [4]
    (warning,) = [r.getMessage() for r in caplog.records if "router command" in r.getMessage()]
    assert "0x1000" in warning and "own AMS Net ID" in warning

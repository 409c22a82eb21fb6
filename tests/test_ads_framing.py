"""The simulated PLC frames ADS by the AMS/TCP length, as TwinCAT does (issue 26 item 5): a request
split over two TCP sends is answered, several requests in one send are each answered in order,
and a client that drops its connection leaves one log line, not a traceback. Raw sockets, requests
built by hand: ADS Read State (command 4), whose answer carries the ADS and device state."""

from __future__ import annotations

import logging
import socket
import struct
import time

import pytest

from drivers.factory import serve_on_free_loopback
from drivers.sim.plc import SimPLC

pytestmark = pytest.mark.machine

READ_STATE = 4
REQUEST = 0x0004  # state flags: a request over TCP with the ADS command bit


def net_id_bytes(net_id: str) -> bytes:
    return bytes(int(part) for part in net_id.split("."))


def read_state(net_id: str, invoke_id: int) -> bytes:
    """One AMS/TCP packet: header (reserved, length), AMS header (target, source, command, flags,
    data length, error, invoke id), no data."""
    ams = (net_id_bytes(net_id) + struct.pack("<H", 851) + net_id_bytes("127.0.0.1.1.2") + struct.pack("<H", 30000)
           + struct.pack("<HHIII", READ_STATE, REQUEST, 0, 0, invoke_id))
    return struct.pack("<HI", 0, len(ams)) + ams


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


def test_a_refused_notification_has_beckhoffs_reply_layout(plc_server):
    """AddDeviceNotification (command 6) is refused with 0x701 in 8 bytes: result, then a handle."""
    payload = struct.pack("<IIIIII16x", 0x4040, 0, 4, 4, 0, 1_000_000)  # group, offset, length, mode, delays
    ams = (net_id_bytes(plc_server.net_id) + struct.pack("<H", 851) + net_id_bytes("127.0.0.1.1.2")
           + struct.pack("<H", 30000) + struct.pack("<HHIII", 6, REQUEST, len(payload), 0, 9) + payload)
    with socket.create_connection((plc_server.ip, plc_server.port)) as sock:
        sock.settimeout(3.0)
        sock.sendall(struct.pack("<HI", 0, len(ams)) + ams)
        reply = sock.recv(65536)
    data_length, = struct.unpack_from("<I", reply, 6 + 20)
    result, = struct.unpack_from("<I", reply, 6 + 32)
    assert data_length == 8 and result == 0x701

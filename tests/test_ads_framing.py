"""The simulated PLC frames ADS by the AMS/TCP length, as TwinCAT does (issue 26 item 5): a request
split over two TCP sends is answered, several requests in one send are each answered in order,
a client that drops its connection leaves one log line, not a traceback, and so does a router
command. A notification's reply and first sample come on the same stream. Raw sockets, requests
built by hand (tests/ads_wire.py): mostly ADS Read State (command 4). A client that subscribes and
then stops reading is dropped with one log line while the PLC's scans and the other clients go on."""

from __future__ import annotations

import logging
import socket
import struct
import threading
import time
from itertools import pairwise

import pytest

from drivers.ads_axis import AdsAxis
from drivers.factory import serve_on_free_loopback
from drivers.sim.ads_device import GVL_OFFSET, PLC_DATA_GROUP
from drivers.sim.ads_server import OUTGOING_LIMIT_BYTES
from drivers.sim.clock import SimClock
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


class Listener:
    """A well-behaved raw-socket client: its thread reads all the PLC sends until the socket closes."""

    def __init__(self, address: tuple[str, int]):
        self.sock = socket.create_connection(address)
        self.packets: list[w.Packet] = []
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        stream = b""
        while data := self.sock.recv(65536):
            whole, stream = w.split(stream + data)
            self.packets += [w.parse(p) for p in whole]

    def samples(self, handle: int) -> list[tuple[int, bytes]]:
        """(FILETIME, value) of each sample of notification `handle` received so far."""
        return [(filetime, raw) for p in list(self.packets) if p.command == w.DEVICE_NOTIFICATION
                for filetime, items in w.stamps(p.data) for h, raw in items if h == handle]

    def close(self) -> None:
        self.sock.shutdown(socket.SHUT_RDWR)
        self._thread.join()
        self.sock.close()


def wait_for(condition, what: str, timeout_s: float = 10.0) -> None:
    """Wait (wall time, a hang guard only) until condition() holds."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"still not {what} after {timeout_s} s"
        time.sleep(0.01)


def test_a_client_that_stops_reading_is_dropped_and_the_move_and_the_other_clients_go_on(caplog):
    """A raw-socket client subscribes (cyclic, 1-ms cycle: every scan) to the whole GVL four times,
    about 67 kB a scan, and never reads; a 30-mm move then runs to the end in 1-ms scans of
    simulated time. Before the fix the scan blocked in sendall on that client as soon as the
    socket's buffers were full, so the move never ended (this test timed out on the worker)."""
    caplog.set_level(logging.WARNING, logger="drivers.sim.ads_server")
    clock = SimClock()
    plc = SimPLC(axis=1, max_velocity=50.0, acceleration=200.0)
    clock.attach(plc.scan)
    server = serve_on_free_loopback(plc)
    axis = AdsAxis(server.net_id, server.ip, axis=1, timeout_s=1.0)
    slow = socket.socket()
    slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # a small window: the server's buffers fill sooner
    slow.connect((server.ip, server.port))
    slow_port = slow.getsockname()[1]
    good = Listener((server.ip, server.port))
    gvl_bytes = plc_layout.GVL_TYPE.size
    slow.sendall(b"".join(w.add_notification(server.net_id, PLC_DATA_GROUP, GVL_OFFSET, gvl_bytes, 3, 0.0, 0.001,
                                             invoke_id=i) for i in range(4)))
    position = GVL_OFFSET + plc_layout.require("GVL_Axiscal.astAxes[1].stStatus.fActPosition").offset
    good.sock.sendall(w.add_notification(server.net_id, PLC_DATA_GROUP, position, 8, 3, 0.0, 0.001, invoke_id=5))
    wait_for(lambda: len(plc.handler.notifications) == 5, "subscribed")
    wait_for(lambda: any(p.command == w.ADD_NOTIFICATION for p in good.packets), "answered")
    (reply,) = [p for p in good.packets if p.command == w.ADD_NOTIFICATION]
    result, handle = struct.unpack("<II", reply.data)
    assert result == 0
    scans: list[int] = []
    failure: list[BaseException] = []

    def run_move() -> None:
        try:
            axis.start_move(30.0, 50.0)  # 0.85 s: 850 scans, about 57 MB for the slow client
            clock.sleep(0.001)
            scans.append(1)
            while axis.status().busy:
                clock.sleep(0.001)
                scans.append(1)
            for _ in range(100):  # and 0.1 s standing
                clock.sleep(0.001)
                scans.append(1)
        except BaseException as exc:  # noqa: BLE001 (re-raised in the test's thread)
            failure.append(exc)

    worker = threading.Thread(target=run_move, daemon=True)
    worker.start()
    try:
        worker.join(60.0)  # a hang guard, not a time limit: the move takes about a second
        hung = worker.is_alive()
    finally:
        slow.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        slow.close()  # a reset: frees a scan blocked on this client (the old code), so nothing hangs
        worker.join(10.0)
    try:
        assert not hung, "the PLC's scan waited on a client that does not read"
        assert not failure, failure
        assert len(scans) * 4 * gvl_bytes > 20 * OUTGOING_LIMIT_BYTES  # far more than the queue holds
        assert plc.value("GVL_Axiscal.astAxes[1].stStatus.bDone") is True
        assert plc.value("GVL_Axiscal.astAxes[1].stStatus.fActPosition") == 30.0
        wait_for(lambda: len(plc.handler.notifications) == 1, "the slow client's notifications deleted")
        wait_for(lambda: len(good.samples(handle)) == len(scans) + 1, "every scan's sample at the good client")
        samples = good.samples(handle)
        assert [ft for ft, _ in samples] == sorted({ft for ft, _ in samples})  # in order, one per scan
        gaps_s = {round((b - a) / w.TICKS_PER_S, 6) for (a, _), (b, _) in pairwise(samples)}
        assert gaps_s == {0.001}  # nothing missing, before, during and after the drop
        assert struct.unpack("<d", samples[-1][1]) == (30.0,)
        lines = [r.getMessage() for r in caplog.records if r.name == "drivers.sim.ads_server"]
        assert len(lines) == 1 and "\n" not in lines[0], lines
        assert f":{slow_port} does not read" in lines[0] and "connection dropped" in lines[0]
    finally:
        good.close()
        axis.close()
        server.stop()


def test_beyond_the_client_limit_a_connection_is_closed_at_once_and_ended_ones_are_let_go(monkeypatch, caplog):
    """Issue 32: pyads' test server kept every connection it ever had in `clients` (a client that
    reconnects all day grew it without end) and took any number of them (two threads each)."""
    from drivers.sim import ads_server

    monkeypatch.setattr(ads_server, "CLIENT_LIMIT", 5)
    caplog.set_level(logging.WARNING, logger="drivers.sim.ads_server")
    server = serve_on_free_loopback(SimPLC(axis=1, max_velocity=50.0, acceleration=200.0))
    try:
        clients = [socket.create_connection((server.ip, server.port)) for _ in range(5)]
        for i, sock in enumerate(clients, start=1):
            sock.sendall(read_state(server.net_id, i))
            assert answers(sock, 1) == [i]
        for _ in range(3):  # the sixth, seventh and eighth: closed at once, one line for the three
            with socket.create_connection((server.ip, server.port)) as extra:
                extra.settimeout(3.0)
                assert extra.recv(100) == b""
        full = [r.getMessage() for r in caplog.records if "the most the PLC serves" in r.getMessage()]
        assert len(full) == 1 and "5 clients connected" in full[0]
        clients.pop().close()
        time.sleep(0.3)  # its thread ends
        with socket.create_connection((server.ip, server.port)) as again:  # room again
            again.sendall(read_state(server.net_id, 9))
            assert answers(again, 1) == [9]
            assert len(server._server.clients) == 5  # the ended connection let go
        for sock in clients:
            sock.close()
    finally:
        server.stop()


def test_a_restart_waits_for_its_address_and_says_when_it_stays_taken(monkeypatch):
    """`ads_lost` stops the server and starts it again on its own address: while something still
    listens there, start() tries again (ADDRESS_IN_USE_S) and takes it once it is free; an address
    that stays taken raises the OSError."""
    import errno

    from drivers.sim import ads_server

    server = serve_on_free_loopback(SimPLC(1, 50.0, 200.0, position=0.0))
    server.stop()
    squatter = socket.socket()
    squatter.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    squatter.bind((server.ip, server.port))
    squatter.listen(1)
    threading.Timer(0.3, squatter.close).start()
    started = time.monotonic()
    server.start()
    try:
        assert server.running and 0.25 < time.monotonic() - started < ads_server.ADDRESS_IN_USE_S
        axis = AdsAxis(server.net_id, server.ip, 1)
        assert not axis.status().error
        axis.close()
    finally:
        server.stop()
    monkeypatch.setattr(ads_server, "ADDRESS_IN_USE_S", 0.2)
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        taken.bind((server.ip, server.port))
        taken.listen(1)
        with pytest.raises(OSError) as raised:
            server.start()
    assert raised.value.errno == errno.EADDRINUSE and not server.running

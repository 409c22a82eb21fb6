"""Serve a SimPLC over ADS/TCP on the loopback with pyads' test server.

`stop()` then `start()` simulates a lost PLC connection: the client's TCP connection is dropped
and a new server takes over the same handler, so the PLC variables keep their values.

How pyads' AdsTestServer behaves, and what this class does about it:
- It binds its socket in the constructor and is a Thread, so it can run only once: every
  `start()` makes a new one. The socket has SO_REUSEADDR, so the port is free again at once.
- It only calls listen() when its thread runs, so a client connecting right after start() could be
  refused: `start()` calls listen() itself before starting the thread.
- Its client threads read one TCP segment at a time and take it for one request: a request split
  over two sends went unanswered, several requests in one send got one answer, and a client that
  dropped its connection left a ConnectionResetError traceback. `FramedConnection` frames the
  byte stream by the AMS/TCP header's length instead (each request answered, in order) and logs a
  dropped connection as one line.
- It answers only what a handler returns, and nothing can reach a client unasked: FramedConnection
  is also the client's notification sink (`send_notification`), and after each reply it sends the
  notifications that became due (a new one's first sample); when it ends, the client's
  notifications are deleted.
- It sends with a blocking sendall from the thread that answers, and the PLC's scan would send
  notifications the same way: a client that stops reading would fill its socket buffers and stop
  the scan, and the whole simulated machine with it. FramedConnection puts what it sends, replies
  and notifications in order, in an outgoing queue that a sender thread of its own writes to the
  socket. A reply waits for room in the queue (a client that does not read its replies is no
  longer read, as TCP's flow control does); a notification that finds the queue over
  OUTGOING_LIMIT_BYTES drops the client with one warning line (its connection closed, its
  notifications deleted), and the other clients and the PLC go on. The scan never waits on a client.
- A packet whose AMS/TCP header is a router command (port register 0x1000 and the like, which a
  client without a local AMS Net ID sends to its own router) is not an ADS request: it gets one
  warning line saying so (the first on a connection; the next go unanswered silently) and no
  answer, as a TwinCAT PLC gives a remote client none.
- It bounds nothing a client sends. FramedConnection bounds what one client can make the PLC
  spend: an AMS/TCP header announcing more than PACKET_LIMIT_BYTES or less than an AMS header, or
  whose first two bytes are neither 0 (an AMS packet) nor a router command (0x10xx: `GET /
  HTTP/1.1` is neither), is refused
  before anything more is read: one warning line, the connection closed. A packet that has not
  arrived whole PACKET_TIMEOUT_S after its first byte (half a frame, then silence) closes the
  connection the same way. All clients together hold at most PENDING_TOTAL_LIMIT_BYTES of
  unfinished packets (a client beyond it is closed). What a request may ask for is bounded by the device
  (`drivers.sim.ads_device`: REPLY_LIMIT_BYTES, NOTIFICATIONS_PER_CLIENT).
- It keeps every request in `request_history`, for good (about 0.75 kB each: a polling client
  grew the demo by 75 MB in 100,000 requests). FramedConnection answers without it: the history
  stays empty.
- It listens with a backlog of 5, so of 200 clients connecting at once most waited for the
  kernel's SYN retries (seconds to tens of seconds). `start()` listens with LISTEN_BACKLOG (the
  kernel caps it at net.core.somaxconn).
- It keeps every connection in `clients` after it ended. FramedServer lets the ended ones go at
  each accept, and closes a connection beyond CLIENT_LIMIT at once.
- Its stop() joins the client threads but not its own thread and closes the listening socket under
  it: `stop()` ends the accept loop and joins that thread first, then lets the server close the
  client threads (joined) and the socket. No thread is left behind.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import select
import socket
import struct
import threading
import time
from collections import deque
from types import TracebackType
from typing import Self

from pyads.testserver import AdsTestServer
from pyads.testserver.handler import AmsResponseData
from pyads.testserver.testserver import AdsClientConnection

from drivers.sim.ads_device import AdsDevice
from drivers.sim.plc import SimPLC

ADS_TCP_PORT = 48898
AMS_TCP_HEADER_BYTES = 6
"""Two reserved bytes, then the length of the AMS packet that follows (uint32, little-endian)."""
AMS_HEADER_BYTES = 32
OUTGOING_LIMIT_BYTES = 1 << 20
"""A client whose outgoing queue holds more than this many bytes when a notification is due is
dropped (the queue grows only once the socket's own buffers, sized by the kernel, are full)."""
OUTGOING_TOTAL_LIMIT_BYTES = 16 << 20
"""What all clients together may have queued (replies and notifications), bytes: each may have
OUTGOING_LIMIT_BYTES, so a thousand clients that send reads and never read the replies held a
GiB; a client with something queued already whose next packet would go beyond it is dropped
(one warning line). A client that reads its replies has an empty queue and is always served."""
CLOSE_DRAIN_S = 1.0
"""How long a connection that ends waits for its queued replies to go out, s (wall time)."""
PACKET_LIMIT_BYTES = 1 << 20
"""The largest AMS packet (after the AMS/TCP header) the PLC takes; one announcing more closes the
connection. The PLC's memory is 16.8 kB: a write of all of it, or a sum request over it, fits
sixty times over."""
PENDING_TOTAL_LIMIT_BYTES = 16 << 20
"""What all clients together may have the PLC hold of packets not yet arrived whole, bytes: each
connection may hold one of up to PACKET_LIMIT_BYTES, so without a common budget a thousand of them
held a GiB; a client whose bytes would go beyond it is closed (one warning line)."""
PACKET_TIMEOUT_S = 5.0
"""How long a packet may take to arrive whole after its first byte, s (wall time); a client that
sends part of one and then nothing is closed after it."""
LISTEN_BACKLOG = 1024
"""Connections the kernel holds while the accept loop catches up (hundreds of clients at once)."""
CLIENT_LIMIT = 1000
"""Clients connected at once (two threads each); one more is closed at once, with one warning line
while the PLC is full."""
ROUTER_COMMANDS = range(0x1000, 0x1100)
"""AMS/TCP header commands of the AMS router (port register 0x1000, close, connect, notification,
get local Net ID); any other non-zero value there is not ADS."""

log = logging.getLogger(__name__)


class FramedConnection(AdsClientConnection):
    """One ADS client: the byte stream cut into AMS packets by their AMS/TCP length, each answered
    in the order it came, whatever the TCP segments were; what goes to the client (replies and
    notifications, in order) through a bounded queue that a sender thread writes to its socket."""

    handler: AdsDevice

    def __init__(self, handler: AdsDevice, client: socket.socket, address: tuple[str, int], server: AdsTestServer):
        super().__init__(handler=handler, client=client, address=address, server=server)
        self._outgoing: deque[bytes] = deque()
        self._outgoing_bytes = 0
        """Bytes in `_outgoing` (not counting the packet the sender is writing)."""
        self._open = True
        """False once the connection ends: nothing more is queued."""
        self._changed = threading.Condition()
        """Guards the three above; notified when they change."""
        self._router_warned = False
        """A router command was warned about (once a connection: a flood of them is one line)."""
        self._sender = threading.Thread(target=self._send_queued, daemon=True,
                                        name=f"ADS sender {address[0]}:{address[1]}")

    def run(self) -> None:
        self._run = True
        self._sender.start()
        try:
            self._serve()
        finally:
            self.handler.drop_notifications(self)
            self._close()

    def _serve(self) -> None:
        held = [0]  # bytes of `pending` counted against the server's PENDING_TOTAL_LIMIT_BYTES
        try:
            self._serve_held(held)
        finally:
            _hold(self.server, -held[0])

    def _serve_held(self, held: list[int]) -> None:
        pending = bytearray()
        started = 0.0  # time.monotonic() when the first byte of the packet in `pending` came
        timeout_s = getattr(self.server, "packet_timeout_s", PACKET_TIMEOUT_S)
        poller = select.poll()  # not select(): a client's descriptor may be above 1023 (CLIENT_LIMIT)
        poller.register(self.client, select.POLLIN)
        while self._run:
            ready = poller.poll(100)
            if not ready:
                if pending and time.monotonic() - started > timeout_s:
                    self._lost(f"sent {len(pending)} bytes of a packet and not the rest within {timeout_s:g} s: "
                               "connection closed")
                    return
                continue
            try:
                data = self.client.recv(65536)
            except OSError as exc:  # ConnectionResetError: the client went away without closing
                self._lost(f"dropped the connection ({exc.strerror or exc})")
                return
            if not data:
                return
            if not pending:
                started = time.monotonic()
            if not _hold(self.server, len(data)):
                self._lost(f"sent {len(pending) + len(data)} bytes of unfinished packets while the clients together "
                           f"hold {PENDING_TOTAL_LIMIT_BYTES} (the PLC's limit): connection closed")
                return
            held[0] += len(data)
            pending += data
            while len(pending) >= AMS_TCP_HEADER_BYTES and self._run:
                refused = _refusal(pending)
                if refused:
                    self._lost(f"{refused}: connection closed")
                    return
                end = AMS_TCP_HEADER_BYTES + struct.unpack_from("<I", pending, 2)[0]
                if len(pending) < end:
                    break  # the rest of this packet is still on its way
                packet = bytes(pending[:end])
                del pending[:end]
                _hold(self.server, -end)
                held[0] -= end
                started = time.monotonic()
                self._answer(packet)

    def _answer(self, packet: bytes) -> None:
        router_command = struct.unpack_from("<H", packet)[0]
        if router_command:
            if self._router_warned:
                return
            self._router_warned = True
            log.warning("ADS client %s:%s sent AMS/TCP router command 0x%04x, which a PLC does not serve to a remote "
                        "client: give the client its own AMS Net ID and port", *self.client_address[:2],
                        router_command)
            return
        request = self.construct_request(packet)  # kept nowhere: pyads' request_history stays empty
        response = self.handler.handle_request(request, sink=self)
        if isinstance(response, AmsResponseData):
            self._queue_reply(self.construct_response(response, request))
            for client, notification in self.handler.due_notifications():
                client.send_notification(notification)

    def send_notification(self, packet: bytes) -> None:
        """Queue a notification packet for this client (from any thread, never waiting). When the
        queue already holds more than OUTGOING_LIMIT_BYTES, the client is dropped instead."""
        with self._changed:
            if not self._open:
                return
            waiting = self._outgoing_bytes
            if (not self._outgoing or waiting + len(packet) <= OUTGOING_LIMIT_BYTES) and self._append(packet):
                return
        self._lost(f"does not read what the PLC sends ({waiting} bytes waiting, the limit is "
                   f"{OUTGOING_LIMIT_BYTES} a client and {OUTGOING_TOTAL_LIMIT_BYTES} for all): connection dropped")

    def _queue_reply(self, data: bytes) -> None:
        """Queue a reply, waiting for room (this client's own thread waits, nobody else)."""
        with self._changed:
            while (self._open and self._run and self._outgoing
                   and self._outgoing_bytes + len(data) > OUTGOING_LIMIT_BYTES):
                self._changed.wait(0.1)
            waiting = self._outgoing_bytes
            if not self._open or self._append(data):
                return
        self._lost(f"does not read its replies ({waiting} bytes waiting) while the clients together have "
                   f"{OUTGOING_TOTAL_LIMIT_BYTES} waiting (the PLC's limit): connection dropped")

    def _append(self, data: bytes) -> bool:
        """Queue `data` (under `_changed`), counted against the server's OUTGOING_TOTAL_LIMIT_BYTES;
        False, and nothing queued, when that budget is spent and this client has something waiting
        already (an empty queue, a client that reads, always gets its packet in)."""
        if not _budget(self.server, "outgoing_bytes", OUTGOING_TOTAL_LIMIT_BYTES, len(data),
                       force=not self._outgoing):
            return False
        self._outgoing.append(data)
        self._outgoing_bytes += len(data)
        self._changed.notify_all()
        return True

    def _send_queued(self) -> None:
        """The sender thread: write what is queued, in order, until the connection ends and the
        queue is empty (a lost connection empties it)."""
        while True:
            with self._changed:
                while self._open and not self._outgoing:
                    self._changed.wait()
                if not self._outgoing:
                    return
                data = self._outgoing.popleft()
                self._outgoing_bytes -= len(data)
                _budget(self.server, "outgoing_bytes", OUTGOING_TOTAL_LIMIT_BYTES, -len(data))
                self._changed.notify_all()
            try:
                self.client.sendall(data)
            except OSError as exc:
                self._lost(f"dropped the connection ({exc.strerror or exc})")
                return

    def _lost(self, why: str) -> None:
        """End the connection now, what is queued unsent, with one warning line saying why (only the
        first reason is said: the threads that notice next stay silent)."""
        with self._changed:
            if not self._open:
                return
            self._open = False
            self._outgoing.clear()
            _budget(self.server, "outgoing_bytes", OUTGOING_TOTAL_LIMIT_BYTES, -self._outgoing_bytes)
            self._outgoing_bytes = 0
            self._changed.notify_all()
        log.warning("ADS client %s:%s %s", *self.client_address[:2], why)
        self._run = False
        with contextlib.suppress(OSError):  # wakes a sendall blocked on it and the reading thread
            self.client.shutdown(socket.SHUT_RDWR)

    def _close(self) -> None:
        """Let the sender write what is queued (at most CLOSE_DRAIN_S), then close the socket."""
        with self._changed:
            self._open = False
            self._changed.notify_all()
        self._sender.join(CLOSE_DRAIN_S)
        if self._sender.is_alive():  # blocked on a client that does not read
            with contextlib.suppress(OSError):
                self.client.shutdown(socket.SHUT_RDWR)
            self._sender.join()
        self.client.close()


def _hold(server: object, change: int) -> bool:
    """Count `change` bytes of unfinished packets against the server's PENDING_TOTAL_LIMIT_BYTES
    (a negative change gives them back); False, and nothing counted, when they do not fit."""
    return _budget(server, "pending_bytes", PENDING_TOTAL_LIMIT_BYTES, change)


def _budget(server: object, name: str, limit: int, change: int, force: bool = False) -> bool:
    """Count `change` bytes against the server's counter `name` (pending_bytes, outgoing_bytes),
    bounded by `limit` unless `force`; a negative change gives bytes back. False, and nothing
    counted, when they do not fit."""
    lock = getattr(server, "budget_lock", None)
    if lock is None:  # pyads' own server: no budget
        return True
    with lock:
        total = getattr(server, name) + change
        if change > 0 and not force and total > limit:
            return False
        setattr(server, name, total)
        return True


def _refusal(pending: bytearray) -> str:
    """Why the AMS/TCP header at the start of `pending` is refused ("" when it is not): a length
    beyond PACKET_LIMIT_BYTES, an AMS packet too short for its header, or a first field that is
    neither an AMS packet nor a router command."""
    command, length = struct.unpack_from("<HI", pending)
    if command and command not in ROUTER_COMMANDS:
        return f"sent an AMS/TCP header that is not ADS (starting {bytes(pending[:6])!r})"
    if length > PACKET_LIMIT_BYTES:
        return f"announced an AMS packet of {length} bytes, more than the {PACKET_LIMIT_BYTES} the PLC takes"
    if not command and length < AMS_HEADER_BYTES:
        return f"announced an AMS packet of {length} bytes, too short for an AMS header ({AMS_HEADER_BYTES})"
    return ""


class FramedServer(AdsTestServer):
    """pyads' test server with FramedConnection for every client. `packet_timeout_s`: how long a
    packet may take to arrive whole after its first byte (PACKET_TIMEOUT_S unless set)."""

    clients: list[AdsClientConnection]
    packet_timeout_s = PACKET_TIMEOUT_S
    pending_bytes = 0
    """Bytes of unfinished packets all its clients hold now (PENDING_TOTAL_LIMIT_BYTES bounds it)."""
    outgoing_bytes = 0
    """Bytes of replies and notifications queued for all its clients now (OUTGOING_TOTAL_LIMIT_BYTES)."""
    budget_lock = threading.Lock()
    _full = False
    """CLIENT_LIMIT was reached and said (one warning line until a client leaves)."""

    def run(self) -> None:
        self._run = True
        poller = select.poll()  # not select(): it refuses a descriptor above 1023
        poller.register(self.server, select.POLLIN)
        while self._run:
            ready = poller.poll(100)
            if not ready:
                continue
            try:
                client, address = self.server.accept()
            except OSError:
                continue
            self.clients = [c for c in self.clients if c.is_alive()]  # the ended ones are let go
            if len(self.clients) >= CLIENT_LIMIT:
                client.close()
                if not self._full:
                    self._full = True
                    log.warning("ADS client %s:%s refused: %d clients connected, the most the PLC serves (the next "
                                "refused stay silent until one leaves)", *address[:2], CLIENT_LIMIT)
                continue
            self._full = False
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            connection = FramedConnection(handler=self.handler, client=client, address=address, server=self)
            connection.daemon = True
            self.clients.append(connection)  # counted before it can answer
            connection.start()


ADDRESS_IN_USE_S = 2.0
"""How long (real time) start() tries again while its address is in use. The fault rehearsal's server,
started again after `ads_lost` on its own loopback address, once found it in use (errno 98) in a full
suite run on a loaded machine; what still held it is not known (not reproduced in 6 runs side by side)."""


class SimAdsServer:
    """The ADS server of a simulated PLC at ip:port (the port every ADS client connects to)."""

    def __init__(self, plc: SimPLC, ip: str = "127.0.0.1", port: int = ADS_TCP_PORT,
                 packet_timeout_s: float = PACKET_TIMEOUT_S):
        """`packet_timeout_s`: how long a packet may take to arrive whole after its first byte, s."""
        self.plc = plc
        self.ip = ip
        self.port = port
        self.packet_timeout_s = packet_timeout_s
        self._server: AdsTestServer | None = None

    @property
    def net_id(self) -> str:
        """The PLC's AMS Net ID: its IP address and .1.1, as TwinCAT sets it by default."""
        return f"{self.ip}.1.1"

    @property
    def running(self) -> bool:
        return self._server is not None

    def start(self) -> None:
        """Accept ADS clients from now on (no-op when already running). The address in use is tried
        again for up to ADDRESS_IN_USE_S (real time) before the OSError is raised."""
        if self._server is not None:
            return
        self.plc.handler.net_id = self.net_id
        deadline = time.monotonic() + ADDRESS_IN_USE_S
        while True:
            try:
                self._server = self._listening()
                return
            except OSError as e:
                if e.errno != errno.EADDRINUSE or time.monotonic() > deadline:
                    raise
            time.sleep(0.05)

    def _listening(self) -> FramedServer:
        server = FramedServer(handler=self.plc.handler, ip_address=self.ip, port=self.port, logging=False)
        server.packet_timeout_s = self.packet_timeout_s
        try:
            server.server.listen(LISTEN_BACKLOG)
            server.start()
        except BaseException:
            server.server.close()
            raise
        return server

    def stop(self) -> None:
        """Drop every client connection and stop listening; all server threads are joined."""
        server, self._server = self._server, None
        if server is None:
            return
        server._run = False  # ends the accept loop within its 0.1 s select timeout
        server.join()
        server.close()  # closes and joins the client threads, closes the listening socket

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

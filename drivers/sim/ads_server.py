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
  is also the client's notification sink (`send_notification`, serialised with the replies), and
  after each reply it sends the notifications that became due (a new one's first sample); when it
  ends, the client's notifications are deleted.
- A packet whose AMS/TCP header is a router command (port register 0x1000 and the like, which a
  client without a local AMS Net ID sends to its own router) is not an ADS request: it gets one
  warning line saying so and no answer, as a TwinCAT PLC gives a remote client none.
- Its stop() joins the client threads but not its own thread and closes the listening socket under
  it: `stop()` ends the accept loop and joins that thread first, then lets the server close the
  client threads (joined) and the socket. No thread is left behind.
"""

from __future__ import annotations

import logging
import select
import socket
import struct
import threading
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

log = logging.getLogger(__name__)


class FramedConnection(AdsClientConnection):
    """One ADS client: the byte stream cut into AMS packets by their AMS/TCP length, each answered
    in the order it came, whatever the TCP segments were."""

    handler: AdsDevice

    def __init__(self, handler: AdsDevice, client: socket.socket, address: tuple[str, int], server: AdsTestServer):
        super().__init__(handler=handler, client=client, address=address, server=server)
        self._send_lock = threading.Lock()
        """Held while sending and while closing: replies (this thread) and notifications (the PLC's
        scan) never interleave, and nothing is sent on a closed socket."""

    def run(self) -> None:
        self._run = True
        try:
            self._serve()
        finally:
            self.handler.drop_notifications(self)
            with self._send_lock:
                self._run = False
                self.client.close()

    def _serve(self) -> None:
        pending = b""
        while self._run:
            ready, _, _ = select.select([self.client], [], [], 0.1)
            if not ready:
                continue
            try:
                data = self.client.recv(65536)
            except OSError as exc:  # ConnectionResetError: the client went away without closing
                log.warning("ADS client %s:%s dropped the connection (%s)", *self.client_address[:2],
                            exc.strerror or exc)
                return
            if not data:
                return
            pending += data
            while len(pending) >= AMS_TCP_HEADER_BYTES and self._run:
                length = struct.unpack_from("<I", pending, 2)[0]
                if len(pending) < AMS_TCP_HEADER_BYTES + length:
                    break  # the rest of this packet is still on its way
                packet, pending = pending[:AMS_TCP_HEADER_BYTES + length], pending[AMS_TCP_HEADER_BYTES + length:]
                self._answer(packet)

    def _answer(self, packet: bytes) -> None:
        router_command = struct.unpack_from("<H", packet)[0]
        if router_command:
            log.warning("ADS client %s:%s sent AMS/TCP router command 0x%04x, which a PLC does not serve to a remote "
                        "client: give the client its own AMS Net ID and port", *self.client_address[:2],
                        router_command)
            return
        if len(packet) < AMS_TCP_HEADER_BYTES + AMS_HEADER_BYTES:
            log.warning("ADS client %s:%s sent a packet too short for an AMS header (%d bytes): ignored",
                        *self.client_address[:2], len(packet))
            return
        request = self.construct_request(packet)
        self.server.request_history.append(request)
        response = self.handler.handle_request(request, sink=self)
        if isinstance(response, AmsResponseData):
            self._send(self.construct_response(response, request))
            for client, notification in self.handler.due_notifications():
                client.send_notification(notification)

    def send_notification(self, packet: bytes) -> None:
        """Send a notification packet to this client (from any thread)."""
        self._send(packet)

    def _send(self, data: bytes) -> None:
        with self._send_lock:
            if not self._run:
                return
            try:
                self.client.sendall(data)
            except OSError as exc:
                log.warning("ADS client %s:%s dropped the connection (%s)", *self.client_address[:2],
                            exc.strerror or exc)
                self._run = False


class FramedServer(AdsTestServer):
    """pyads' test server with FramedConnection for every client."""

    def run(self) -> None:
        self._run = True
        while self._run:
            ready, _, _ = select.select([self.server], [], [], 0.1)
            if not ready:
                continue
            try:
                client, address = self.server.accept()
            except OSError:
                continue
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            connection = FramedConnection(handler=self.handler, client=client, address=address, server=self)
            connection.daemon = True
            connection.start()
            self.clients.append(connection)


class SimAdsServer:
    """The ADS server of a simulated PLC at ip:port (the port every ADS client connects to)."""

    def __init__(self, plc: SimPLC, ip: str = "127.0.0.1", port: int = ADS_TCP_PORT):
        self.plc = plc
        self.ip = ip
        self.port = port
        self._server: AdsTestServer | None = None

    @property
    def net_id(self) -> str:
        """The PLC's AMS Net ID: its IP address and .1.1, as TwinCAT sets it by default."""
        return f"{self.ip}.1.1"

    @property
    def running(self) -> bool:
        return self._server is not None

    def start(self) -> None:
        """Accept ADS clients from now on (no-op when already running)."""
        if self._server is not None:
            return
        self.plc.handler.net_id = self.net_id
        server = FramedServer(handler=self.plc.handler, ip_address=self.ip, port=self.port, logging=False)
        try:
            server.server.listen(5)
            server.start()
        except BaseException:
            server.server.close()
            raise
        self._server = server

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

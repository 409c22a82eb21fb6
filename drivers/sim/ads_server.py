"""Serve a SimPLC over ADS/TCP on the loopback with pyads' test server.

`stop()` then `start()` simulates a lost PLC connection: the client's TCP connection is dropped
and a new server takes over the same handler, so the PLC variables keep their values.

How pyads' AdsTestServer behaves, and what this class does about it:
- It binds its socket in the constructor and is a Thread, so it can run only once: every
  `start()` makes a new one. The socket has SO_REUSEADDR, so the port is free again at once.
- It only calls listen() when its thread runs, so a client connecting right after start() could be
  refused: `start()` calls listen() itself before starting the thread.
- Its stop() joins the client threads but not its own thread and closes the listening socket under
  it: `stop()` ends the accept loop and joins that thread first, then lets the server close the
  client threads (joined) and the socket. No thread is left behind.
"""

from __future__ import annotations

from types import TracebackType
from typing import Self

from pyads.testserver import AdsTestServer

from drivers.sim.plc import SimPLC

ADS_TCP_PORT = 48898


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
        server = AdsTestServer(handler=self.plc.handler, ip_address=self.ip, port=self.port, logging=False)
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

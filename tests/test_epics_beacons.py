"""The simulated IOC's Channel Access beacons stay on loopback, whatever this process's environment
says, at the first start and after a restart (the ca_lost fault): a beacon sent to 255.255.255.255
leaves the machine, which a workplace's network monitoring flags."""

from __future__ import annotations

import logging
import os
import socket

from drivers.sim.epics_ioc import LOOPBACK, SimMotorIoc, _not_a_beacon_failure
from drivers.sim.plc import SimPLC


def beacon_hosts(ioc: SimMotorIoc) -> set[str]:
    return {host for host, _ in ioc._context.beacon_socks}


def test_beacons_go_to_loopback_only_at_start_and_after_a_restart(monkeypatch):
    for key in [key for key in os.environ if key.startswith("EPICS_")]:
        monkeypatch.delenv(key)  # caproto's defaults would beacon to 255.255.255.255
    ioc = SimMotorIoc(SimPLC(1, 20.0, 50.0, position=0.0), "SIM:B1", low=-10.0, high=100.0, velocity=5.0)
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        assert beacon_hosts(ioc) == {LOOPBACK}
        assert {port for _, port in ioc._context.beacon_socks} == {ioc.port + 1}
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((LOOPBACK, ioc.port + 1))
        ioc.stop()
        ioc.start()  # the ca_lost fault's way back
        assert beacon_hosts(ioc) == {LOOPBACK}
        listener.settimeout(5.0)
        datagram, sender = listener.recvfrom(1024)  # a beacon on loopback: CA command 13
        assert int.from_bytes(datagram[:2], "big") == 13 and sender[0] == LOOPBACK
        assert not [key for key in os.environ if key.startswith("EPICS_")]  # put back as found
    finally:
        listener.close()
        ioc.close()


def test_a_failed_beacon_is_hidden_only_on_loopback():
    def record(address: tuple[str, int]) -> logging.LogRecord:
        return logging.LogRecord("caproto.ctx", logging.ERROR, __file__, 1,
                                 "Failed to send beacon to %r. Try setting EPICS_CAS_AUTO_BEACON_ADDR_LIST=no "
                                 "and EPICS_CAS_BEACON_ADDR_LIST=<addresses>.", (address,), None)

    assert not _not_a_beacon_failure(record((LOOPBACK, 5065)))
    assert _not_a_beacon_failure(record(("255.255.255.255", 5065)))

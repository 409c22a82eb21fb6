"""ADS packets built and read by hand, from Beckhoff's layout, for the tests of the simulated PLC's
ADS server: an AMS/TCP header (2 reserved bytes, the length), the AMS header (target and source
Net ID and port, command, state flags, data length, error, invoke id), then the command's data."""

from __future__ import annotations

import struct
from dataclasses import dataclass

READ, WRITE, READ_STATE, DEVICE_INFO = 2, 3, 4, 1
ADD_NOTIFICATION, DELETE_NOTIFICATION, DEVICE_NOTIFICATION = 6, 7, 8
REQUEST = 0x0004
"""State flags of a request over TCP with the ADS command bit."""
CLIENT = ("127.0.0.1.1.2", 30000)
TICKS_PER_S = 10_000_000
"""Notification times on the wire are in 100 ns."""


def net_id_bytes(net_id: str) -> bytes:
    return bytes(int(part) for part in net_id.split("."))


def request(net_id: str, command: int, data: bytes = b"", invoke_id: int = 1, port: int = 851) -> bytes:
    """One AMS/TCP packet asking `command` of net_id:port, from CLIENT."""
    ams = (net_id_bytes(net_id) + struct.pack("<H", port) + net_id_bytes(CLIENT[0]) + struct.pack("<H", CLIENT[1])
           + struct.pack("<HHIII", command, REQUEST, len(data), 0, invoke_id) + data)
    return struct.pack("<HI", 0, len(ams)) + ams


def read_state(net_id: str, invoke_id: int, port: int = 851) -> bytes:
    return request(net_id, READ_STATE, b"", invoke_id, port)


def add_notification(net_id: str, group: int, offset: int, length: int, mode: int, max_delay_s: float,
                     cycle_s: float, invoke_id: int = 1, port: int = 851) -> bytes:
    data = struct.pack("<IIIIII16x", group, offset, length, mode, round(max_delay_s * TICKS_PER_S),
                       round(cycle_s * TICKS_PER_S))
    return request(net_id, ADD_NOTIFICATION, data, invoke_id, port)


@dataclass(frozen=True)
class Packet:
    """An AMS packet as received: header fields and the data."""

    target: tuple[str, int]
    source: tuple[str, int]
    command: int
    state_flags: int
    error: int
    invoke_id: int
    data: bytes


def parse(packet: bytes) -> Packet:
    """One whole AMS/TCP packet."""
    reserved, length = struct.unpack_from("<HI", packet)
    assert reserved == 0 and len(packet) == 6 + length
    target, source = packet[6:14], packet[14:22]
    command, flags, data_length, error, invoke_id = struct.unpack_from("<HHIII", packet, 22)
    data = packet[38:]
    assert len(data) == data_length
    return Packet((".".join(map(str, target[:6])), struct.unpack("<H", target[6:])[0]),
                  (".".join(map(str, source[:6])), struct.unpack("<H", source[6:])[0]), command, flags, error,
                  invoke_id, data)


def split(stream: bytes) -> tuple[list[bytes], bytes]:
    """The whole AMS/TCP packets at the start of `stream`, and the rest."""
    packets = []
    while len(stream) >= 6 and len(stream) >= 6 + struct.unpack_from("<I", stream, 2)[0]:
        length = struct.unpack_from("<I", stream, 2)[0]
        packets.append(stream[:6 + length])
        stream = stream[6 + length:]
    return packets, stream


def stamps(data: bytes) -> list[tuple[int, list[tuple[int, bytes]]]]:
    """A Device Notification's data: [(FILETIME in 100 ns, [(handle, sample bytes), ...]), ...]."""
    length, count = struct.unpack_from("<II", data)
    assert length == len(data) - 4
    at, out = 8, []
    for _ in range(count):
        filetime, samples = struct.unpack_from("<QI", data, at)
        at += 12
        items = []
        for _ in range(samples):
            handle, size = struct.unpack_from("<II", data, at)
            items.append((handle, data[at + 8:at + 8 + size]))
            at += 8 + size
        out.append((filetime, items))
    assert at == len(data)
    return out

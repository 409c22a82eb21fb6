"""AMS port 10000 of the simulated PLC: what TwinCAT's system service answers to what a client asks
when it connects and while it watches the connection.

An ADS client that connects to a PLC (ads-client's default connect, TwinCAT's own tools) first
asks the system service whether TwinCAT runs: the extended system state (read index group 0xF0,
16 bytes; TwinCAT 3.1.4022 and newer) or, failing that, ADS Read State; ads-client then polls it
every second to see the connection is alive. The simulated PLC's TwinCAT is always in Run:

- Read State: ADS state Run (5), device state 1;
- Read Device Info: "TwinCAT System", version 3.1.4024;
- Read of index group 0xF0, offset 0: ADS state Run, device state 1, restart index 0, version 3,
  revision 1, build 4024, platform 0 and OS type 0 (not modelled), flags 0, 2 reserved bytes;
- any other read or write: invalid index group (0x702); any other command, notifications and write
  control (Run/Config/Reset of TwinCAT) included: service not supported (0x701).
"""

from __future__ import annotations

import struct

SYSTEM_SERVICE_PORT = 10000
SYSTEM_STATE_GROUP = 0xF0
"""Index group of the extended system state (AdsSysServState)."""
RUN, DEVICE_STATE = 5, 1
VERSION = (3, 1, 4024)
NAME = b"TwinCAT System"
_DEVICE_INFO, _READ, _WRITE, _READ_STATE, _READ_WRITE = 1, 2, 3, 4, 9
SERVICE_NOT_SUPPORTED, INVALID_GROUP, INVALID_SIZE = 0x701, 0x702, 0x705


def system_state() -> bytes:
    """The 16 bytes of the extended system state: ADS state, device state, restart index, version,
    revision, build, platform, OS type, flags, reserved."""
    major, minor, build = VERSION
    return struct.pack("<HHHBBHBBH2x", RUN, DEVICE_STATE, 0, major, minor, build, 0, 0, 0)


def serve_system(command: int, data: bytes) -> tuple[int, bytes]:
    """(ADS result, reply data after the result and, for a read, its length) of a request to port 10000."""
    if command == _DEVICE_INFO:
        major, minor, build = VERSION
        return 0, struct.pack("<BBH16s", major, minor, build, NAME)
    if command == _READ_STATE:
        return 0, struct.pack("<HH", RUN, DEVICE_STATE)
    if command == _READ:
        group, offset, length = struct.unpack("<III", data[:12])
        if group != SYSTEM_STATE_GROUP or offset != 0:
            return INVALID_GROUP, b""
        state = system_state()
        return (INVALID_SIZE, b"") if length < len(state) else (0, state)
    if command in (_WRITE, _READ_WRITE):
        return INVALID_GROUP, b""
    return SERVICE_NOT_SUPPORTED, b""

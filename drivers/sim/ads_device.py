"""The ADS device of the simulated PLC: answers requests as a TwinCAT 3 PLC runtime (port 851) does,
and as TwinCAT's system service (port 10000) does for what a client asks when it connects.

It serves the PLC's memory (`protocols.plc_layout`: GVL_Axiscal with TwinCAT's pack-8 layout)
to the ADS services a client uses: read and write by index group/offset and by handle, handles by
name, symbol information by name, data type information by name, symbol and data type upload,
sum read and sum write, device information and state, the device data group 0xF100 (ADS state and
device state), and device notifications on anything it can read (`drivers.sim.ads_notifications`).
Port 10000 answers as `drivers.sim.ads_system` says. It plugs into `pyads.testserver` as its
handler. What it answers as TwinCAT does:

- an error of the service goes in the reply's result field; the AMS header's error stays 0;
- a request addressed to another AMS Net ID gets 0x7 (target machine not found) and one to a port
  other than the runtime's and 10000 0x6 (target port not found) in the AMS header, as from the
  AMS router;
- a write by handle whose length is not the variable's size gets 0x705 and changes nothing;
- an unknown name or handle gets 0x710, an unknown index group 0x702, an offset outside the
  memory 0x703, a reply longer than the read length asked for 0x705;
- a notification on a range it cannot read gets that read's error, one in a transmission mode
  other than cyclic (3) and on change (4) 0x713 (AdsTransMode not supported), one more than
  NOTIFICATIONS_PER_CLIENT on one connection 0x716 (no more notification handles), the deletion
  of an unknown notification 0x714; a refused notification's reply is 8 bytes, result and handle
  0, as Beckhoff's;
- a sum read (0xF080) whose replies would hold more than REPLY_LIMIT_BYTES gets 0x705, as a
  plain read beyond the memory does, and nothing of it is read;
- a command it does not implement (write control) gets 0x701.

Not modelled: RPC methods, enum values in the data type information, the TwinCAT system symbols
(TwinCAT_SystemInfoVarList and the like), sum notifications.
"""

from __future__ import annotations

import struct
import threading
import time

from pyads.testserver.handler import AbstractHandler, AmsHeader, AmsPacket, AmsResponseData

from drivers.sim.ads_notifications import CYCLIC, ON_CHANGE, Notifications, NotificationSink
from drivers.sim.ads_system import SYSTEM_SERVICE_PORT, serve_system
from protocols import plc_layout
from protocols.plc_layout import DataType

TWINCAT_PLC_PORT = 851
PLC_DATA_GROUP = 0x4040
"""Index group of the PLC's data area (TwinCAT 3); the GVL starts at GVL_OFFSET in it."""
GVL_OFFSET = 0x10000

# ADS commands
_DEVICE_INFO, _READ, _WRITE, _READ_STATE, _READ_WRITE = 1, 2, 3, 4, 9
_ADD_NOTIFICATION, _DELETE_NOTIFICATION, _DEVICE_NOTIFICATION = 6, 7, 8
"""Add's reply is result, then the handle (0 when refused), as Beckhoff's; a client's own Device
Notification (8) gets no reply."""
# reserved index groups
_HANDLE_BY_NAME, _VALUE_BY_HANDLE, _RELEASE_HANDLE = 0xF003, 0xF005, 0xF006
_SYMBOL_VERSION, _SYMBOL_INFO_BY_NAME_EX, _DATA_TYPE_BY_NAME_EX = 0xF008, 0xF009, 0xF011
_SYMBOL_UPLOAD, _UPLOAD_INFO, _DATA_TYPE_UPLOAD, _UPLOAD_INFO2 = 0xF00B, 0xF00C, 0xF00E, 0xF00F
_SUM_READ, _SUM_WRITE = 0xF080, 0xF081
_DEVICE_DATA = 0xF100
"""ADS state (offset 0, 2 bytes) and device state (offset 2, 2 bytes) of the runtime."""
# ADS error codes
TARGET_PORT_NOT_FOUND, TARGET_MACHINE_NOT_FOUND = 0x6, 0x7
SERVICE_NOT_SUPPORTED, INVALID_GROUP, INVALID_OFFSET = 0x701, 0x702, 0x703
INVALID_SIZE, SYMBOL_NOT_FOUND = 0x705, 0x710
TRANS_MODE_NOT_SUPPORTED, INVALID_NOTIFICATION, NO_MORE_NOTIFICATION_HANDLES = 0x713, 0x714, 0x716
REPLY_LIMIT_BYTES = 1 << 20
"""The most data one reply carries (a sum read's results and values): a request asking for more
is refused with 0x705 before anything is read. The PLC's whole memory is 16.8 kB, its symbol and
data type uploads 2.4 kB together, so no client of the contract comes near it."""
NOTIFICATIONS_PER_CLIENT = 256
"""The most device notifications one connection may hold (each keeps its last value and, for a
long maximum delay, up to 64 KiB of samples waiting); one more is refused with 0x716."""

ADS_TYPE_ID = {"BOOL": 33, "INT": 2, "UINT": 18, "UDINT": 19, "LREAL": 5}
"""ADS data type id (ADST_*) of each elementary type; structures are ADST_BIGTYPE."""
ADST_BIGTYPE = 65
_FLAG_DATA_TYPE, _FLAG_DATA_ITEM = 0x1, 0x2
_RUN = 5
_TOP_SYMBOLS = tuple(f"{plc_layout.GVL}.{m}" for m, _, _ in plc_layout.GVL_TYPE.members)


class AdsError(Exception):
    """An ADS error code to answer with."""

    def __init__(self, code: int):
        super().__init__(hex(code))
        self.code = code


def _ads_type(kind: DataType) -> int:
    if kind.element is not None:
        return _ads_type(kind.element)
    return ADS_TYPE_ID[kind.iec_base] if not kind.members else ADST_BIGTYPE


def _strings(*texts: str) -> tuple[list[int], bytes]:
    encoded = [t.encode("ascii") for t in texts]
    return [len(e) for e in encoded], b"".join(e + b"\0" for e in encoded)


def _array_infos(kind: DataType) -> bytes:
    return b"" if kind.bounds is None else struct.pack("<iI", kind.bounds[0], kind.bounds[1] - kind.bounds[0] + 1)


def symbol_entry(var: plc_layout.Variable) -> bytes:
    """An ADS symbol entry (AdsSymbolEntry) of `var`, with its entry length first."""
    (name_len, type_len, comment_len), text = _strings(var.name, var.kind.name, "")
    body = struct.pack("<IIIIHHHHH", PLC_DATA_GROUP, GVL_OFFSET + var.offset, var.size, _ads_type(var.kind),
                       0, 1 if var.kind.bounds else 0, name_len, type_len, comment_len)
    body += text + _array_infos(var.kind)
    return struct.pack("<I", 4 + len(body)) + body


def data_type_entry(kind: DataType, item_name: str | None = None, offset: int = 0) -> bytes:
    """An ADS data type entry (AdsDatatypeEntry) of `kind`, with its entry length first; as a
    structure member (item_name given) it names the member and its offset."""
    if item_name is not None:
        name, type_name, flags = item_name, kind.name, _FLAG_DATA_ITEM
    else:
        name = kind.name
        type_name = kind.element.name if kind.element else (kind.base or "")
        flags = _FLAG_DATA_TYPE
    (name_len, type_len, comment_len), text = _strings(name, type_name, "")
    members = () if item_name is not None else kind.members
    body = struct.pack("<IIIIIIIHHHHH", 1, 0, 0, kind.size, offset, _ads_type(kind), flags,
                       name_len, type_len, comment_len, 1 if kind.bounds and item_name is None else 0,
                       len(members))
    body += text + (_array_infos(kind) if item_name is None else b"")
    body += b"".join(data_type_entry(member, member_name, at) for member_name, member, at in members)
    return struct.pack("<I", 4 + len(body)) + body


class AdsDevice(AbstractHandler):
    """TwinCAT-like answers over `memory` (the GVL's bytes), each while holding `lock`.

    net_id: the AMS Net ID this device answers to ("" answers to any; `SimAdsServer` sets it).
    writes: how many write services changed memory (the simulated compensation rereads the
    table only after one).
    time_s: the simulated time of the PLC's last scan, s (the PLC sets it at each scan).
    notifications: the clients' device notifications; the PLC samples them at each scan
    (`collect_notifications`).
    """

    def __init__(self, memory: bytearray, lock: threading.Lock, start_time: float = 0.0):
        self.memory = memory
        self.lock = lock
        self.net_id = ""
        self.port = TWINCAT_PLC_PORT
        self.writes = 0
        self.time_s = start_time
        self.notifications = Notifications(epoch_s=time.time() - start_time)
        self._handles: dict[int, plc_layout.Variable] = {}
        self._next_handle = 0x1000

    def handle_request(self, request: AmsPacket, sink: NotificationSink | None = None) -> AmsResponseData | None:
        """The reply to `request` (None for a client's own Device Notification, which gets none).
        `sink`: the client's connection, where the notifications it asks for go."""
        header = request.ams_header
        state = struct.pack("<H", struct.unpack("<H", header.state_flags)[0] | 0x0001)
        port = struct.unpack("<H", header.target_port)[0]
        routed = self._route_error(header.target_net_id, port)
        if routed:
            return AmsResponseData(state, struct.pack("<I", routed), b"")
        command = struct.unpack("<H", header.command_id)[0]
        if command == _DEVICE_NOTIFICATION:
            return None
        if port == SYSTEM_SERVICE_PORT:
            try:
                result, data = serve_system(command, header.data)
            except struct.error:
                result, data = INVALID_SIZE, b""
        else:
            with self.lock:
                try:
                    data = self._serve(command, header.data, sink, header)
                    result = 0
                except AdsError as e:
                    data, result = b"", e.code
                except (struct.error, UnicodeDecodeError):
                    data, result = b"", INVALID_SIZE
        body = struct.pack("<I", result)
        if command in (_READ, _READ_WRITE):
            body += struct.pack("<I", len(data))
        if command == _ADD_NOTIFICATION and result:
            body += struct.pack("<I", 0)  # the handle: none given
        return AmsResponseData(state, struct.pack("<I", 0), body + data)

    def _route_error(self, net_id: bytes, port: int) -> int:
        if self.net_id and ".".join(str(b) for b in net_id) != self.net_id:
            return TARGET_MACHINE_NOT_FOUND
        return TARGET_PORT_NOT_FOUND if port not in (self.port, SYSTEM_SERVICE_PORT) else 0

    # --- notifications -----------------------------------------------------------------------

    def collect_notifications(self, t_s: float, sample: bool = True) -> list[tuple[NotificationSink, bytes]]:
        """The notification packets due at simulated time t_s, sampling first when `sample`
        (the PLC's scan); the caller holds `lock` and sends them after releasing it."""
        return self.notifications.collect(t_s, self._read if sample else None)

    def due_notifications(self) -> list[tuple[NotificationSink, bytes]]:
        """The packets already due (a new notification's first sample when its maximum delay
        is 0), without sampling; takes `lock` itself."""
        with self.lock:
            return self.collect_notifications(self.time_s, sample=False)

    def drop_notifications(self, sink: NotificationSink) -> None:
        with self.lock:
            self.notifications.drop(sink)

    def _add_notification(self, data: bytes, sink: NotificationSink | None, header: AmsHeader) -> bytes:
        group, offset, length, mode, max_delay, cycle = struct.unpack("<IIIIII", data[:24])
        value = self._read(group, offset, length)
        if len(value) != length:
            raise AdsError(INVALID_SIZE)
        if sink is None:
            raise AdsError(SERVICE_NOT_SUPPORTED)
        if mode not in (CYCLIC, ON_CHANGE):
            raise AdsError(TRANS_MODE_NOT_SUPPORTED)
        if self.notifications.count(sink) >= NOTIFICATIONS_PER_CLIENT:
            raise AdsError(NO_MORE_NOTIFICATION_HANDLES)
        route = header.source_net_id + header.source_port + header.target_net_id + header.target_port
        handle = self.notifications.add(sink, route, group, offset, length, mode, cycle, max_delay, value,
                                        self.time_s)
        return struct.pack("<I", handle)

    def _delete_notification(self, data: bytes, sink: NotificationSink | None) -> bytes:
        handle = struct.unpack("<I", data[:4])[0]
        if sink is None or not self.notifications.delete(handle, sink):
            raise AdsError(INVALID_NOTIFICATION)
        return b""

    def _serve(self, command: int, data: bytes, sink: NotificationSink | None = None,
               header: AmsHeader | None = None) -> bytes:
        if command == _ADD_NOTIFICATION and header is not None:
            return self._add_notification(data, sink, header)
        if command == _DELETE_NOTIFICATION:
            return self._delete_notification(data, sink)
        if command == _DEVICE_INFO:
            return struct.pack("<BBH16s", 3, 1, 4024, b"Plc30 App")
        if command == _READ_STATE:
            return struct.pack("<HH", _RUN, 0)
        if command == _READ:
            group, offset, length = struct.unpack("<III", data[:12])
            return self._fit(self._read(group, offset, length), length)
        if command == _WRITE:
            group, offset, length = struct.unpack("<III", data[:12])
            self._write(group, offset, data[12:12 + length])
            return b""
        if command == _READ_WRITE:
            group, offset, read_length, write_length = struct.unpack("<IIII", data[:16])
            if group == _HANDLE_BY_NAME and read_length > 4:  # TwinCAT 3 then adds the size and type
                return self._fit(self._extended_handle(data[16:16 + write_length]), read_length)
            return self._fit(self._read_write(group, offset, data[16:16 + write_length]), read_length)
        raise AdsError(SERVICE_NOT_SUPPORTED)

    @staticmethod
    def _fit(reply: bytes, length: int) -> bytes:
        if len(reply) > length:
            raise AdsError(INVALID_SIZE)
        return reply

    # --- services ----------------------------------------------------------------------------

    def _read(self, group: int, offset: int, length: int) -> bytes:
        if group == _VALUE_BY_HANDLE:
            var = self._handle(offset)
            return self._slice(var.offset, min(length, var.size))
        if group == PLC_DATA_GROUP:
            return self._slice(offset - GVL_OFFSET, length)
        if group == _SYMBOL_VERSION:
            return b"\x01"
        if group == _DEVICE_DATA:
            state = struct.pack("<HH", _RUN, 0)
            if offset >= len(state):
                raise AdsError(INVALID_OFFSET)
            return state[offset:offset + length]
        if group == _UPLOAD_INFO:
            symbols = self._upload()
            return struct.pack("<II", len(_TOP_SYMBOLS), len(symbols))
        if group == _UPLOAD_INFO2:
            symbols, types = self._upload(), self._type_upload()
            return struct.pack("<IIIIII", len(_TOP_SYMBOLS), len(symbols), len(plc_layout.DATA_TYPES), len(types),
                               0, 0)
        if group == _SYMBOL_UPLOAD:
            return self._upload()
        if group == _DATA_TYPE_UPLOAD:
            return self._type_upload()
        raise AdsError(INVALID_GROUP)

    def _write(self, group: int, offset: int, value: bytes) -> None:
        if group == _RELEASE_HANDLE:
            handle = struct.unpack("<I", value[:4])[0]
            if self._handles.pop(handle, None) is None:
                raise AdsError(SYMBOL_NOT_FOUND)
            return
        if group == _VALUE_BY_HANDLE:
            var = self._handle(offset)
            if len(value) != var.size:
                raise AdsError(INVALID_SIZE)
            start = var.offset
        elif group == PLC_DATA_GROUP:
            start = offset - GVL_OFFSET
            self._slice(start, len(value))  # checks the range
        else:
            raise AdsError(INVALID_GROUP)
        self.memory[start:start + len(value)] = value
        self.writes += 1

    def _read_write(self, group: int, offset: int, value: bytes) -> bytes:
        if group == _HANDLE_BY_NAME:
            var = self._variable(value)
            handle, self._next_handle = self._next_handle, self._next_handle + 1
            self._handles[handle] = var
            return struct.pack("<I", handle)
        if group == _SYMBOL_INFO_BY_NAME_EX:
            return symbol_entry(self._variable(value))
        if group == _DATA_TYPE_BY_NAME_EX:
            name = value.split(b"\0", 1)[0].decode("ascii").strip()
            kind = plc_layout.DATA_TYPES.get(name.lower())
            if kind is None:
                raise AdsError(SYMBOL_NOT_FOUND)
            return data_type_entry(kind)
        if group == _SUM_READ:
            return self._sum_read(offset, value)
        if group == _SUM_WRITE:
            return self._sum_write(offset, value)
        raise AdsError(INVALID_GROUP)

    def _extended_handle(self, name: bytes) -> bytes:
        handle = self._read_write(_HANDLE_BY_NAME, 0, name)
        var = self._handles[struct.unpack("<I", handle)[0]]
        type_name = var.kind.name.encode("ascii")
        return handle + struct.pack("<IIH", var.size, 0, len(type_name)) + type_name + b"\0"

    def _sum_read(self, count: int, value: bytes) -> bytes:
        if 12 * count > len(value):
            raise AdsError(INVALID_SIZE)
        entries = [struct.unpack_from("<III", value, 12 * i) for i in range(count)]
        if 4 * count + sum(length for _, _, length in entries) > REPLY_LIMIT_BYTES:
            raise AdsError(INVALID_SIZE)
        results, data = [], []
        for group, offset, length in entries:
            try:
                part, code = self._fit(self._read(group, offset, length), length), 0
            except AdsError as e:
                part, code = b"", e.code
            results.append(struct.pack("<I", code))
            data.append(part.ljust(length, b"\0"))
        return b"".join(results + data)

    def _sum_write(self, count: int, value: bytes) -> bytes:
        if 12 * count > len(value):
            raise AdsError(INVALID_SIZE)
        results, at = [], 12 * count
        for i in range(count):
            group, offset, length = struct.unpack_from("<III", value, 12 * i)
            try:
                self._write(group, offset, value[at:at + length])
                code = 0
            except AdsError as e:
                code = e.code
            results.append(struct.pack("<I", code))
            at += length
        return b"".join(results)

    # --- helpers -----------------------------------------------------------------------------

    def _variable(self, name: bytes) -> plc_layout.Variable:
        var = plc_layout.resolve(name.split(b"\0", 1)[0].decode("ascii"))
        if var is None:
            raise AdsError(SYMBOL_NOT_FOUND)
        return var

    def _handle(self, handle: int) -> plc_layout.Variable:
        var = self._handles.get(handle)
        if var is None:
            raise AdsError(SYMBOL_NOT_FOUND)
        return var

    def _slice(self, start: int, length: int) -> bytes:
        if start < 0 or start >= len(self.memory):
            raise AdsError(INVALID_OFFSET)
        if start + length > len(self.memory):
            raise AdsError(INVALID_SIZE)
        return bytes(self.memory[start:start + length])

    @staticmethod
    def _upload() -> bytes:
        return b"".join(symbol_entry(plc_layout.require(name)) for name in _TOP_SYMBOLS)

    @staticmethod
    def _type_upload() -> bytes:
        return b"".join(data_type_entry(kind) for kind in plc_layout.DATA_TYPES.values())

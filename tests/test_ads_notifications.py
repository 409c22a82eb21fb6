"""Device notifications and AMS port 10000 of the simulated PLC, in process (fast tier): requests
built by hand (tests/ads_wire.py) go to the PLC's ADS device, the notifications it pushes are
recorded by a client connection stand-in and read back by hand. What a notification promises
(issue 26 item 5): a first sample at once, on change only when the value changed, cyclic every
cycle time, nothing held longer than the maximum delay; its deletion; refusals in Beckhoff's
8-byte layout. The same over TCP with third-party clients: tests/test_ads_clients.py."""

from __future__ import annotations

import struct
from itertools import pairwise

import pytest
from pyads.testserver.testserver import AdsClientConnection

from drivers.sim.ads_device import GVL_OFFSET, PLC_DATA_GROUP
from drivers.sim.ads_notifications import FILETIME_AT_UNIX_EPOCH, WAITING_LIMIT_BYTES
from drivers.sim.plc import SimPLC
from protocols import plc_layout
from protocols.plc_contract import Command
from tests import ads_wire as w

NET_ID = "127.0.0.1.1.1"
POSITION = GVL_OFFSET + plc_layout.require("GVL_Axiscal.astAxes[1].stStatus.fActPosition").offset
CYCLIC, ON_CHANGE = 3, 4


class Client:
    """Where the PLC sends this client's notifications (its TCP connection in the server)."""

    def __init__(self) -> None:
        self.packets: list[tuple[float, bytes]] = []
        self.now_s = 0.0

    def send_notification(self, packet: bytes) -> None:
        self.packets.append((self.now_s, packet))

    def samples(self, handle: int) -> list[tuple[float, float, float]]:
        """(simulated time sent s, time sampled s, position) of each of handle's samples."""
        out = []
        for sent, packet in self.packets:
            p = w.parse(packet)
            assert (p.command, p.state_flags, p.target, p.source) == (8, 4, w.CLIENT, (NET_ID, 851))
            for filetime, items in w.stamps(p.data):
                out += [(sent, filetime, struct.unpack("<d", raw)[0]) for h, raw in items if h == handle]
        t0 = out[0][1] if out else 0
        return [(sent, (ft - t0) / w.TICKS_PER_S, v) for sent, ft, v in out]


@pytest.fixture
def plc():
    plc = SimPLC(axis=1, max_velocity=50.0, acceleration=200.0)
    plc.handler.net_id = NET_ID
    return plc


def ask(plc: SimPLC, packet: bytes, client: Client | None = None) -> w.Packet:
    """The reply to one request, as the server's connection sends it, then what became due."""
    response = plc.handler.handle_request(AdsClientConnection.construct_request(packet), sink=client)
    assert response is not None
    reply = w.parse(AdsClientConnection.construct_response(response, AdsClientConnection.construct_request(packet)))
    for sink, notification in plc.handler.due_notifications():
        sink.send_notification(notification)
    return reply


def subscribe(plc: SimPLC, client: Client, mode: int, max_delay_s: float, cycle_s: float,
              group: int = PLC_DATA_GROUP, offset: int = POSITION, length: int = 8) -> tuple[int, int]:
    """(result, handle) of an Add Device Notification; its reply is always result and handle."""
    reply = ask(plc, w.add_notification(NET_ID, group, offset, length, mode, max_delay_s, cycle_s), client)
    assert reply.error == 0 and len(reply.data) == 8
    result, handle = struct.unpack("<II", reply.data)
    return result, handle


def write(plc: SimPLC, name: str, fmt: str, value) -> None:
    offset = GVL_OFFSET + plc_layout.require(f"GVL_Axiscal.astAxes[1].stControl.{name}").offset
    raw = struct.pack("<" + fmt, value)
    assert ask(plc, w.request(NET_ID, w.WRITE, struct.pack("<III", PLC_DATA_GROUP, offset, len(raw)) + raw)
               ).data == b"\0\0\0\0"


def move(plc: SimPLC, target: float, velocity: float) -> None:
    write(plc, "fPosition", "d", target)
    write(plc, "fVelocity", "d", velocity)
    write(plc, "eCommand", "h", int(Command.MOVE_ABSOLUTE))
    write(plc, "bExecute", "?", True)


def run(plc: SimPLC, client: Client, until_s: float, step_s: float) -> None:
    t = plc.handler.time_s
    while t < until_s - 1e-9:
        t = round(t + step_s, 9)
        client.now_s = t
        plc.scan(t)


def test_on_change_sends_the_first_value_at_once_then_each_change_once_per_cycle(plc):
    client = Client()
    result, handle = subscribe(plc, client, ON_CHANGE, max_delay_s=0.0, cycle_s=0.05)
    assert result == 0 and handle != 0
    assert client.samples(handle) == [(0.0, 0.0, 0.0)]  # sent with the reply, before any scan
    move(plc, 10.0, 20.0)  # 0.5 s at 20 mm/s, plus 0.1 s of ramps at 200 mm/s²
    run(plc, client, 1.5, 0.01)
    samples = client.samples(handle)
    times = [t for _, t, _ in samples]
    positions = [p for _, _, p in samples]
    assert all(b - a >= 0.05 - 1e-9 for a, b in pairwise(times))  # at most one sample per cycle
    assert all(b > a for a, b in pairwise(positions))  # each one a change
    assert positions[-1] == 10.0 and times[-1] <= 0.65  # arrived; then nothing while it stands
    assert 10 <= len(samples) <= 14  # about one per 50 ms over the 0.6 s move
    assert all(sent == pytest.approx(t) for sent, t, _ in samples)  # a delay of 0: sent when taken


def test_cyclic_sends_every_cycle_even_when_nothing_changes(plc):
    client = Client()
    _, handle = subscribe(plc, client, CYCLIC, max_delay_s=0.0, cycle_s=0.1)
    run(plc, client, 1.0, 0.01)
    samples = client.samples(handle)
    assert len(samples) == 11 and {p for _, _, p in samples} == {0.0}
    assert [round(t, 6) for _, t, _ in samples] == [round(0.1 * i, 6) for i in range(11)]


def test_samples_wait_at_most_the_maximum_delay_and_go_together(plc):
    client = Client()
    _, handle = subscribe(plc, client, ON_CHANGE, max_delay_s=0.3, cycle_s=0.0)  # cycle 0: every scan
    assert client.packets == []  # the first sample may wait too
    move(plc, 20.0, 20.0)
    run(plc, client, 2.0, 0.05)
    samples = client.samples(handle)
    assert len(samples) == 23  # the first, then one per 50-ms scan over the 1.1-s move
    taken_by_packet: dict[float, list[float]] = {}
    for sent, taken, _ in samples:
        taken_by_packet.setdefault(sent, []).append(taken)
    for sent, taken in taken_by_packet.items():  # the oldest waited the delay, and not a scan longer
        assert 0.3 - 1e-6 <= sent - min(taken) < 0.3 + 0.05
    assert len(client.packets) < len(samples) / 4  # several samples, one stamp each, per packet
    stamps = [w.stamps(w.parse(p).data) for _, p in client.packets]
    assert all(len({ft for ft, _ in s}) == len(s) for s in stamps)


def test_a_long_delay_on_a_large_range_holds_at_most_the_waiting_limit(plc):
    """429 s (the longest delay the wire can say) sampling 4 KiB at every 10-ms scan: without a
    bound 4 kB x 42 900 samples would wait; the samples go once they hold 64 KiB, 16 samples."""
    client = Client()
    _, handle = subscribe(plc, client, CYCLIC, max_delay_s=429.0, cycle_s=0.0, offset=GVL_OFFSET, length=4096)
    run(plc, client, 1.0, 0.01)  # the first sample and 100 scans
    per_packet = WAITING_LIMIT_BYTES // 4096  # 16
    sent = [(at, w.stamps(w.parse(p).data)) for at, p in client.packets]
    assert [len(stamps) for _, stamps in sent] == [per_packet] * (101 // per_packet)  # 96 sent, 5 still waiting
    assert {(h, len(raw)) for _, stamps in sent for _, items in stamps for h, raw in items} == {(handle, 4096)}
    assert [at for at, _ in sent] == pytest.approx([0.01 * (per_packet - 1 + per_packet * i) for i in range(6)])
    (waiting,) = [s.waiting for s in plc.handler.notifications._subscriptions.values()]
    assert len(waiting) == 101 % per_packet


def test_a_packet_carries_all_of_a_clients_due_samples_and_times_are_filetimes(plc):
    client = Client()
    _, first = subscribe(plc, client, CYCLIC, max_delay_s=0.0, cycle_s=0.1)
    _, second = subscribe(plc, client, CYCLIC, max_delay_s=0.0, cycle_s=0.1, offset=POSITION - 8, length=1)
    assert first != second
    client.packets.clear()
    run(plc, client, 0.1, 0.1)
    (only,) = client.packets
    ((filetime, items),) = w.stamps(w.parse(only[1]).data)
    assert [h for h, _ in items] == [first, second]
    seconds = (filetime - FILETIME_AT_UNIX_EPOCH) / w.TICKS_PER_S
    assert seconds == pytest.approx(plc.handler.notifications.epoch_s + 0.1, abs=1e-6)


def test_a_deleted_notification_sends_nothing_and_a_second_delete_is_0x714(plc):
    client, other = Client(), Client()
    _, handle = subscribe(plc, client, CYCLIC, max_delay_s=0.0, cycle_s=0.1)
    delete = w.request(NET_ID, w.DELETE_NOTIFICATION, struct.pack("<I", handle))
    assert ask(plc, delete, other).data == struct.pack("<I", 0x714)  # not the other client's to delete
    assert ask(plc, delete, client).data == b"\0\0\0\0"
    client.packets.clear()
    run(plc, client, 1.0, 0.1)
    assert client.packets == []
    assert ask(plc, delete, client).data == struct.pack("<I", 0x714)


def test_a_clients_notifications_end_with_its_connection(plc):
    client = Client()
    subscribe(plc, client, CYCLIC, max_delay_s=0.0, cycle_s=0.1)
    plc.handler.drop_notifications(client)
    client.packets.clear()
    run(plc, client, 1.0, 0.1)
    assert client.packets == [] and len(plc.handler.notifications) == 0


@pytest.mark.parametrize("group, offset, length, mode, code", [
    (0x1234, 0, 4, ON_CHANGE, 0x702),  # no such index group
    (PLC_DATA_GROUP, 0, 8, ON_CHANGE, 0x703),  # below the GVL
    (PLC_DATA_GROUP, POSITION, 0xFFFF_FFFF, ON_CHANGE, 0x705),  # beyond it
    (PLC_DATA_GROUP, POSITION, 8, 1, 0x713),  # a client-side transmission mode: not supported
])
def test_a_refused_notification_is_result_and_handle_0(plc, group, offset, length, mode, code):
    client = Client()
    assert subscribe(plc, client, mode, 0.0, 0.1, group, offset, length) == (code, 0)
    run(plc, client, 0.5, 0.1)
    assert client.packets == []


def test_the_runtime_state_is_device_data_0xf100_and_can_be_watched(plc):
    """ads-client's default connect subscribes to it (and to the symbol version 0xF008)."""
    client = Client()
    reply = ask(plc, w.request(NET_ID, w.READ, struct.pack("<III", 0xF100, 0, 4)))
    assert reply.data == struct.pack("<IIHH", 0, 4, 5, 0)  # Run, device state 0, as Read State says
    _, handle = subscribe(plc, client, ON_CHANGE, 0.0, 0.0, group=0xF100, offset=0, length=4)
    _, version = subscribe(plc, client, ON_CHANGE, 0.0, 0.0, group=0xF008, offset=0, length=1)
    items = [item for _, p in client.packets for _, items in w.stamps(w.parse(p).data) for item in items]
    assert items == [(handle, struct.pack("<HH", 5, 0)), (version, b"\x01")]


def test_port_10000_answers_as_twincats_system_service_in_run(plc):
    state = ask(plc, w.read_state(NET_ID, 1, port=10000))
    assert (state.source, state.error, state.data) == ((NET_ID, 10000), 0, struct.pack("<IHH", 0, 5, 1))
    info = ask(plc, w.request(NET_ID, w.DEVICE_INFO, port=10000)).data
    assert struct.unpack("<IBBH16s", info) == (0, 3, 1, 4024, b"TwinCAT System\0\0")
    extended = ask(plc, w.request(NET_ID, w.READ, struct.pack("<III", 0xF0, 0, 16), port=10000)).data
    assert struct.unpack("<IIHHHBBHBBH2x", extended) == (0, 16, 5, 1, 0, 3, 1, 4024, 0, 0, 0)
    assert ask(plc, w.request(NET_ID, w.READ, struct.pack("<III", 0x4040, GVL_OFFSET, 8), port=10000)
               ).data == struct.pack("<II", 0x702, 0)  # the PLC's memory is not the system service's
    refused = ask(plc, w.add_notification(NET_ID, 0xF0, 0, 16, ON_CHANGE, 0.0, 0.1, port=10000), Client())
    assert refused.data == struct.pack("<II", 0x701, 0)
    assert ask(plc, w.read_state(NET_ID, 1, port=852)).error == 0x6  # other ports: none, from the router

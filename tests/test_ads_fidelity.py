"""The simulated PLC answers like TwinCAT, as seen by an ADS client we did not write.

`tests/ads_client/probe.js` asks the simulated PLC, through ads-client (npm, installed by
tests/setup_system.sh), what a TwinCAT client asks, after ads-client's default connect (the
system service on port 10000, the runtime's state and symbol version by notification): device
information and state, symbols and data types (member order, offsets, sizes), structured values,
a write of the wrong size, an unknown symbol, a notification served and one refused, a service the
simulation does not offer, a wrong AMS port and Net ID. The expected
layouts below are worked out by hand from TwinCAT 3's pack-8 rule (a member starts at a multiple
of min(its size or its structure's alignment, 8); a structure's size is rounded up to its
alignment), not computed by the code under test.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from drivers.ads_axis import AdsAxis
from drivers.factory import serve_on_free_loopback
from drivers.sim.clock import SimClock
from drivers.sim.plc import SimPLC
from protocols.plc_contract import CompTable

PROBE = Path(__file__).parent / "ads_client" / "probe.js"
CLIENT = Path(__file__).parent / "ads_client" / "node_modules" / "ads-client"
ST = Path(__file__).parents[1] / "protocols" / "st"

pytestmark = [
    pytest.mark.machine,
    pytest.mark.skipif(shutil.which("node") is None or not CLIENT.exists(),
                       reason="needs node and ads-client (tests/setup_system.sh installs it with npm)"),
]

EXPECTED = {
    # name: (size, [(member, type, offset, size of one element, array (start, length) or None)])
    "ST_AxiscalControl": (32, [("eCommand", "INT", 0, 2, None), ("fPosition", "LREAL", 8, 8, None),
                               ("fVelocity", "LREAL", 16, 8, None), ("bExecute", "BOOL", 24, 1, None),
                               ("bHalt", "BOOL", 25, 1, None), ("bReset", "BOOL", 26, 1, None)]),
    "ST_AxiscalStatus": (24, [("bBusy", "BOOL", 0, 1, None), ("bDone", "BOOL", 1, 1, None),
                              ("bError", "BOOL", 2, 1, None), ("nErrorId", "UDINT", 4, 4, None),
                              ("fActPosition", "LREAL", 8, 8, None), ("bEnabled", "BOOL", 16, 1, None),
                              ("bHomed", "BOOL", 17, 1, None)]),
    "ST_AxiscalAxis": (56, [("stControl", "ST_AxiscalControl", 0, 32, None),
                            ("stStatus", "ST_AxiscalStatus", 32, 24, None)]),
    "ST_AxiscalComp": (4152, [("afForward", "LREAL", 0, 8, (0, 256)), ("afReverse", "LREAL", 2048, 8, (0, 256)),
                              ("fStart", "LREAL", 4096, 8, None), ("fSpacing", "LREAL", 4104, 8, None),
                              ("nPoints", "UINT", 4112, 2, None), ("fOverrun", "LREAL", 4120, 8, None),
                              ("fMaxRate", "LREAL", 4128, 8, None), ("fMaxAccel", "LREAL", 4136, 8, None),
                              ("bEnable", "BOOL", 4144, 1, None)]),
}

TABLE = CompTable(forward=(0.001, -0.002, 0.0035), reverse=(0.004, 0.0, -0.0015), start=-5.0, spacing=50.0,
                  overrun=5.0, max_rate=0.01, max_accel=0.1, enabled=True)


def _st_members(type_name: str) -> list[str]:
    """Member names in the order the shipped Structured Text declares them."""
    text = (ST / f"{type_name}.st").read_text()
    body = text.split("STRUCT", 1)[1].split("END_STRUCT", 1)[0]
    return re.findall(r"^\s*(\w+)\s*:", body, flags=re.MULTILINE)


def _move(axis: AdsAxis, clock: SimClock, target: float):
    """Move to target at 20 mm/s in simulated time; the status at the end."""
    axis.start_move(target, 20.0)
    clock.sleep(0.05)
    while axis.status().busy:
        clock.sleep(0.05)
    return axis.status()


@pytest.fixture(scope="module")
def probed():
    """Runs the probe once against a simulated PLC that has moved to 37.5 and holds TABLE."""
    clock = SimClock()
    plc = SimPLC(axis=1, max_velocity=50.0, acceleration=200.0)
    clock.attach(plc.scan)
    with serve_on_free_loopback(plc) as server:
        axis = AdsAxis(server.net_id, server.ip, axis=1, timeout_s=1.0)
        try:
            axis.write_comp_table(TABLE)
            status = _move(axis, clock, 37.5)
            run = subprocess.run(["node", str(PROBE), server.ip, server.net_id], capture_output=True, text=True,
                                 timeout=120, check=False)
            assert run.returncode == 0, run.stderr
            answers = json.loads(run.stdout)
            yield answers, status, _move(axis, clock, 10.0)  # the PLC goes on scanning and moving

        finally:
            axis.close()


def test_device_info_and_state_are_a_twincat_3_plc_in_run(probed):
    answers, _, _ = probed
    assert answers["connection"]["rawClient"] is False  # ads-client's default connect
    assert answers["connection"]["tcSystemState"]["adsStateStr"] == "Run"  # asked of port 10000
    assert answers["deviceInfo"]["value"]["deviceName"] == "Plc30 App"
    assert answers["deviceInfo"]["value"]["majorVersion"] == 3
    assert answers["state"]["value"]["adsStateStr"] == "Run"


@pytest.mark.parametrize("type_name", list(EXPECTED))
def test_structures_have_twincats_pack_8_layout_in_declaration_order(probed, type_name):
    answers, _, _ = probed
    size, members = EXPECTED[type_name]
    got = answers["types"][type_name]["value"]
    assert got["size"] == size
    assert [(m["name"], m["type"], m["offset"], m["size"], tuple(m["arrayInfos"][0]) if m["arrayInfos"] else None)
            for m in got["items"]] == members
    assert [m[0] for m in members] == _st_members(type_name)


def test_symbols_are_where_their_structures_say(probed):
    answers, _, _ = probed
    sym = {path: answer["value"] for path, answer in answers["symbols"].items()}
    axis, control = sym["GVL_Axiscal.astAxes[1]"], sym["GVL_Axiscal.astAxes[1].stControl"]
    status, position = sym["GVL_Axiscal.astAxes[1].stStatus"], sym["GVL_Axiscal.astAxes[1].stStatus.fActPosition"]
    comp, forward = sym["GVL_Axiscal.astComp[1]"], sym["GVL_Axiscal.astComp[1].afForward"]
    assert (axis["type"], axis["size"]) == ("ST_AxiscalAxis", 56)
    assert (sym["GVL_Axiscal.astAxes"]["type"], sym["GVL_Axiscal.astAxes"]["size"]) == (
        "ARRAY [1..4] OF ST_AxiscalAxis", 4 * 56)
    assert control["indexOffset"] == axis["indexOffset"] and status["indexOffset"] == axis["indexOffset"] + 32
    assert position["indexOffset"] == status["indexOffset"] + 8 and position["size"] == 8
    assert comp["indexOffset"] == sym["GVL_Axiscal.astAxes"]["indexOffset"] + 4 * 56  # astComp follows astAxes
    assert (forward["type"], forward["size"], forward["indexOffset"]) == ("ARRAY [0..255] OF LREAL", 2048,
                                                                          comp["indexOffset"])
    assert len({s["indexGroup"] for s in sym.values()}) == 1


def test_structured_values_read_whole_equal_what_pyads_reads_member_by_member(probed):
    answers, status, _ = probed
    got = answers["status"]["value"]
    assert got["fActPosition"] == status.actual_position == 37.5
    assert (got["bBusy"], got["bDone"], got["bError"], got["nErrorId"], got["bEnabled"], got["bHomed"]) == (
        status.busy, status.done, status.error, status.error_id, status.enabled, status.homed)
    comp = answers["comp"]["value"]
    assert comp["afForward"] == list(TABLE.forward) and comp["afReverse"] == list(TABLE.reverse)
    assert (comp["fStart"], comp["fSpacing"], comp["nPoints"], comp["fOverrun"], comp["fMaxRate"],
            comp["fMaxAccel"], comp["bEnable"]) == (-5.0, 50.0, 3, 5.0, 0.01, 0.1, True)


def test_a_write_of_the_wrong_size_is_refused_in_the_result_field_and_changes_nothing(probed):
    answers, _, after = probed
    assert (answers["wrongSizeWrite"]["error"], answers["wrongSizeWrite"]["where"]) == (0x705, "ads")
    assert answers["afterWrongSize"]["value"] == 1  # MOVE_ABSOLUTE, from the last move; 8 bytes of 7 would be 1799
    assert answers["rightSizeWrite"]["value"] is True and answers["afterAll"]["value"]["eCommand"] == 3
    assert answers["writeValue"]["value"] is True and answers["afterAll"]["value"]["fVelocity"] == 12.5
    assert after.actual_position == 10.0 and after.done and not after.error


@pytest.mark.parametrize("request_name, code, where", [
    ("unknownSymbol", 0x710, "ads"),  # symbol not found
    ("refusedNotification", 0x702, "ads"),  # invalid index group, in the reply's result field
    ("writeControl", 0x701, "ads"),  # service not supported
    ("wrongPort", 0x6, "ams"),  # target port not found, from the router
    ("wrongNetId", 0x7, "ams"),  # target machine not found
])
def test_errors_carry_twincats_code_in_twincats_place(probed, request_name, code, where):
    answers, _, _ = probed
    assert (answers[request_name]["error"], answers[request_name]["where"]) == (code, where)


def test_a_notification_is_served_and_its_first_sample_is_the_value_when_subscribed(probed):
    answers, status, _ = probed
    notification = answers["notification"]["value"]
    assert notification["handle"] > 0 and notification["first"] == status.actual_position == 37.5

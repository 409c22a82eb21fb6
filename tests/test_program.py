"""`axiscal program`: the plan as a part program. The LinuxCNC program is run through LinuxCNC's
own interpreter (`rs274 -g`, Debian linuxcnc-uspace, installed by tests/setup_system.sh): its
canonical motions and dwells must be the plan's."""

import re
import shutil
import subprocess

import pytest

from campaign.config import load_config
from campaign.plan import build_plan
from tests.conftest import ROOT

DEMO = ROOT / "campaign" / "demo.toml"
RS274 = shutil.which("rs274")


def canonical(path) -> list[tuple[str, float]]:
    """(STRAIGHT_FEED, x) and (DWELL, s) and (SET_FEED_RATE, f) in the order rs274 prints them."""
    proc = subprocess.run([RS274, "-g", str(path)], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=60, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    calls = []
    for line in proc.stdout.splitlines():
        match = re.search(r"(STRAIGHT_FEED|DWELL|SET_FEED_RATE|STRAIGHT_TRAVERSE)\(([^,)]*)", line)
        if match:
            calls.append((match.group(1), float(match.group(2))))
    return calls


@pytest.mark.machine
@pytest.mark.skipif(RS274 is None, reason="LinuxCNC's rs274 is not installed (tests/setup_system.sh installs "
                                          "linuxcnc-uspace where apt is available)")
def test_linuxcnc_program_runs_in_rs274_with_the_plans_stops_and_dwells(cli, tmp_path):
    out = tmp_path / "demo.ngc"
    assert cli("program", DEMO, "--dialect", "linuxcnc", "-o", out).code == 0
    calls = canonical(out)
    plan = build_plan(load_config(DEMO))
    moves = [x for kind, x in calls if kind == "STRAIGHT_FEED"]
    assert moves == pytest.approx([s.position for s in plan.stops()], abs=5e-5)
    assert not [c for c in calls if c[0] == "STRAIGHT_TRAVERSE"]
    dwells = [s for kind, s in calls if kind == "DWELL"]
    assert len(dwells) == 110 and set(dwells) == {4.0}
    feeds = {f for kind, f in calls if kind == "SET_FEED_RATE" and f > 0}
    assert feeds == {load_config(DEMO).plan.velocity * 60}
    # every dwell follows the move to a target, in the plan's order
    sequence = [kind for kind, _ in calls if kind in ("STRAIGHT_FEED", "DWELL")]
    measured = [s.point is not None for s in plan.stops()]
    expected = [k for m in measured for k in (("STRAIGHT_FEED", "DWELL") if m else ("STRAIGHT_FEED",))]
    assert sequence == expected


@pytest.mark.parametrize(("dialect", "move", "dwell", "ends"), [
    ("fanuc", "G01 X0.0000 F480.0", "G04 X4.000", ("M30", "%")),
    ("siemens", "G1 X0.0000 F480.0", "G4 F4.000", ("M30",)),
    ("heidenhain", "L X+0.0000 F480", "CYCL DEF 9.1 DWELL 4.000", ("END PGM AXISCAL MM",)),
    ("linuxcnc", "G1 X0.0000 F480.0", "G4 P4.000", ("M2",)),
])
def test_every_dialect_writes_the_moves_dwells_and_campaign_id(cli, tmp_path, dialect, move, dwell, ends):
    out = tmp_path / "p.txt"
    assert cli("program", DEMO, "--dialect", dialect, "-o", out).code == 0
    lines = out.read_text().splitlines()
    body = [re.sub(r"^\d+ ", "", line) for line in lines]  # heidenhain numbers its blocks
    assert move in body and sum(1 for line in body if line.startswith(dwell.rsplit(" ", 1)[0])) == 110
    assert body[-len(ends):] == list(ends)
    assert any("axiscal ISO 230-2 campaign sim-press-X-" in line for line in body[:5])
    if dialect == "heidenhain":
        assert [int(line.split()[0]) for line in lines] == list(range(len(lines)))


def test_an_axis_name_that_is_no_nc_letter_is_refused(cli, tmp_path):
    config = tmp_path / "c.toml"
    config.write_text(DEMO.read_text().replace('name = "X"', 'name = "AX1"'))
    result = cli("program", config, "--dialect", "fanuc", "-o", tmp_path / "p.nc")
    assert result.code == 2 and result.err.startswith("error: ") and "AX1" in result.err
    assert not (tmp_path / "p.nc").exists()

"""Discovery on campaigns planned the way users plan them: `axiscal run` on the simulated machine
with the shipped horizontal config (11 targets, golden offsets, the stability trigger), machines
with one effect each besides the bow. Discovery names only effects the machine has, always the
bow, never a period more than 5 % off, and lists what it cannot separate under `unresolved`."""

import json
import re

import pytest

from tests.conftest import DATA

BASE = (DATA / "configs" / "horizontal-sim.toml").read_text()
BOW = ("[effects.linear_scale]\nppm = -12.4\n[effects.nonlinear_lead]\np2_um = 0.49\np3_um = 0.73\n"
       "start_mm = 0.0\nend_mm = 600.0\n[effects.noise]\nsigma_um = 0.34\nreading_sigma_um = 0.05\n")
MACHINES = {
    "bow only": ("", {"nonlinear_lead"}),
    "settling, no backlash": ("[effects.settling]\ne0_um = 1.5\ntau_s = 0.6\n", {"nonlinear_lead", "settling"}),
    "backlash, no settling": ("[effects.backlash]\nb_um = 1.5\n", {"nonlinear_lead", "backlash"}),
    "10 mm lead": ("[effects.periodic_lead]\namplitude_um = 1.0\nperiod_mm = 10.0\nphase_rad = 0.3\n",
                   {"nonlinear_lead", "periodic_lead"}),
}
SEEDS = (1, 2)
"""Two seeds a machine (a third by hand: 40 s of the ten minutes the suite may take); the bench
(bench/discovery_draws.py) draws 144 machines a seed for what is named that the machine lacks."""


def user_campaign(cli, tmp_path, extra: str, seed: int):
    model = tmp_path / "machine.toml"
    model.write_text(BOW + extra)
    config = re.sub(r'(?m)^model = .*$', f'model = "{model}"', BASE)
    config = re.sub(r"\[sim\]\nseed = \d+", f"[sim]\nseed = {seed}", config)
    config = re.sub(r"(\[plan\][^\[]*?)seed = \d+", lambda m: m.group(1) + f"seed = {seed}", config, flags=re.DOTALL)
    assert "offsets = \"golden\"" in config and "count = 11" in config and "method = \"stable\"" in config
    (tmp_path / "c.toml").write_text(config)
    assert cli("run", tmp_path / "c.toml", "--out", tmp_path / "run").code == 0
    result = cli("discover", tmp_path / "run" / "points.csv", "--json")
    assert result.code == 0, result.err
    return json.loads(result.out)


@pytest.mark.machine
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("machine", list(MACHINES))
def test_names_only_what_the_machine_has_and_lists_the_rest(cli, tmp_path, machine, seed):
    extra, present = MACHINES[machine]
    found = user_campaign(cli, tmp_path, extra, seed)
    named = set(found["added"])
    assert "nonlinear_lead" in named, found["notes"]
    assert named <= present, (named, found["unresolved"])
    if "periodic_lead" in found["model"] and "periodic_lead" in named:
        assert found["model"]["periodic_lead"]["period_mm"] == pytest.approx(10.0, rel=0.05)
    for entry in found["unresolved"]:
        assert entry["effects"] and entry["why"] and entry["how_to_tell"]
        assert not set(entry["effects"]) & named
    unresolved = {name for entry in found["unresolved"] for name in entry["effects"]}
    missing = present - named - {"settling"}  # settling of 1.5 µm at 0.6 s is mostly gone by the capture
    assert missing <= unresolved, (machine, named, found["unresolved"])
    assert len(found["notes"]) == len(set(found["notes"]))
    if machine == "10 mm lead":  # 11 targets cannot pin a 10 mm lead: its aliases fit about as well
        period = next(e for e in found["unresolved"] if e["effects"] == ["periodic_lead"])
        assert any(p == pytest.approx(10.0, rel=0.05) for p in period["periods_mm"])
        assert "period_mm" in period["how_to_tell"]

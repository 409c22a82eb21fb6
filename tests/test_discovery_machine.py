"""Issue 4's acceptance on the full simulated machine (real pyads against the loopback PLC, real
pyserial over a pty): for each effect, a campaign with that effect on, discover given a model
without it. The effect is named, its parameter recovered within 15 %, gap_after <= 1.3 x noise.
(tests/test_discovery.py runs the same cases, and the null case, on the fast simulator.)"""

import json
import math

import pytest

from tests.test_discovery import BASE, HIDDEN, NOISE_UM, PLAN

MACHINE_PLAN = PLAN.replace("dwell_s = 2.0", "dwell_s = 2.0\ndwell_jitter = 0.8")


def effects_toml(effects: dict) -> str:
    return "".join(f"[sim.effects.{name}]\n" + "".join(f"{k} = {float(v)!r}\n" for k, v in params.items())
                   for name, params in effects.items())


@pytest.mark.machine
@pytest.mark.parametrize("hidden", list(HIDDEN))
def test_one_hidden_effect_on_the_simulated_machine(cli, tmp_path, hidden):
    true_params, checked = HIDDEN[hidden]
    (tmp_path / "c.toml").write_text(MACHINE_PLAN + effects_toml({**BASE, hidden: true_params}))
    run = cli("run", tmp_path / "c.toml", "--out", tmp_path / "m")  # in-process, as a subprocess would
    assert run.code == 0, run.err[-1500:]
    start = [name for name in BASE if name not in (hidden, "noise")]
    (tmp_path / "start.toml").write_text("".join(f"[effects.{name}]\n" for name in start))
    found = cli("discover", tmp_path / "m" / "points.csv", "--model", tmp_path / "start.toml", "--json")
    assert found.code == 0, found.err[-1500:]
    data = json.loads(found.out)
    assert data["added"] == [hidden], data["notes"]
    found = data["model"][hidden]
    for key in checked:
        assert found[key] == pytest.approx(true_params[key], rel=0.15), (key, found)
    assert data["gap_after_um"] <= 1.3 * NOISE_UM
    assert math.isfinite(data["gap_before_um"]) and data["gap_after_um"] < data["gap_before_um"]

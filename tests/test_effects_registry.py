"""Issue 34 item 7: effects are objects, one module each in one registry (campaign/effects/), read by
the simulated machine (through campaign.model) and by discovery. Adding an effect is adding one
module, its test and its doc: shown here with an effect the product does not have, defined in this
test and registered, which the simulator then simulates from a model file and discovery names on
the campaign recorded from it, with nothing else changed."""

from __future__ import annotations

import dataclasses
import json
import math
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest

import campaign.effects
from campaign.commands.discover import config_beside
from campaign.config import load_config
from campaign.discovery.data import read_campaign
from campaign.discovery.effects import FORMS
from campaign.discovery.fit import linear_fit
from campaign.discovery.followup import part_of, plan_follow_up
from campaign.discovery.local import reversal_name
from campaign.discovery.records import Unresolved
from campaign.discovery.vocabulary import how_to_tell_pairs, may_soak
from campaign.effects import effect, effects, register, unregister
from campaign.effects.base import SIZE_UM, Effect, EffectForm, Ranges, Samples, Shape, span_ends
from campaign.errors import InputError
from campaign.measure import start_campaign
from campaign.model import EFFECT_PARAMS, EFFECTS, ErrorModel, read_model
from tests.fakes import FakeMachine

ROOT = Path(__file__).resolve().parents[1]


# --- a new effect, written as an effect module is (campaign/effects/NAME.py defines EFFECT) ---------

def middle_wear_um(p: dict[str, float], x: np.ndarray, d: np.ndarray) -> np.ndarray:
    """A reversal that grows towards the middle of the span, where the screw is used most: wear_um
    more lost motion in the middle than at the ends, a parabola over start_mm to end_mm."""
    u = 2 * (x - p["start_mm"]) / (p["end_mm"] - p["start_mm"]) - 1
    return -d * p["wear_um"] / 2 * np.clip(1 - u**2, 0.0, 1.0)


def middle_wear_columns(data: Samples, shape: Shape, held: Shape) -> np.ndarray:
    return middle_wear_um({"wear_um": 1.0, **shape}, data.x, data.d)[:, None]


def middle_wear_span(data: Samples, held: Shape) -> Shape:
    return {"start_mm": held.get("start_mm", float(data.x.min())), "end_mm": held.get("end_mm", float(data.x.max()))}


def middle_wear_ranges(data: Samples) -> Ranges:
    return {"wear_um": (-SIZE_UM, SIZE_UM)}


EFFECT = Effect(
    "middle_wear", 65, {"wear_um": "lost motion added in the middle of the span, µm",
                        "start_mm": "start of the worn span, mm", "end_mm": "end of the worn span, mm"},
    lambda p, x, d, t, w: middle_wear_um(p, x, d),
    EffectForm("middle_wear", ("wear_um",), (), "target", middle_wear_columns, sizes=("wear_um",),
               ranges=middle_wear_ranges, fixed_shape=middle_wear_span),
    check=span_ends,
    rivals={"backlash": "targets over the whole travel in both directions: wear in the middle is a reversal "
                        "larger there than at the ends"},
    follow_up="travel")


@pytest.fixture
def middle_wear():
    register(EFFECT)
    try:
        yield EFFECT
    finally:
        unregister(EFFECT.name)


AXIS = """
[axis]
soft_limit_min = -10.0
soft_limit_max = 610.0
max_velocity = 50.0
max_acceleration = 200.0

[plan]
length = 600.0
count = 13
overrun = 5.0
cycles = 4
dwell_s = 1.0
velocity = 50.0
offsets = "golden"

[capture]
average_s = 0.5

[sim]
model = "axis.toml"
seed = {seed}
"""
MODEL = """
[effects.linear_scale]
ppm = -12.4

[effects.backlash]
b_um = 3.0

[effects.middle_wear]
wear_um = {wear}
start_mm = 0.0
end_mm = 600.0

[effects.noise]
sigma_um = 0.3
reading_sigma_um = 0.05
"""
START = """
[effects.linear_scale]
[effects.backlash]
"""


def undocumented() -> list[str]:
    """Registered effects without their doc: a simulated effect without a row in docs/error-model.md's
    table of the effects, a discoverable one without a row in its table of physical ranges."""
    text = (ROOT / "docs" / "error-model.md").read_text()

    def has_row(title: str, name: str) -> bool:
        table = text.split(f"\n## {title}", 1)[1].split("\n## ", 1)[0]
        return re.search(rf"^\|[^|\n]*`{name}`", table, re.MULTILINE) is not None

    return [e.name for e in effects() if (e.simulated and not has_row("The effects", e.name))
            or (not e.simulator_only and not has_row("Physical ranges", e.name))]


# --- the tests ---------------------------------------------------------------------------------------

def test_every_module_of_the_package_is_one_registered_effect_and_documented():
    """Adding a module is adding an effect: each module of campaign/effects/ (but base) defines EFFECT
    under its own name, the registry lists exactly those, and each has its rows in
    docs/error-model.md."""
    modules = sorted(m.name for m in pkgutil.iter_modules(campaign.effects.__path__) if m.name != "base")
    assert sorted(e.name for e in effects()) == modules
    for name in modules:
        module = __import__(f"campaign.effects.{name}", fromlist=["EFFECT"])
        assert module.EFFECT is effect(name)
    assert undocumented() == []
    # the simulator holds effects discovery lacks, on purpose: they have no least-squares form
    assert {"local_defect", "local_step", "partial_wave"} <= {e.name for e in effects() if e.simulator_only}
    assert not set(FORMS) & {e.name for e in effects() if e.simulator_only}
    assert "environment" in FORMS and "environment" not in EFFECT_PARAMS  # discovery's only: it follows a log


@pytest.mark.parametrize(("effects_table", "said"), [
    ({"local_step": {"height_um": 1, "at_mm": 5, "rise_mm": 2, "direction": 2}},
     "'effects.local_step.direction' must be 0, 1 or -1"),
    ({"local_defect": {"amplitude_um": 1, "centre_mm": 5, "width_mm": 2, "skew": -1}},
     "'effects.local_defect.skew' must be between -0.9 and 0.9"),
    ({"thermal_drift": {"growth_ppm": 1, "tau_s": 0}}, "'effects.thermal_drift.tau_s' must be > 0"),
    ({"periodic_lead": {"amplitude_um": 1, "period_mm": -10}}, "'effects.periodic_lead.period_mm' must be > 0"),
    ({"nonlinear_lead": {"p2_um": 1, "start_mm": 600, "end_mm": 0}}, "'effects.nonlinear_lead.end_mm' must be > start_mm"),
    ({"noise": {"sigma_um": 0.3, "reading_sigma_um": -0.1}}, "'effects.noise' sigmas must be >= 0"),
    ({"environment": {"air_factor": 1.0}}, "unknown effect 'effects.environment'"),
])
def test_a_model_file_is_checked_by_the_rules_of_each_effects_module(effects_table, said):
    """The checks of a model file come from the effect modules (choices, limits, positive, check);
    `environment` has no deviation, so a model file may not give it."""
    from campaign.model import model_from_dict

    with pytest.raises(InputError, match=re.escape(f"m.toml: {said}")):
        model_from_dict({"effects": effects_table}, "m.toml")


def test_an_effect_cannot_be_registered_twice_or_without_simulator_and_form():
    with pytest.raises(ValueError, match="registered already"):
        register(effect("backlash"))
    with pytest.raises(ValueError, match="neither simulated nor discovered"):
        Effect("nothing", 1, {}, None)


def test_a_registered_effect_is_known_everywhere_at_once_and_forgotten_when_unregistered(tmp_path):
    """The model's names, the model-file validation, discovery's vocabulary and the docs check read
    the registry and nothing else: registering one object is all it takes, and taking it out
    undoes it."""
    path = tmp_path / "axis.toml"
    path.write_text(MODEL.format(wear=1.5))
    with pytest.raises(InputError, match="unknown effect 'effects.middle_wear'"):
        read_model(path)
    assert "middle_wear" not in EFFECT_PARAMS and "middle_wear" not in FORMS
    register(EFFECT)
    try:
        assert EFFECTS["middle_wear"] is EFFECT and "middle_wear" in FORMS
        assert read_model(path).effects["middle_wear"] == {"wear_um": 1.5, "start_mm": 0.0, "end_mm": 600.0}
        path.write_text(MODEL.format(wear=1.5).replace("end_mm = 600.0", "end_mm = -1.0"))
        with pytest.raises(InputError, match=r"'effects.middle_wear.end_mm' must be > start_mm"):
            read_model(path)  # its own rule, from its module
        assert undocumented() == ["middle_wear"]  # without its doc, the docs check fails
    finally:
        unregister("middle_wear")
    assert "middle_wear" not in EFFECT_PARAMS and undocumented() == []
    # no product code names it: the registry is the only place consulted
    for code in [*ROOT.joinpath("campaign").rglob("*.py"), *ROOT.joinpath("drivers").rglob("*.py")]:
        assert "middle_wear" not in code.read_text(), code


def test_whether_a_local_error_may_hide_behind_an_effect_is_its_modules_word():
    """Discovery looks for local errors again without each named effect that may soak one up; which
    those are is each module's may_soak, so a registered effect that says so is looked behind too."""
    assert {e.name for e in effects() if may_soak(e.name)} == {
        "periodic_lead", "backlash", "position_dependent_backlash", "settling"}
    soaking = dataclasses.replace(EFFECT, may_soak=True)
    register(soaking)
    try:
        assert may_soak("middle_wear")
    finally:
        unregister("middle_wear")
    with pytest.raises(KeyError):
        may_soak("middle_wear")


def test_the_reversal_a_split_local_term_must_beat_is_the_registrys_word():
    """A local term split by direction must beat a reversal constant along the travel; which effect's
    column that is comes from the module that says `reversal`, and its column is that reversal."""
    flagged = [e for e in effects() if e.reversal]
    assert len(flagged) == 1 and flagged[0].form is not None and reversal_name() is not None

    class Points:
        x, d = np.array([0.0, 100.0, 300.0, 300.0]), np.array([1.0, -1.0, 1.0, -1.0])
        t, w, time_source, env, air_index_change = np.zeros((4, 1)), None, "time_s", {}, None

    column = flagged[0].form.columns(Points(), {}, {})
    assert np.allclose(column[:, 0], -Points.d / 2)


@pytest.mark.machine  # a simulated campaign and a discovery each: about 0.7 s
@pytest.mark.parametrize("seed", range(1, 7))
def test_a_new_effect_is_simulated_from_a_model_file_and_named_by_discovery(middle_wear, tmp_path, cli, seed):
    """The simulated machine's physics (drivers.sim.machine.SimAxisPhysics, in the fake machine)
    simulates the registered effect from an error-model file named by the config; the campaign is
    recorded; `axiscal discover --json` names it with its size within 3 of its standard errors, as
    it names a shipped one, and its rival's how-to-tell comes from its module."""
    wear = [1.2, 1.5, 2.0][seed % 3]
    (tmp_path / "axis.toml").write_text(MODEL.format(wear=wear))
    (tmp_path / "axis.cfg.toml").write_text(AXIS.replace("{seed}", str(seed)))
    config = load_config(tmp_path / "axis.cfg.toml")
    assert config.sim.model == "axis.toml"
    start_campaign(config, tmp_path / "run", opener=FakeMachine(error_um=None), durable=False)
    (tmp_path / "start.toml").write_text(START)
    result = cli("discover", tmp_path / "run" / "points.csv", "--model", tmp_path / "start.toml", "--json")
    assert result.code == 0, result.err
    found = json.loads(result.out)
    assert found["added"] == ["middle_wear"], (found["added"], found["notes"])
    step = found["steps"][0]
    assert abs(step["params"]["wear_um"] - wear) <= 3 * step["standard_errors"]["wear_um"], step
    assert found["gap_after_um"] < found["gap_before_um"]
    assert how_to_tell_pairs()[frozenset({"middle_wear", "backlash"})] == EFFECT.rivals["backlash"]
    # its part of a follow-up, from its module: a group with it is planned as its part says
    assert part_of("middle_wear") == "travel"
    data = read_campaign(tmp_path / "run" / "points.csv", None, config_beside(str(tmp_path / "run" / "points.csv")))
    follow = plan_follow_up([Unresolved(("backlash", "middle_wear"), "", "")], [], data, linear_fit(data, []), config,
                            None, found["noise_um"], tmp_path / "follow.toml", ["run/points.csv"])
    assert follow is not None and [p.effects for p in follow.parts] == [["backlash", "middle_wear"]], follow
    assert "whole travel" in follow.parts[0].why and not follow.unplanned


@pytest.mark.machine  # a simulated campaign and a discovery each: about 0.7 s
@pytest.mark.parametrize("seed", range(1, 4))
def test_a_registered_effect_the_axis_lacks_is_not_named(middle_wear, tmp_path, cli, seed):
    """Registering an effect adds a candidate, not a name: on an axis without it (the same model,
    its middle_wear left out) discovery names nothing."""
    (tmp_path / "axis.toml").write_text(MODEL.format(wear=0.0).split("[effects.middle_wear]")[0]
                                        + "[effects.noise]" + MODEL.split("[effects.noise]")[1])
    (tmp_path / "axis.cfg.toml").write_text(AXIS.replace("{seed}", str(seed)))
    assert "middle_wear" not in read_model(tmp_path / "axis.toml").effects
    start_campaign(load_config(tmp_path / "axis.cfg.toml"), tmp_path / "run", opener=FakeMachine(error_um=None),
                   durable=False)
    (tmp_path / "start.toml").write_text(START)
    result = cli("discover", tmp_path / "run" / "points.csv", "--model", tmp_path / "start.toml", "--json")
    assert result.code == 0, result.err
    found = json.loads(result.out)
    assert found["added"] == [], (found["added"], found["notes"])
    tried = [c for c in found["remaining"] if c["effect"] == "middle_wear"]
    assert tried and tried[0]["verdict"] != "accepted", found["remaining"]


def test_the_simulators_one_point_deviation_is_the_arrays_bit_for_bit():
    """The simulated machine evaluates its model once a tick on floats (ErrorModel.deviation_at); that
    must be deviation_um's value exactly, for every registered effect, at drawn points and parameters
    (a wait of inf: no settling left)."""
    rng = np.random.default_rng(7)
    model = {}
    for name, e in EFFECTS.items():
        for _ in range(100):  # drawn until its module's checks take it (an end after its start)
            params = {}
            for key in e.params:
                if key in e.choices:
                    params[key] = float(rng.choice(e.choices[key]))
                elif key in e.limits:
                    params[key] = float(rng.uniform(*e.limits[key]))
                elif key.endswith("_mm"):
                    params[key] = float(rng.uniform(5.0, 600.0))
                elif key.endswith("_s"):
                    params[key] = float(rng.uniform(0.5, 2000.0))
                else:
                    params[key] = float(rng.uniform(0.1, 3.0) if key in e.positive else rng.uniform(-3.0, 3.0))
            if e.errors(params) is None:
                break
        assert e.errors(params) is None, (name, e.errors(params))
        model[name] = params
    m = ErrorModel(model)
    for _ in range(2000):
        x, d, t = float(rng.uniform(-10.0, 610.0)), float(rng.choice([-1.0, 1.0])), float(rng.uniform(0.0, 9000.0))
        w = float(rng.choice([0.0, float(rng.uniform(0.0, 20.0)), math.inf]))
        assert m.deviation_at(x, d, t, w) == float(m.deviation_um(x, d, t, w)), (x, d, t, w)

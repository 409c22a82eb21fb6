"""Discovery says what it cannot tell: a glitch is flagged, not taken for physics; each note and
each parameter's unit once; a period given in the model is held and only its amplitude fitted."""

import json

import numpy as np
import pytest

from campaign.commands.discover import unit_of
from campaign.discovery.naming import period_spread_mm
from campaign.discovery.simulate import simulate_campaign
from campaign.model import ErrorModel
from campaign.pointtable import write_points
from tests.test_discovery import CONFIG, SPAN

BOW = {"linear_scale": {"ppm": -12.4}, "nonlinear_lead": {"p2_um": 2.0, "p3_um": -1.5, "start_mm": SPAN[0],
                                                          "end_mm": SPAN[1]},
       "noise": {"sigma_um": 0.5, "reading_sigma_um": 0.05}}


def bow_table(tmp_path, glitch_um=0.0, extra=None, seed=5, dwell_jitter=0.0):
    table = simulate_campaign(CONFIG, ErrorModel({**BOW, **(extra or {})}), seed=seed, dwell_jitter=dwell_jitter)
    if glitch_um:
        table.deviation[37] += glitch_um
    path = tmp_path / "p.csv"
    write_points(path, table)
    return path, table


@pytest.mark.machine
def test_a_glitch_is_flagged_left_out_and_the_noise_given_with_and_without(cli, tmp_path):
    path, table = bow_table(tmp_path, glitch_um=12.0)
    result = cli("discover", path, "--json")
    assert result.code == 0, result.err
    found = json.loads(result.out)
    assert len(found["outliers"]) == 1
    glitch = found["outliers"][0]
    assert glitch["run"] == int(table.run[37]) and glitch["target"] == pytest.approx(float(table.target[37]))
    assert found["added"] == ["nonlinear_lead"]  # the glitch is not taken for physics
    scatter = found["scatter_um"]
    assert scatter["without_outliers"] == pytest.approx(0.5, rel=0.2) and scatter["with_outliers"] > 1.5 * scatter["without_outliers"]
    assert found["noise_um"] == pytest.approx(0.5, rel=0.2)
    assert any("left out of the fit" in n for n in found["notes"])
    text = cli("discover", path, "--verbose")
    assert "left out of the fit" in text.out and "µm without" in text.out


@pytest.mark.machine
def test_without_a_glitch_nothing_is_flagged(cli, tmp_path):
    path, _ = bow_table(tmp_path)
    found = json.loads(cli("discover", path, "--json").out)
    assert found["outliers"] == [] and not any("left out of the fit" in n for n in found["notes"])


@pytest.mark.machine
def test_each_parameter_once_with_its_unit(cli, tmp_path):
    assert unit_of("backlash", "b_um", "s") == "µm"
    assert unit_of("settling", "e0_um", "s") == "µm"
    path, _ = bow_table(tmp_path, extra={"backlash": {"b_um": 6.0}}, dwell_jitter=0.8)  # waits that tell settling
    out = cli("discover", path, "--verbose").out
    line = next(ln for ln in out.splitlines() if "add backlash" in ln)
    said = line.split("(", 1)[1].split(");")[0]
    assert said.startswith("b_um = ") and said.count("µm") == 2 and "e = " not in said  # value and error


@pytest.mark.machine
def test_notes_are_said_once(cli, tmp_path):
    path, _ = bow_table(tmp_path, extra={"backlash": {"b_um": 6.0}})
    found = json.loads(cli("discover", path, "--json").out)
    assert len(found["notes"]) == len(set(found["notes"]))
    topics = [n.split(",")[0] for n in found["notes"]]
    assert len(topics) == len(set(topics))


def test_a_period_given_in_the_model_is_held_and_its_amplitude_fitted(cli, tmp_path):
    lead = {"periodic_lead": {"amplitude_um": 1.5, "period_mm": 10.0, "phase_rad": 0.7}}
    path, _ = bow_table(tmp_path, extra=lead)
    model = tmp_path / "m.toml"
    model.write_text("[effects.linear_scale]\n[effects.nonlinear_lead]\n[effects.periodic_lead]\nperiod_mm = 10.0\n")
    found = json.loads(cli("discover", path, "--model", model, "--json").out)
    periodic = found["model"]["periodic_lead"]
    assert periodic["period_mm"] == 10.0
    assert periodic["amplitude_um"] == pytest.approx(1.5, rel=0.15)
    assert "periodic_lead" not in {n for e in found["unresolved"] for n in e["effects"]}


def test_the_period_error_includes_the_competing_optima():
    assert period_spread_mm([(10.0, 0.0)]) == 0.0
    # one alias 2 in BIC behind: weight e^-1 against 1
    spread = period_spread_mm([(10.0, 0.0), (12.0, 2.0)])
    assert spread == pytest.approx(np.sqrt(np.exp(-1) * 4 / (1 + np.exp(-1))))

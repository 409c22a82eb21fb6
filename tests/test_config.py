"""The campaign config: unknown keys and out-of-range values give one line naming the key."""

import subprocess
import sys
from pathlib import Path

import pytest

from campaign.config import schema_markdown
from tests.conftest import ROOT, assert_one_line_error
from tests.test_plan import BASE

BAD = {
    "unknown key": (BASE + "colour = 1\n", "capture.colour"),
    "unknown section": (BASE + "[nope]\nx = 1\n", "[nope]"),
    "out of range": (BASE.replace("cycles = 2", "cycles = 0"), "plan.cycles"),
    "wrong type": (BASE.replace("cycles = 2", 'cycles = "five"'), "plan.cycles"),
    "bad choice": (BASE + 'method = "magic"\n', "capture.method"),
    "missing required": (BASE.replace("max_velocity = 20.0\n", ""), "axis.max_velocity"),
    "limits inverted": (BASE.replace("soft_limit_min = -10.0", "soft_limit_min = 200.0"), "axis.soft_limit_max"),
    "unit vs kind": (BASE.replace("[axis]", '[axis]\nunit = "deg"'), "axis.unit"),
    "edlen on a rotary axis": (BASE.replace("[axis]", '[axis]\nkind = "rotary"\nunit = "deg"') +
                               '[environment]\nair_correction = "edlen"\n', "environment.air_correction"),
    "targets not increasing": (BASE.replace("[0.0, 60.0, 120.0]", "[0.0, 60.0, 30.0]"), "plan.targets"),
    "not toml": ("[axis\nfoo", "not valid TOML"),
    "bad line format": (BASE + '[instrument.line]\nseparator = 5\n', "separator"),
    "bad sim effect": (BASE + '[sim.effects.warp]\nx = 1\n', "effects.warp"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_config_one_line(cli, tmp_path, case):
    text, key = BAD[case]
    path = tmp_path / "c.toml"
    path.write_text(text)
    assert_one_line_error(cli("plan", path), str(path), key)


def test_missing_config_file(cli, tmp_path):
    assert_one_line_error(cli("plan", tmp_path / "none.toml"), "no such file")


def test_example_configs_are_valid(cli):
    paths = sorted((ROOT / "data" / "configs").glob("*.toml"))
    assert len(paths) >= 4
    for path in paths:
        result = cli("plan", path, "--json")
        assert result.code == 0, (path, result.err)


def test_docs_config_is_generated_from_the_schema():
    assert (ROOT / "docs" / "config.md").read_text() == schema_markdown()


def test_campaign_never_imports_pyads_or_serial():
    code = ("import sys, importlib, pkgutil, campaign\n"
            "for m in pkgutil.iter_modules(campaign.__path__):\n"
            "    if m.name != '__main__': importlib.import_module('campaign.' + m.name)\n"
            "import campaign.commands.run, campaign.commands.demo\n"
            "bad = [m for m in ('pyads', 'serial') if m in sys.modules]\n"
            "print(bad); sys.exit(1 if bad else 0)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=Path(ROOT),
                          check=False, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_help_and_parsers_import_no_heavy_library():
    """`axiscal --help` and every command's parser load without numpy's heavy friends or pyads;
    they load when a command runs (bench/startup.py measures the time)."""
    code = ("import sys\n"
            "from campaign.cli import build_parser\n"
            "from campaign.commands import SUMMARY\n"
            "build_parser([])\n"
            "for name in SUMMARY: build_parser([name])\n"
            "heavy = [m for m in ('pandas', 'scipy', 'matplotlib', 'pyads', 'serial') if m in sys.modules]\n"
            "print(heavy); sys.exit(1 if heavy else 0)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=Path(ROOT),
                          check=False, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_specs_are_frozen_and_a_changed_copy_is_validated_again():
    import dataclasses

    from campaign.config import config_with, parse_config
    from campaign.errors import InputError

    config = parse_config(BASE, "base.toml")
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.axis.max_velocity = 1e9  # type: ignore[misc]
    with pytest.raises(TypeError):
        config.sections["axis"]["max_velocity"] = 1e9  # type: ignore[index]
    slower = config_with(config, {"axis": {"max_velocity": 5.0}})
    assert slower.axis.max_velocity == 5.0 and config.axis.max_velocity == 20.0
    assert slower.plan == config.plan and slower.source == "base.toml"
    with pytest.raises(InputError, match=r"base.toml: key 'axis.max_velocity': -1.0 is out of range"):
        config_with(config, {"axis": {"max_velocity": -1.0}})
    with pytest.raises(InputError, match=r"base.toml: key 'axis.soft_limit_max': must be above"):
        config_with(config, {"axis": {"soft_limit_min": 500.0}})
    spaced = config_with(config, {"plan": {"targets": None, "length": 100.0, "count": 3}})  # None: as if not given
    assert spaced.plan.targets is None and spaced.plan.length == 100.0
    listed = config_with(spaced, {"plan": {"targets": [0.0, 50.0], "length": None, "count": None}})
    assert listed.plan.targets == (0.0, 50.0) and listed.plan.length is None


def test_every_key_has_one_owning_spec_field_with_its_meaning():
    from dataclasses import fields

    from campaign.config import SCHEMA, SECTIONS

    owners = [(section, f.name) for section, specs in SECTIONS.items() for spec in specs
              for f in fields(spec) if "key" in f.metadata]
    assert len(owners) == len(set(owners)) == sum(len(keys) for keys in SCHEMA.values())
    assert all(key.doc for keys in SCHEMA.values() for key in keys.values())


def test_the_config_sections_are_frozen_to_the_last_list():
    """Nothing writes into a config: not a section, not a key, not a list inside one (the targets
    appended to once reached meta.json)."""
    from campaign.config import parse_config, recorded_sections

    config = parse_config('[campaign]\nmachine = "m"\n[axis]\nsoft_limit_min = -5.0\nsoft_limit_max = 105.0\n'
                          'max_velocity = 50.0\n[plan]\ntargets = [0.0, 50.0, 100.0]\nvelocity = 10.0\n', "c.toml")
    with pytest.raises(AttributeError):
        config.sections["plan"]["targets"].append(999.0)
    with pytest.raises(TypeError):
        config.sections["plan"]["cycles"] = 9
    with pytest.raises(AttributeError):
        config.data["plan"]["targets"].append(999.0)
    assert config.sections["plan"]["targets"] == (0.0, 50.0, 100.0)
    assert recorded_sections(config)["plan"]["targets"] == [0.0, 50.0, 100.0]  # JSON lists again

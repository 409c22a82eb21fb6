"""The layers of docs/architecture.md hold: import-linter checks the contracts in pyproject.toml."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept():
    lint = Path(sys.executable).with_name("lint-imports")
    proc = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "7 kept, 0 broken" in proc.stdout


def lint_a_copy(tmp_path, module: str, line: str) -> subprocess.CompletedProcess:
    """lint-imports on a copy of the project in which `module` (a path) also has `line`."""
    import shutil

    for name in ("campaign", "drivers", "protocols", "tests", "pyproject.toml"):
        src = ROOT / name
        (shutil.copytree(src, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__", "ads_client"))
         if src.is_dir() else shutil.copy(src, tmp_path / name))
    bad = tmp_path / module
    bad.write_text((bad.read_text() if bad.exists() else "") + f"\n{line}  # noqa\n")
    lint = Path(sys.executable).with_name("lint-imports")
    return subprocess.run([str(lint), "--no-cache"], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          check=False, env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"})


def test_a_broken_contract_is_reported(tmp_path):
    """The check can fail: a copy of protocols/ that imports campaign/ breaks the first contract."""
    proc = lint_a_copy(tmp_path, "protocols/units.py", "from campaign.errors import InputError")
    assert proc.returncode != 0
    assert "protocols/ is pure" in proc.stdout and "BROKEN" in proc.stdout


def test_a_driver_may_import_only_the_vocabulary(tmp_path):
    """drivers/ sits in the system's layers above the vocabulary only: a new driver module that
    imports a room of campaign/ (the outliers) breaks the contract; one that imports the vocabulary
    (the specs) keeps it."""
    proc = lint_a_copy(tmp_path / "room", "drivers/new_driver.py", "import campaign.outliers")
    assert proc.returncode != 0, proc.stdout[-2000:]
    assert "BROKEN" in proc.stdout and "drivers.new_driver -> campaign.outliers" in proc.stdout
    proc = lint_a_copy(tmp_path / "vocabulary", "drivers/new_driver.py", "import campaign.specs")
    assert proc.returncode == 0, proc.stdout[-2000:]


def test_the_run_time_code_never_imports_the_tests_helpers(tmp_path):
    proc = lint_a_copy(tmp_path, "campaign/measure/capture.py", "import tests.fakes")
    assert proc.returncode != 0
    assert "the tests' helpers are never imported by the code that runs BROKEN" in proc.stdout.replace("\n", " ")


def test_the_system_layers_list_the_rooms_of_the_exhaustive_contract():
    """The whole-system contract cannot be exhaustive by itself (import-linter needs a container):
    it lists the same rooms, in the same order, as the exhaustive contract of campaign/."""
    import tomllib

    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    rooms = next(c for c in contracts if c.get("containers") == ["campaign"])["layers"]
    system = next(c for c in contracts if c["name"].startswith("the system"))["layers"]
    in_campaign = [" | ".join(m.removeprefix("campaign.") for m in layer.split(" | ")) for layer in system
                   if layer.startswith("campaign.")]
    assert in_campaign == rooms
    assert system[-1] == "protocols" and "drivers" in system


def test_outside_code_uses_a_room_through_its_public_face(tmp_path):
    proc = lint_a_copy(tmp_path, "campaign/commands/plan.py", "from campaign.record.recorder import Recorder")
    assert proc.returncode != 0
    assert "campaign.commands.plan -> campaign.record.recorder" in proc.stdout


def test_the_fake_machine_is_imported_only_when_asked(tmp_path):
    """drivers/fake.py ships in the product, but run-time code reaches it only through
    drivers.factory.fake_opener(): a simulated driver that imports it breaks the contract."""
    proc = lint_a_copy(tmp_path, "drivers/sim/plc.py", "import drivers.fake")
    assert proc.returncode != 0
    assert "drivers.sim.plc -> drivers.fake" in proc.stdout

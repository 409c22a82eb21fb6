"""Strict typing where it pays: the modules pyproject.toml lists get every flag of `mypy --strict`
(per module, as mypy allows), and `make test`'s mypy run holds them to it. (A second run of
`mypy --strict` on them checked the same flags again and cost 19 s of the suite: dropped.)"""

import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STRICT_MODULES = {"campaign.specs", "campaign.plan", "campaign.measure", "campaign.measure.*", "campaign.record",
                  "campaign.record.*", "campaign.history.store"}


def mypy_config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]


def strict_flags() -> set[str]:
    """The flags `mypy --strict` turns on, as config keys (from this mypy's own --help)."""
    mypy = Path(sys.executable).with_name("mypy")
    text = subprocess.run([str(mypy), "--help"], capture_output=True, text=True, check=True, timeout=60).stdout
    block = re.search(r"--strict\s+Strict mode; enables the following flags:(.*?)\n  --", text, re.DOTALL)
    assert block, "mypy --help no longer lists the strict flags"
    flags = re.findall(r"--([a-z-]+)", re.sub(r"-\s*\n\s*", "-", block.group(1)))
    return {f.replace("-", "_") for f in flags}


def test_the_listed_modules_get_every_strict_flag():
    config = mypy_config()
    override = next(o for o in config["overrides"] if STRICT_MODULES <= set(o["module"]))
    wanted = strict_flags()
    assert len(wanted) >= 10 and "disallow_any_generics" in wanted
    for flag in sorted(wanted - {"warn_unused_configs"}):  # a global report about the config file itself
        assert override.get(flag) is True or config.get(flag) is True, f"{flag} is not on for the strict modules"

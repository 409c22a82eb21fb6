"""Shared test helpers, and the guard of the two tiers: a test that starts the simulated machine,
a subprocess campaign, a browser or a pty must be marked `machine`; without the mark it fails
at once saying so, so `pytest -m "not machine"` stays fast and honest."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

# One BLAS thread per process, set before numpy is first imported (and inherited by the xdist workers
# and every `axiscal` subprocess): three workers on two cores each running two BLAS threads spent
# twice the CPU for the same wall time (a 25,600-row discover: 67 s of CPU against 32 s) and made the
# machine tier's long discoveries several times slower than alone.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

import pytest

from campaign.cli import main
from tests.pg_server import postgres_server  # noqa: F401 - the session's PostgreSQL server, a fixture


def sweep(fast, *more):
    """Parameters of a sweep over seeds (or cases): the first runs in the fast tier, the others are
    marked `machine` (the marker's "sweeps many simulated campaigns"), so `make test` runs them all
    and the fast tier stays under a minute run plain."""
    return [fast, *(pytest.param(m, marks=pytest.mark.machine) for m in more)]


ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
PAPER = DATA / "paper-2022-beckhoff-press"


@pytest.fixture(autouse=True)
def _no_terminal_size(monkeypatch):
    """Every test sees the same environment however pytest is started: xdist's workers set COLUMNS
    and LINES (80 × 24), which rich would take for a terminal's size. A test that wants a width
    sets COLUMNS itself."""
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.delenv("LINES", raising=False)


os.environ["AXISCAL_DB"] = "none"
"""Campaigns in the tests record into no history store, never the user's default one: set for the
whole session (module- and session-scoped fixtures and their subprocesses included; an autouse
fixture starts too late for them). The history tests name their own store (tests/test_history*.py)."""


MACHINE_WORDS = ("axiscal", "-m campaign", "chromium", "chromedriver", "node", "rs274", "linuxcnc")
"""A subprocess whose command line holds one of these is a machine-tier process."""


def _refuse(what: str):
    def refuse(*args, **kwargs):
        raise AssertionError(f"this test {what}: mark it @pytest.mark.machine (see tests/conftest.py)")

    return refuse


def _guard(monkeypatch: pytest.MonkeyPatch) -> None:
    import pty

    from drivers.sim.ads_server import SimAdsServer

    monkeypatch.setattr(SimAdsServer, "start", _refuse("starts the simulated machine (ADS server)"))
    monkeypatch.setattr(os, "openpty", _refuse("opens a pty"))
    monkeypatch.setattr(os, "forkpty", _refuse("opens a pty"))
    monkeypatch.setattr(pty, "fork", _refuse("opens a pty"))
    real_popen_init = subprocess.Popen.__init__

    def popen_init(self, args, *rest, **kwargs):
        words = " ".join(map(str, args)) if isinstance(args, (list, tuple)) else str(args)
        if any(w in words for w in MACHINE_WORDS):
            _refuse(f"starts a subprocess ({words[:80]})")()
        real_popen_init(self, args, *rest, **kwargs)

    monkeypatch.setattr(subprocess.Popen, "__init__", popen_init)


UNGROUPED = pytest.StashKey[set]()
"""The tests xdist_group should have kept together and xdist did not (see below)."""


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    """Under `--dist loadgroup` (make test), a test marked xdist_group must have been given its group
    by xdist (the "@group" end of its id, added by then), or the group's tests run on several
    workers at once: pytest 9.2 with pytest-xdist 3.8 ignored the mark (pytest-xdist issue 1386),
    and two LinuxCNC tests met at the one-per-machine lock. Such tests fail at their set-up, saying
    so, instead of running apart."""
    if os.environ.get("PYTEST_XDIST_WORKER") and config.getvalue("loadgroup"):
        config.stash[UNGROUPED] = {item.nodeid for item in items
                                   if item.get_closest_marker("xdist_group") and "@" not in item.nodeid}


def pytest_runtest_setup(item):
    if item.nodeid in item.config.stash.get(UNGROUPED, set()):
        pytest.fail("--dist loadgroup did not keep this test in its xdist_group: this pytest and pytest-xdist "
                    "ignore the mark (pytest-xdist issue 1386; pyproject.toml pins pytest below 9.2)", pytrace=False)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Around the whole test (its fixtures of any scope included): unmarked tests get the guard."""
    if item.get_closest_marker("machine") is not None:
        yield
        return
    monkeypatch = pytest.MonkeyPatch()
    _guard(monkeypatch)
    try:
        yield
    finally:
        monkeypatch.undo()


def once_per_run(tmp_path_factory: pytest.TempPathFactory, name: str, make) -> Path:
    """The directory `make(directory)` fills, made once for the whole `pytest` run and shared by every
    xdist worker (beside the workers' own temporary directories, under a lock: the first worker to
    ask makes it, the others wait for it). For a module's expensive set-up whose result its tests
    only read: a module-scoped fixture ran once on each worker that got one of the module's tests.
    A test that writes into it copies it first."""
    import fcntl

    base = tmp_path_factory.getbasetemp()
    directory = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / f"once-{name}"
    with open(f"{directory}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        done = Path(f"{directory}.done")
        if not done.exists():
            shutil.rmtree(directory, ignore_errors=True)
            directory.mkdir()
            make(directory)
            done.touch()
    return directory


@pytest.fixture(scope="session")
def demo_campaign(tmp_path_factory):
    """`demo_campaign(*options)`: the campaign of `axiscal demo --json --plot PNG *options` (its --json
    result, its directory, the plot), recorded once for the whole `pytest` run (once_per_run). The
    demo is the same campaign every time (its seeds are in demo.toml), so the dozen tests that only
    read one share it instead of each recording its own (about 5 s of CPU each)."""
    import json
    import sys

    def make(options: tuple[str, ...], shared: Path) -> None:
        proc = subprocess.run([sys.executable, "-m", "campaign", "demo", "--out", str(shared / "demo"), "--json",
                               "--plot", str(shared / "demo.png"), *options],
                              capture_output=True, text=True, timeout=180, cwd=ROOT, check=False)
        assert proc.returncode == 0, proc.stderr[-2000:]
        (shared / "result.json").write_text(proc.stdout)

    def record(*options: str) -> tuple[dict, Path, Path]:
        name = "demo" + "".join(options).replace("-", "_")
        shared = once_per_run(tmp_path_factory, name, lambda directory: make(options, directory))
        return json.loads((shared / "result.json").read_text()), shared / "demo", shared / "demo.png"

    return record


class CliResult:
    def __init__(self, code: int, out: str, err: str):
        self.code, self.out, self.err = code, out, err


@pytest.fixture
def cli(capsys):
    """Run `axiscal ARGS...` in-process; returns exit code, stdout and stderr."""

    def run(*args: str) -> CliResult:
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return CliResult(code, captured.out, captured.err)

    return run


def events(directory, kind: str | None = None, **data) -> list[dict]:
    """The events.jsonl records of a campaign directory, of `kind` and with `data` items if given."""
    from campaign.record.directory import read_events

    return [e for e in read_events(directory)
            if (kind is None or e["kind"] == kind) and all(e["data"].get(k) == v for k, v in data.items())]


def status(directory) -> str:
    """The campaign's status from its run records (completed, interrupted, failed, running)."""
    from campaign.record.directory import open_campaign

    return open_campaign(directory).status


def assert_one_line_error(result: CliResult, *fragments: str) -> None:
    """Exit 2, exactly one stderr line starting with 'error:', no traceback, fragments in it."""
    assert result.code == 2, (result.code, result.err)
    lines = result.err.strip().splitlines()
    assert len(lines) == 1, result.err
    assert lines[0].startswith("error: "), lines[0]
    assert "Traceback" not in result.err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])

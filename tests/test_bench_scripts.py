"""`make bench` (bench/run_all.py) runs every benchmark script in bench/, or says why one is run by
hand: a new script is not silently left out of it."""

from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench"


def test_run_all_runs_every_bench_script_or_says_why_not():
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_run_all", BENCH / "run_all.py")
    assert spec is not None and spec.loader is not None
    run_all = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_all)
    run = {script for script, *_ in run_all.SCRIPTS}
    separate = set(run_all.SEPARATE)
    scripts = {path.name for path in BENCH.glob("*.py")} - {"run_all.py"}
    assert run | separate == scripts, f"not in SCRIPTS nor SEPARATE: {sorted(scripts - run - separate)}; " \
                                      f"no such script: {sorted((run | separate) - scripts)}"
    assert not run & separate
    assert all(len(why) > 20 for why in run_all.SEPARATE.values())

# Quick start: `make demo` or `make test`. Both create .venv if missing and install the project.
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	rm -rf runs/demo
	$(VENV)/bin/axiscal demo --out runs/demo --plot runs/demo/iso230.png
	$(VENV)/bin/axiscal report runs/demo -o runs/demo/report.html

# Four workers on two cores: the tests that start a real-time LinuxCNC (one per machine: one xdist
# group, scheduled first as the largest) keep one worker waiting on LinuxCNC's motion for about five
# minutes with little CPU, and tests that wait on a subprocess or a socket leave a core idle; three
# workers kept the cores 89 % busy, four 92 % (671 s against 657 s of pytest). One BLAS thread per process
# (tests/conftest.py sets the same for a plain `pytest`): more only oversubscribes the two cores.
# mypy runs beside pytest (it has a core to itself while the workers start) and fails the target
# after pytest's report when it found errors.
# The system packages (tests/setup_system.sh: apt-get, npm) install beside the Python packages: on a
# fresh clone each took about 40 s, one after the other.
test:
	bash tests/setup_system.sh & setup=$$!; $(MAKE) --no-print-directory $(STAMP); made=$$?; \
	wait $$setup; test $$made -eq 0
	report=$$(mktemp); $(VENV)/bin/mypy campaign drivers protocols > "$$report" 2>&1 & mypy=$$!; \
	trap 'kill $$mypy 2>/dev/null; rm -f "$$report"' EXIT INT TERM; \
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m pytest -q -n 4 --dist loadgroup; tests=$$?; \
	wait $$mypy; typed=$$?; cat "$$report"; test $$tests -eq 0 -a $$typed -eq 0

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports

bench: $(STAMP)
	$(PY) bench/run_all.py

clean:
	rm -rf $(VENV) runs .pytest_cache

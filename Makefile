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

test: $(STAMP)
	bash tests/setup_system.sh
	$(VENV)/bin/mypy campaign drivers protocols
	$(PY) -m pytest -q -n 2 -m 'not linuxcnc'
	$(PY) -m pytest -q -m linuxcnc

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports

bench: $(STAMP)
	$(PY) bench/run_all.py

clean:
	rm -rf $(VENV) runs .pytest_cache

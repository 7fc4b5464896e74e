# The two commands of the README. Both create .venv on first use; later runs reuse it
# (the stamp files are redone only when pyproject.toml or the constraints change).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
# Pins the CPU build of torch; without it pip pulls a CUDA build of several GB.
CONSTRAINTS := constraints/cpu.txt

.PHONY: demo test test-fast lint clean

demo: $(VENV)/.installed
	$(BIN)/senbench run suites/quickstart.yaml --workers 2
	$(BIN)/senbench report results/quickstart

# Two pytest workers (pytest-xdist): many tests wait on the processes they start, so two
# at a time keep both cores busy.
test: $(VENV)/.installed-dev
	$(BIN)/pytest -q -n 2

# The tier to run on every change: everything but the tests marked slow (under 90 s).
test-fast: $(VENV)/.installed-dev
	$(BIN)/pytest -q -m "not slow"

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check .

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip

$(VENV)/.installed: $(VENV)/bin/python pyproject.toml $(CONSTRAINTS)
	$(BIN)/pip install -q -c $(CONSTRAINTS) -e .
	touch $@

$(VENV)/.installed-dev: $(VENV)/.installed
	$(BIN)/pip install -q -c $(CONSTRAINTS) -e '.[dev]'
	touch $@

clean:
	rm -rf $(VENV) results/quickstart

# One command sets up and runs each job on a fresh machine (Debian, Python >= 3.10).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# Menagerie's Panda: a local copy beside the project when there is no internet.
export MENAGERIE_ROOT ?= $(abspath ../shared/menagerie)
export OMP_NUM_THREADS ?= 1

.PHONY: setup demo test test-fast bench clean

# The tested set of packages (constraints.txt) within setup.cfg's ranges; torch first, as
# the CPU build (an unpinned torch pulls a multi-GB CUDA build).
$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip
	$(BIN)/pip install -c constraints.txt torch==2.13.0
	$(BIN)/pip install -c constraints.txt -e ".[test,train]"

setup: $(BIN)/activate

demo: setup
	$(BIN)/franka-composer demo

test: setup
	$(BIN)/python -m pytest -q

test-fast: setup
	$(BIN)/python -m pytest -q -m "not slow"

# The documentation site, warnings as errors, into docs/_build/html (docs/_scripts/screenshots.sh
# then shows it in a headless browser).
.PHONY: docs
docs: setup
	$(BIN)/pip install -c constraints.txt -e ".[docs]"
	$(BIN)/sphinx-build -W --keep-going -b html docs docs/_build/html

bench: setup
	$(BIN)/python benchmarks/bench.py

clean:
	rm -rf $(VENV) demo_output

# One command sets up and runs each job on a fresh machine (Debian, Python >= 3.11).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# PyTorch's CPU wheels (PyPI's torch is a multi-GB CUDA build), as an extra index beside
# pip's own: its 2.13.0+cpu sorts above PyPI's 2.13.0, torch's dependencies still come
# from pip's indexes, and where it cannot be reached a local +cpu wheel (find-links) is
# taken. Empty: pip's own indexes alone.
TORCH_INDEX ?= https://download.pytorch.org/whl/cpu
export OMP_NUM_THREADS ?= 1

# Menagerie's Panda: MENAGERIE_ROOT as the user set it; else mujoco-menagerie's own cache (or
# its download) when the cache has the Panda or no local copy exists; else the local copy
# beside the project (machines without internet).
MENAGERIE_COPY := $(abspath ../shared/menagerie)
WITH_MENAGERIE = if [ -z "$${MENAGERIE_ROOT:-}" ] && [ -d "$(MENAGERIE_COPY)/franka_emika_panda" ] \
	&& ! $(BIN)/python -c 'import sys, franka_composer.assets as a; sys.exit(not a.panda_in_cache())' \
	2>/dev/null; then export MENAGERIE_ROOT="$(MENAGERIE_COPY)"; fi;
# The tests run as in the venv activated: the scripts they start (benchmarks/*.sh) take the
# tools on PATH where the checkout has no .venv of its own (VENV=elsewhere).
IN_VENV = export PATH="$(abspath $(BIN)):$$PATH";

.PHONY: setup setup-demo demo test test-fast bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip

# Each setup installs once, and again when constraints.txt or setup.cfg is newer than its
# stamp in the venv (a venv kept from before took none of their changes); else pip is not run.
# `setup` installs what `setup-demo` does too, and stamps both.
# What the demo needs: the environments and video writing (no training, datasets or sweeps).
setup-demo: $(VENV)/.setup-demo
$(VENV)/.setup-demo: constraints.txt setup.cfg | $(BIN)/python
	$(BIN)/pip install -c constraints.txt -e .
	touch $@

# Everything the tests use, in the tested versions (constraints.txt) within setup.cfg's
# ranges; torch first, as the CPU build.
setup: $(VENV)/.setup
$(VENV)/.setup: constraints.txt setup.cfg | $(BIN)/python
	$(BIN)/pip install -c constraints.txt torch==2.13.0 $(if $(TORCH_INDEX),--extra-index-url $(TORCH_INDEX))
	$(BIN)/pip install -c constraints.txt -e ".[test,train]"
	touch $@ $(VENV)/.setup-demo

demo: setup-demo
	$(WITH_MENAGERIE) $(BIN)/franka-composer demo

test: setup
	$(WITH_MENAGERIE) $(IN_VENV) $(BIN)/python -m pytest -q

test-fast: setup
	$(WITH_MENAGERIE) $(IN_VENV) $(BIN)/python -m pytest -q -m "not slow"

# The documentation site, warnings as errors, into docs/_build/html (docs/_scripts/screenshots.sh
# then shows it in a headless browser).
.PHONY: docs
docs: setup
	$(BIN)/pip install -c constraints.txt -e ".[docs]"
	$(BIN)/sphinx-build -W --keep-going -b html docs docs/_build/html

bench: setup
	$(WITH_MENAGERIE) $(BIN)/python benchmarks/bench.py

clean:
	rm -rf $(VENV) demo_output docs/_build docs/tasks build dist *.egg-info

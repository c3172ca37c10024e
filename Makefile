# Developer targets; CI runs .ci/run, which calls the same commands.
PYTHON ?= python

.PHONY: install test test-all lint format type doc examples check

install:
	$(PYTHON) -m pip install torch==2.13.0 -e ".[dev]"

# The quick lane while developing (the tests marked slow left out); CI runs the full suite (test-all).
test:
	$(PYTHON) -m pytest -q -m "not slow"

test-all:
	$(PYTHON) -m pytest -q

lint:
	$(PYTHON) -m ruff check sb3_maddpg tests examples benchmarks docs
	$(PYTHON) -m ruff format --check sb3_maddpg tests examples benchmarks docs

format:
	$(PYTHON) -m ruff check --fix sb3_maddpg tests examples benchmarks docs
	$(PYTHON) -m ruff format sb3_maddpg tests examples benchmarks docs

type:
	$(PYTHON) -m mypy

doc:
	$(PYTHON) -m sphinx -W --keep-going -b html docs docs/_build/html

check: lint type test-all doc

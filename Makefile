# Every target bootstraps its own virtual environment in .venv on first use.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CONFIG ?= configs/twoblock.yaml
THREADS ?=

.PHONY: sweep test bench figures lint clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

sweep: $(STAMP)
	$(PY) -m sweep run $(CONFIG) $(if $(THREADS),--threads $(THREADS))

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) -m sweep.bench

figures: $(STAMP)
	$(PY) -m sweep figures

lint: $(STAMP)
	$(PY) -m ruff check sweep tests
	$(PY) -m ruff format --check sweep tests

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build *.egg-info

# Every target bootstraps its own virtual environment in .venv on first use.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CONFIG ?= configs/twoblock.yaml
THREADS ?=

.PHONY: sweep test test-nojit bench figures lint clean venv docs

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,zarr,docs]'
	touch $(STAMP)

sweep: $(STAMP)
	$(PY) -m sweep run $(CONFIG) $(if $(THREADS),--threads $(THREADS))

test: $(STAMP)
	$(PY) -m pytest -q

# The kernels as plain Python, so they count in coverage runs: the tests of the
# model, kernels, grid, files and CLI (the long regularised, batch and figure runs
# would take hours without the JIT).
NOJIT_TESTS := tests/test_physics.py tests/test_kernels.py tests/test_grid.py \
	tests/test_cli.py tests/test_config.py tests/test_dataset.py tests/test_accelerate.py
test-nojit: $(STAMP)
	NUMBA_DISABLE_JIT=1 $(PY) -m pytest -q $(NOJIT_TESTS)

bench: $(STAMP)
	$(PY) benchmarks/bench.py

figures: $(STAMP)
	$(PY) -m sweep figures --dpi 100

# The documentation site, offline, warnings as errors: docs/_build/html/index.html.
# The gallery's examples run during the build (seconds once the kernels are cached).
docs: $(STAMP)
	$(PY) -m sphinx -E -W --keep-going -q -b html docs docs/_build/html
	@echo "open docs/_build/html/index.html"

lint: $(STAMP)
	$(PY) -m ruff check sweep tests benchmarks examples docs/conf.py docs/_ext
	$(PY) -m ruff format --check sweep tests benchmarks examples docs/conf.py docs/_ext

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build *.egg-info docs/_build docs/auto_examples docs/generated

# Every target bootstraps its own virtual environment in .venv on first use.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CONFIG ?= configs/twoblock.yaml
THREADS ?=

# Python's bytecode, written once by the first process that imports a module, under
# .venv (not beside the sources). Where PYTHONDONTWRITEBYTECODE is set, as on the CI
# machine, every process would compile numpy, numba, xarray and matplotlib from source
# again: 3.5 s of CPU more to import the package, 7.5 s more for a small CLI run (uv,
# unlike pip, writes no bytecode at install), and the suite starts many processes.
unexport PYTHONDONTWRITEBYTECODE
export PYTHONPYCACHEPREFIX := $(CURDIR)/$(VENV)/pycache

.PHONY: sweep kick test test-all test-nojit bench figures lint clean venv docs bit-identity-reference

venv: $(STAMP)

# uv (from PyPI, into the venv) installs the packages: 20 s where pip takes 100.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet uv
	$(PY) -m uv pip install --quiet --python $(PY) -e '.[test,zarr,bench,docs]'
	touch $(STAMP)

sweep: $(STAMP)
	$(PY) -m sweep run $(CONFIG) $(if $(THREADS),--threads $(THREADS))

# The critical kick of a config that sweeps the start (initial_v_over_V), bisected to
# 1 %: results/<name>_kick.nc and .png; resumes from that file. E.g.
#   make kick CONFIG=configs/kick_slip_law.yaml
kick: $(STAMP)
	$(PY) -m sweep kick $(CONFIG) $(if $(THREADS),--threads $(THREADS))

# The suite on TEST_WORKERS processes (pytest-xdist; "auto": one per core), which take
# tests as they come free and share numba's on-disk cache of compiled kernels. First the
# kernel variants a tier uses (tests/data/kernel_variants*.txt) are compiled into that
# cache, each once, one process per core (tests/precompile.py; loads when warm). The
# report ends with the slowest tests (and set-ups), where the suite's time goes.
#   make test       the fast tier: every test not marked slow (every method, model,
#                   coupling, unequal blocks and the tangent compiled at least once)
#   make test-all   every test (CI runs this one)
TEST_WORKERS ?= 2
test: $(STAMP)
	$(PY) tests/precompile.py --tier fast
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal -m "not slow" --durations=15

test-all: $(STAMP)
	$(PY) tests/precompile.py --tier all
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal --durations=25

# The kernels as plain Python, so they count in coverage runs: the tests of the
# model, kernels, grid, files and CLI (the long regularised, batch and figure runs
# would take hours without the JIT).
NOJIT_TESTS := tests/test_physics.py tests/test_kernels.py tests/test_grid.py \
	tests/test_cli.py tests/test_config.py tests/test_dataset.py tests/test_accelerate.py
test-nojit: $(STAMP)
	NUMBA_DISABLE_JIT=1 $(PY) -m pytest -q $(NOJIT_TESTS)

# The benchmarks (results/bench.json), then the plot of the engine against its peers
# drawn from them (results/bench_peers.png; docs/performance.md).
bench: $(STAMP)
	$(PY) benchmarks/bench.py
	$(PY) benchmarks/plot_bench.py

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

# The bit-identity guard's reference (tests/test_bit_identity.py): git archive of
# COMMIT's sweep/ and tests/bit_identity_cases.py, and REFERENCE_COMMIT set to COMMIT.
REFERENCE_ARCHIVE := tests/data/bit_identity_reference.tar.gz
bit-identity-reference:
	@test -n "$(COMMIT)" || { echo "usage: make bit-identity-reference COMMIT=<commit>" >&2; exit 2; }
	commit=$$(git rev-parse --verify "$(COMMIT)^{commit}") && \
	git archive --format=tar.gz -o $(REFERENCE_ARCHIVE) $$commit sweep tests/bit_identity_cases.py && \
	$(PYTHON) -c 'import re, sys; p = "tests/test_bit_identity.py"; s = open(p).read(); \
	open(p, "w").write(re.sub(r"REFERENCE_COMMIT = \"\w+\"", f"REFERENCE_COMMIT = \"{sys.argv[1]}\"", s))' $$commit
	@ls -l $(REFERENCE_ARCHIVE)

clean:
	rm -rf $(VENV) .cache .pytest_cache .ruff_cache build *.egg-info docs/_build docs/auto_examples docs/generated

# kinegen: derive robot kinematics in SymPy, generate verified numpy and C kernels.
#
#   make            set up .venv, regenerate every kernel, build the C, verify, print the summary
#   make test       set up if needed, build the C, run the whole test suite
#   make generate   regenerate generated/ from derivations/ (deterministic)
#   make build      compile the generated C (strict warnings) and its cffi extensions
#   make verify     kernels against SymPy at 30 digits, as a table
#   make check      fail when generated/ is out of date with derivations/ and codegen/
#   make bench      time the kernels against lambdify, the Robotics Toolbox and Pinocchio
#                   (installed into .venv-bench only); writes benchmarks/results.md
#   make clean      remove the virtual environment, caches and built libraries

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
KINEGEN := $(PY) -m codegen
# The benchmark's own environment: the project plus the peers it is timed against.
BENCH_VENV ?= .venv-bench
BENCH_PY := $(BENCH_VENV)/bin/python
BENCH_STAMP := $(BENCH_VENV)/.installed
BENCH_PEERS = $$($(BENCH_PY) -c "import tomllib; print(' '.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['bench']))")

.PHONY: all install generate build sanitize verify check test bench clean

all: $(STAMP)
	$(KINEGEN) all

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $@

install: $(STAMP)

generate: $(STAMP)
	$(KINEGEN) generate

build: $(STAMP)
	$(KINEGEN) build

sanitize: build
	$(KINEGEN) sanitize

verify: build
	$(KINEGEN) verify

check: $(STAMP)
	$(KINEGEN) check

test: build
	$(PY) -m pytest

# A peer that cannot be installed here is left out (the table says "not installed").
$(BENCH_STAMP): pyproject.toml
	$(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(BENCH_PY) -m pip install --quiet --disable-pip-version-check -e .
	$(BENCH_PY) -m pip install --quiet --disable-pip-version-check -e '.[bench]' || \
	for peer in $(BENCH_PEERS); do \
		$(BENCH_PY) -m pip install --quiet --disable-pip-version-check "$$peer" || echo "bench: $$peer not installed"; \
	done
	touch $@

bench: $(BENCH_STAMP)
	$(BENCH_PY) -m codegen build --quiet
	$(BENCH_PY) benchmarks/run.py

clean:
	rm -rf $(VENV) $(BENCH_VENV) .cache build *.egg-info
	find generated -name '*.so' -delete

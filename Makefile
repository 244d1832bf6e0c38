# kinegen: derive robot kinematics in SymPy, generate verified numpy and C kernels.
#
#   make            set up .venv, regenerate every kernel, build the C, verify, print the summary
#   make test       set up if needed, build the C, run the whole test suite
#   make generate   regenerate generated/ from derivations/ (deterministic)
#   make build      compile the generated C (strict warnings) and its cffi extensions
#   make verify     kernels against SymPy at 30 digits, as a table
#   make check      fail when generated/ is out of date with derivations/ and codegen/
#   make bench      time Paul's partitioned inverse against a 6x6 solve (PUMA 560)
#   make clean      remove the virtual environment, caches and built libraries

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
KINEGEN := $(PY) -m codegen

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

bench: build
	$(PY) benchmarks/wrist_partition.py

clean:
	rm -rf $(VENV) .cache build *.egg-info
	find generated -name '*.so' -delete

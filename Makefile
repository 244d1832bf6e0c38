# kinegen: derive robot kinematics in SymPy, generate verified numpy and C kernels.
#
#   make            set up .venv, regenerate every kernel, build the C, verify, print the summary
#   make test       set up if needed, build the C, run the whole test suite
#   make generate   regenerate generated/ from derivations/ (deterministic)
#   make build      compile the generated C (strict warnings) and its cffi extensions
#   make verify     kernels against SymPy at 30 digits, as a table
#   make check      fail when generated/ is out of date with derivations/ and codegen/
#   make plots      trajectory plots as PNG files in plots/ (installs matplotlib, the 'plots' extra)
#   make clean      remove the virtual environment, caches and built libraries

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PLOTS_STAMP := $(VENV)/.plots-installed
KINEGEN := $(PY) -m codegen

.PHONY: all install generate build sanitize verify check test plots clean

all: $(STAMP)
	$(KINEGEN) all

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $@

install: $(STAMP)

# matplotlib, for `make plots` and the plot tests (about 20 s to install, once)
$(PLOTS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev,plots]'
	touch $@

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

# matplotlib is installed when it can be; without it the plot tests skip, saying why.
test: build
	@$(MAKE) --no-print-directory $(PLOTS_STAMP) || echo "make test: matplotlib not installed; the plot tests will skip"
	$(PY) -m pytest

plots: $(PLOTS_STAMP)
	$(PY) -m codegen.plots --out plots

clean:
	rm -rf $(VENV) .cache build *.egg-info
	find generated -name '*.so' -delete

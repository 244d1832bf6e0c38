# kinegen: derive robot kinematics in SymPy, generate verified numpy and C kernels.
#
#   make            set up .venv, regenerate every kernel, build the C, verify, print the summary
#   make test       set up if needed, build the C, run the whole test suite
#   make generate   regenerate generated/ from derivations/ (deterministic)
#   make build      compile the generated C (strict warnings) and its cffi extensions
#   make verify     kernels against SymPy at 30 digits, as a table
#   make check      fail when generated/ is out of date with derivations/ and codegen/
#   make report     the PDF report (report/build/kinegen-report.pdf); installs TeX Live if missing
#   make avr-limits the AVR 3000 Matlab script: axis limits from motor limits (R=18.3in by default)
#   make plots      trajectory plots as PNG files in plots/ (installs matplotlib, the 'plots' extra)
#   make bench      time the kernels against lambdify, the Robotics Toolbox and Pinocchio
#                   (installed into .venv-bench only; writes benchmarks/results.md), then
#                   Paul's partitioned inverse against a 6x6 solve (PUMA 560), then the cold
#                   generation time of every zoo arm (benchmarks/zoo.md)
#   make clean      remove the virtual environment, caches and built libraries

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PLOTS_STAMP := $(VENV)/.plots-installed
KINEGEN := $(PY) -m codegen
# The benchmark's own environment: the project plus the peers it is timed against.
BENCH_VENV ?= .venv-bench
BENCH_PY := $(BENCH_VENV)/bin/python
BENCH_STAMP := $(BENCH_VENV)/.installed
BENCH_PEERS = $$($(BENCH_PY) -c "import tomllib; print(' '.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['bench']))")

.PHONY: all install generate build sanitize verify check test report texlive plots bench clean avr-limits

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

avr-limits: $(STAMP)
	$(KINEGEN) --quiet avr3000-limits --R=$(or $(R),18.3in)

# matplotlib is installed when it can be; without it the plot tests skip, saying why.
test: build
	@$(MAKE) --no-print-directory $(PLOTS_STAMP) || echo "make test: matplotlib not installed; the plot tests will skip"
	$(PY) -m pytest

# The report needs pdflatex; `make test` does not (it skips the report build without it).
# texlive-latex-base + texlive-latex-recommended hold every package the report loads.
TEXLIVE_PACKAGES := texlive-latex-base texlive-latex-recommended
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

texlive:
	@command -v pdflatex >/dev/null 2>&1 || { \
	  echo "pdflatex not found: installing $(TEXLIVE_PACKAGES)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(TEXLIVE_PACKAGES); }

report: $(STAMP) texlive
	$(KINEGEN) report
plots: $(PLOTS_STAMP)
	$(PY) -m codegen.plots --out plots

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
	$(BENCH_PY) benchmarks/wrist_partition.py
	$(BENCH_PY) benchmarks/zoo_generation.py

clean:
	rm -rf $(VENV) $(BENCH_VENV) .cache build *.egg-info
	find generated -name '*.so' -delete

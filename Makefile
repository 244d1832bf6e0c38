# kinegen: derive robot kinematics in SymPy, generate verified numpy and C kernels.
#
#   make            set up .venv, regenerate every kernel, build the C, verify, print the summary
#                   (each stage skipped when its inputs did not change; the time of each at the end)
#   make test       set up if needed, build the C (the portable layout a user's package builds;
#                   the sanitizer tests compile every layout), run the whole test suite on every
#                   core (with the sanitizer runs); the time of each stage at the end
#   make generate   regenerate generated/ from derivations/ (deterministic)
#   make build      compile the generated C (strict warnings) and its cffi extensions (what changed)
#   make sanitize   every C entry point under ASan and UBSan
#   make fuzz       the long fuzz: the hypothesis properties and random descriptions at their long
#                   profile, then libFuzzer over every C entry point (installs clang if missing)
#   make verify     kernels against SymPy at 30 digits, as a table
#   make check      fail when generated/ is out of date with derivations/ and codegen/
#   make report     the PDF report (report/build/kinegen-report.pdf); installs TeX Live if missing
#   make avr-limits the AVR 3000 Matlab script: axis limits from motor limits (R=18.3in by default)
#   make plots      trajectory plots as PNG files in plots/ (installs matplotlib, the 'plots' extra)
#   make bench      time the kernels against lambdify, the Robotics Toolbox and Pinocchio
#                   (installed into .venv-bench only; writes benchmarks/results.md), then
#                   Paul's partitioned inverse against a 6x6 solve (PUMA 560), then the cold
#                   generation time of every zoo arm with its compile (benchmarks/zoo.md), then the
#                   real URDF files: generation and the kernels against Pinocchio (benchmarks/urdf_zoo.md),
#                   then the automatic IK of a UR5 and a KR5 against the Toolbox's ikine_LM and
#                   analytic_ik (benchmarks/auto_ik.md), then the time and memory of the refusals
#                   of hostile input (benchmarks/refusals.md), then the closed-form ik of short
#                   chains and of 4- to 6-joint arms' tasks, 10,000 + 1,000 configurations in both
#                   backends (benchmarks/short_chains.md; in .venv, as it reads the tests' helpers),
#                   then ik_numeric in C and numpy against the Toolbox's ik_LM on the Panda and the
#                   Jaco, and ik of one 4x4 pose against the 12-vector (benchmarks/numeric_ik.md),
#                   then the general 6R's every real solution of the Jaco, 10,000 + 1,000 poses in
#                   both backends, against the Toolbox's Raghavan-Roth and ik_LM (benchmarks/general_6r.md),
#                   then every closed-form arm of both zoos: wrong, missing and no-solution counts
#                   over 10,000 + 1,000 configurations in both backends (benchmarks/ik_census.md; in .venv)
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

.PHONY: all install plots-install generate build sanitize fuzz verify check test report texlive clang plots bench clean avr-limits

# How long each stage took, printed at the end of make and make test: $(call timed,STAGE,COMMAND)
# runs COMMAND and, when it succeeds, adds "STAGE seconds" to $(TIMES).
TIMES := .cache/stage-times
timed = start=$$(date +%s.%N) && $(2) && \
	awk -v s=$$start -v e=$$(date +%s.%N) 'BEGIN { printf "%-9s %6.1f s\n", "$(1)", e - s }' >> $(TIMES)
show_times = echo "time per stage ($@):" && sed 's/^/  /' $(TIMES) && \
	awk '{ t += $$2 } END { printf "  %-9s %6.1f s\n", "total", t }' $(TIMES)
# The test suite's worker processes (pytest-xdist): one per CPU this process may use.
TEST_JOBS ?= $(shell nproc 2>/dev/null || echo 2)

# `kinegen all` regenerates, builds and verifies, each only if its inputs changed since the
# last run (content stamps in .cache/make and beside each extension); `make generate`,
# `make build` and `make verify` always do theirs.
all:
	@mkdir -p $(dir $(TIMES)) && : > $(TIMES)
	@$(call timed,install,$(MAKE) --no-print-directory install)
	@$(KINEGEN) all --times $(TIMES)
	@$(show_times)

# pip as Python's venv brings it (no upgrade: it installs an editable pyproject.toml
# project since pip 21.3).  WITH_PLOTS=1 (make test) adds the 'plots' extra in the same
# resolve, and falls back to without it when matplotlib cannot be installed.
PIP_INSTALL := $(PY) -m pip install --quiet --disable-pip-version-check
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	@plots=; if [ -n "$(WITH_PLOTS)" ]; then \
		echo "$(PIP_INSTALL) -e '.[dev,plots]'"; \
		if $(PIP_INSTALL) -e '.[dev,plots]'; then plots=1; else \
		echo "make: matplotlib not installed; the plot tests will skip"; $(PIP_INSTALL) -e '.[dev]' || exit 1; fi; \
	else echo "$(PIP_INSTALL) -e '.[dev]'"; $(PIP_INSTALL) -e '.[dev]' || exit 1; fi; \
	touch $@; if [ -n "$$plots" ]; then touch $(PLOTS_STAMP); fi

install: $(STAMP)
	@:

# matplotlib, for `make plots` and the plot tests (the 'plots' extra; about 20 s to install, once)
PLOTS_REQUIREMENTS = $$($(PY) -c "import tomllib; print(' '.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['plots']))")
$(PLOTS_STAMP): $(STAMP)
	$(PIP_INSTALL) $(PLOTS_REQUIREMENTS)
	touch $@

plots-install: $(PLOTS_STAMP)
	@:

generate: $(STAMP)
	$(KINEGEN) generate

build: $(STAMP)
	$(KINEGEN) build

sanitize: build
	$(KINEGEN) sanitize

verify: build
	$(KINEGEN) verify

# The long profile of the property tests (the short one runs in `make test`), then libFuzzer
# over every C entry point (`kinegen fuzz`: a million inputs each; --runs N, --seconds S).
fuzz: build clang
	HYPOTHESIS_PROFILE=fuzz $(PY) -m pytest -n $(TEST_JOBS) -m fuzz -p no:cacheprovider
	$(KINEGEN) fuzz

check: $(STAMP)
	$(KINEGEN) check

avr-limits: $(STAMP)
	$(KINEGEN) --quiet avr3000-limits --R=$(or $(R),18.3in)

# The whole suite, sanitizer runs included, in $(TEST_JOBS) processes (a worker that runs out
# of tests takes some of the other's: the long ones do not leave a tail).  matplotlib is
# installed when it can be; without it the plot tests skip, saying why.
# make test builds the C at -O0 (KINEGEN_OPT, read by each package's build_c.py): the suite checks
# values, which every level computes alike, and -O0 compiles in a fraction of the time; the
# default -O2 build is the one tests/generation/test_install.py installs.
test: export KINEGEN_OPT = -O0
test:
	@mkdir -p $(dir $(TIMES)) && : > $(TIMES)
	@$(call timed,install,$(MAKE) --no-print-directory install WITH_PLOTS=1 && \
		{ $(MAKE) --no-print-directory plots-install || echo "make test: matplotlib not installed; the plot tests will skip"; })
	@$(call timed,build,$(KINEGEN) build --portable)
	@$(call timed,pytest,$(PY) -m pytest -n $(TEST_JOBS) --dist worksteal)
	@$(show_times)

# The report needs pdflatex; `make test` does not (it skips the report build without it).
# texlive-latex-base + texlive-latex-recommended hold every package the report loads.
TEXLIVE_PACKAGES := texlive-latex-base texlive-latex-recommended
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

texlive:
	@command -v pdflatex >/dev/null 2>&1 || { \
	  echo "pdflatex not found: installing $(TEXLIVE_PACKAGES)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(TEXLIVE_PACKAGES); }

# libFuzzer for `make fuzz`: clang and its compiler-rt runtimes (libFuzzer, ASan, UBSan), which
# clang only recommends (about 10 s to install here).
CLANG_PACKAGES := clang libclang-rt-dev

clang:
	@command -v clang >/dev/null 2>&1 || { \
	  echo "clang not found: installing $(CLANG_PACKAGES)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(CLANG_PACKAGES); }

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

bench: $(BENCH_STAMP) $(STAMP)
	$(BENCH_PY) -m codegen build --quiet
	$(BENCH_PY) benchmarks/run.py
	$(BENCH_PY) benchmarks/wrist_partition.py
	$(BENCH_PY) benchmarks/zoo_generation.py
	$(BENCH_PY) benchmarks/urdf_zoo.py
	$(BENCH_PY) benchmarks/auto_ik.py
	$(BENCH_PY) benchmarks/dynamics.py
	$(BENCH_PY) benchmarks/refusals.py
	$(PY) benchmarks/short_chains.py
	$(BENCH_PY) benchmarks/numeric_ik.py
	$(BENCH_PY) benchmarks/general_6r.py
	$(BENCH_PY) benchmarks/peers_ik.py
	$(PY) benchmarks/ik_census.py --out build/ik_census --markdown benchmarks/ik_census.md

clean:
	rm -rf $(VENV) $(BENCH_VENV) .cache build *.egg-info
	find generated \( -name '*.so' -o -name '*.stamp' \) -delete

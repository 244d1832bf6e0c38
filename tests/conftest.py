import os
import resource
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# The tests live in one folder per layer (tests/ik/, tests/rates/, ..., docs/architecture.md) and
# share helpers across them (test_zoo's arms, urdf_zoo, this file's kernels): every folder is on the
# path, as tests/ alone was, whichever test pytest imports first.
_HERE = Path(__file__).resolve().parent
for _folder in [_HERE, *sorted(p for p in _HERE.iterdir() if p.is_dir() and p.name not in ("data", "__pycache__"))]:
    if str(_folder) not in sys.path:
        sys.path.insert(0, str(_folder))

import derivations  # noqa: E402
import generated  # noqa: E402

# Under pytest-xdist every core already runs a worker of its own: a render's, a verification's or a
# fuzz run's own worker processes (KINEGEN_JOBS, default one per core) would only add their forks
# and the pickling of every kernel to and fro (a tenth of a zoo arm's `kinegen generate`: 5.3 ->
# 4.9 s of CPU for the KR 5), so the tests and the commands they start do their work in one
# process.  The tests of the worker processes themselves ask for theirs (jobs=2, KINEGEN_JOBS=2).
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("KINEGEN_JOBS", "1")

ROBOT_NAMES = list(derivations.ROBOTS)

# Hypothesis profiles (tests/test_properties.py, tests/test_random_descriptions.py), chosen by
# HYPOTHESIS_PROFILE: "default" is the short run of `make test`; "fuzz" the long one of `make fuzz`.
# Both are derandomized (the examples follow from the test alone, so a CI failure reproduces) and
# keep no example database.  Tests that cost more per example take a fraction of max_examples.
_PROFILE = dict(derandomize=True, database=None, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("default", max_examples=10, **_PROFILE)
settings.register_profile("fuzz", max_examples=2000, **_PROFILE)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@pytest.fixture(scope="session")
def models():
    """Every registered model, derived once (and cached on disk)."""
    return {name: derivations.load(name) for name in ROBOT_NAMES}


def kernels(name, backend):
    return generated.load(name, backend=backend)


def shared_folder(tmp_path_factory, name: str) -> Path:
    """A folder for the whole run, which pytest-xdist's workers share (each worker's basetemp is a
    folder of the run's): a package generated there once, under a lock, serves every worker,
    instead of one generation per worker.  Without xdist (-n 0, -p no:xdist), the session's own."""
    base = tmp_path_factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / name
    root.mkdir(exist_ok=True)
    return root


# KINEGEN_TEST_CPU=FILE: each test's CPU time (user + system, of its worker and of the processes
# that worker waited for: compilers, `kinegen generate`, the render's forked workers), one line
# per test appended to FILE, setup and teardown included.  On a machine shared with other work the
# wall-clock --durations say more about the load than about the test; this does not.
# `sort -rn FILE | head` lists the costliest tests; `awk '{s += $1} END {print s}' FILE`, the total.
def _cpu_seconds():
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


if os.environ.get("KINEGEN_TEST_CPU"):
    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        start = _cpu_seconds()
        yield
        with open(os.environ["KINEGEN_TEST_CPU"], "a", encoding="utf-8") as log:
            log.write(f"{_cpu_seconds() - start:.3f}\t{item.nodeid}\n")

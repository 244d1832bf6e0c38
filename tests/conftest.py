import concurrent.futures
import os

import pytest

import derivations
import generated
from codegen.generate import _joint_count, default_jobs

ROBOT_NAMES = list(derivations.ROBOTS)


def _derive(name):
    """Derive ``name`` into the disk cache (a worker of pytest_configure); the model stays there."""
    if name in derivations.KERNEL_SETS:
        derivations.load_kernel_set(name)
    else:
        derivations.load(name)


def pytest_configure(config):
    """Fill the derivation cache once, before pytest-xdist starts its workers.

    Each worker derives the models its tests use (the ``models`` fixture: all of
    them); from a cold cache (a fresh clone, CI) every worker would derive the Puma
    560 at the same time.  Here the controller derives each model once, in parallel
    processes, the most joints first, and the workers read them from the cache.  A
    warm cache makes this a few pickle loads.  Without xdist workers (or with the cache
    off) nothing is done here: the tests derive what they use, as before.
    """
    workers = getattr(config.option, "numprocesses", None)
    if hasattr(config, "workerinput") or not workers or os.environ.get("KINEGEN_NO_CACHE"):
        return
    names = sorted([*ROBOT_NAMES, *derivations.KERNEL_SETS], key=lambda n: -_joint_count(n))
    jobs = min(default_jobs(), len(names))
    if jobs <= 1:
        for name in names:
            _derive(name)
        return
    with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
        for done in [pool.submit(_derive, name) for name in names]:
            done.result()


@pytest.fixture(scope="session")
def models():
    """Every registered model, derived once (and cached on disk)."""
    return {name: derivations.load(name) for name in ROBOT_NAMES}


def kernels(name, backend):
    return generated.load(name, backend=backend)

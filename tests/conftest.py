import importlib

import pytest

import derivations

ROBOT_NAMES = list(derivations.ROBOTS)


@pytest.fixture(scope="session")
def models():
    """Every registered model, derived once (and cached on disk)."""
    return {name: derivations.load(name) for name in ROBOT_NAMES}


def kernels(name, backend):
    module = "numpy_kernels" if backend == "numpy" else "c_kernels"
    return importlib.import_module(f"generated.{name}.{module}")

import pytest

import derivations
import generated

ROBOT_NAMES = list(derivations.ROBOTS)


@pytest.fixture(scope="session")
def models():
    """Every registered model, derived once (and cached on disk)."""
    return {name: derivations.load(name) for name in ROBOT_NAMES}


def kernels(name, backend):
    return generated.load(name, backend=backend)

"""Degenerate parameters (a zero length, +-1e-300) through both backends (issue #17).

Each robot's ik at a few targets, with each parameter in turn at 0 and at +-1e-300: the numpy
kernels must answer as the C does (no ZeroDivisionError from a Python float), with the same
valid flags and, where valid, the same joint values.  The expected behaviour is the C's
IEEE arithmetic: a division by zero gives inf or NaN, and the branch is reported not valid.
"""
import numpy as np
import pytest

import generated

TARGETS = {
    "planar_2r": [[0.3, 0.2], [0.9, -0.1], [0.0, 0.0]],
    "planar_3r": [[0.3, 0.2, 0.1], [0.9, -0.1, 2.0], [0.0, 0.0, 0.0]],
    "adept_three": [[0.3, 0.2, 0.1, 0.2], [0.6, -0.3, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]],
    "scorbot_er7": [[0.75, 0.0, 0.3], [0.3, 0.3, 0.6], [0.0, 0.0, 0.0]],
}


@pytest.mark.parametrize("name", list(TARGETS))
def test_numpy_and_c_agree_on_degenerate_parameters(name):
    kn, kc = generated.load(name, backend="numpy"), generated.load(name, backend="c")
    x = np.array(TARGETS[name], dtype=float)
    tried = 0
    for p in kn.PARAMS:
        for value in (0.0, 1e-300, -1e-300):
            Qn, valid_n = kn.ik(x, **{p: value})
            Qc, valid_c = kc.ik(x, **{p: value})
            np.testing.assert_array_equal(valid_n, valid_c, err_msg=f"{name} {p}={value}")
            both = valid_n[..., None] & np.isfinite(Qn) & np.isfinite(Qc)
            difference = np.abs(np.where(both, Qn - Qc, 0.0))
            difference = np.minimum(difference, np.abs(difference - 2 * np.pi))  # +-pi wrap either side
            assert difference.max() < 1e-9, (name, p, value)
            tried += 1
    assert tried == 3 * len(kn.PARAMS)

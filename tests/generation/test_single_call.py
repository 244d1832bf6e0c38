"""The C backend's one-point path of ik with a free joint (issue #26, item 6): a single pose with the
free joint's value as a float64 array of shape (1,) goes to the C one-point entry, which must refuse
what the general path refuses (a value past 1e4: free = 1e16 marked wrong branches valid).

The package is the zoo's KUKA LWR 4, generated once per session (tests/test_zoo.py); every answer
is held to the test's own forward kinematics.
"""
from __future__ import annotations

import numpy as np
import pytest

from test_zoo import ARMS, configurations, fk, generated_package, generated_root  # noqa: F401  (a fixture)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_one_pose_with_a_huge_free_value_is_refused_on_every_path(backend, generated_root):
    arm = ARMS["kuka_lwr4"]
    k = generated_package("kuka_lwr4", generated_root).load(backend)
    q = configurations(arm, 3)
    T = fk(arm, q)
    for free in (np.array([1e16]), np.array([-2e4]), 1e16, np.array([[1e16]])):
        with pytest.raises(ValueError, match="beyond 10000"):
            k.ik(T[0], free=free)
    # within the bound, one pose at a time as a 4 x 4 and with free of shape (1,): the free joint comes
    # back as given, and every valid branch reaches the pose
    for i in range(3):
        Q, valid = k.ik(T[i], free=q[i, 2:3].copy())
        assert Q.shape == (8, 7) and valid.any()
        assert (Q[:, 2] == q[i, 2]).all()
        assert np.abs(fk(arm, Q[valid]) - T[i]).max() < 1e-9

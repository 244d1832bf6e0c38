"""The numeric inverse kinematics every package has (issue #26): ik_numeric(x, q0), and ik from
fixed seeds where no closed form exists; IK_METHOD; the names of a URDF's joints and links.

Every answer is held to the test's own forward kinematics (tests/test_zoo.py's DH product,
written from the description files), not to the package's fk.  The packages are the zoo's,
generated once per session and shared with tests/test_zoo.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from test_urdf import package as urdf_package
from test_urdf import urdf_root  # noqa: F401  (a fixture)
from test_zoo import ARMS, configurations, fk, generated_package, generated_root  # noqa: F401  (a fixture)

RESIDUAL = 1e-12   # what ik_numeric converges to (m and rad)
REACHED = 1e-9     # an answer's pose against the test's own fk, max-norm over the 4x4 entries


def wrapped(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", ["kinova_jaco", "franka_panda", "kuka_kr5"])
def test_ik_numeric_converges_from_a_seed_near_a_solution(name, backend, generated_root):
    """From seeds within 0.1 rad of random configurations within the limits: converged on at least
    99.9 %, every converged answer's pose equal to the target (the test's own fk) to 1e-9, and the
    answer the seed leads to (for the redundant Panda too: within 0.2 rad of the generating one)."""
    arm = ARMS[name]
    k = generated_package(name, generated_root).load(backend)
    q = configurations(arm, 1000)
    rng = np.random.default_rng(26)
    q0 = q + rng.uniform(-0.1, 0.1, q.shape)
    target = fk(arm, q)
    found, converged = k.ik_numeric(target, q0)
    assert found.shape == q.shape and converged.shape == (1000,)
    assert converged.mean() >= 0.999, converged.mean()
    assert np.abs(fk(arm, found[converged]) - target[converged]).max() < REACHED
    assert np.abs(wrapped(found - q)[converged]).max() < 0.25
    low = np.array([lim[0] if lim else -np.inf for lim in arm.limits])
    high = np.array([lim[1] if lim else np.inf for lim in arm.limits])
    assert ((found >= low) & (found <= high)).all()  # joints kept within their limits
    one, ok = k.ik_numeric(target[0], q0[0])  # the single call: shape (n,), ()
    assert one.shape == (arm.n,) and ok.shape == () and bool(ok)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_ik_of_an_arm_without_closed_form_finds_solutions_from_its_seeds(backend, generated_root):
    """The Kinova Jaco (a general 6R): ik runs ik_numeric from 16 fixed seeds.  On 200 random
    reachable poses: every valid answer reaches its pose, distinct answers are distinct
    configurations, and at least one answer exists on at least 99 % of the poses."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    assert k.IK_METHOD == "numeric" and len(k.BRANCHES) == 16
    q = configurations(arm, 200)
    target = fk(arm, q)
    Q, valid = k.ik(target)
    assert Q.shape == (200, 16, 6) and valid.shape == (200, 16)
    reached = np.abs(fk(arm, Q) - target[:, None]).max(axis=(-2, -1))
    assert reached[valid].max() < REACHED
    assert valid.any(axis=1).mean() >= 0.99
    for i in range(200):  # no answer twice
        answers = Q[i][valid[i]]
        gaps = np.abs(wrapped(answers[:, None, :] - answers[None, :, :])).max(axis=-1)
        assert (gaps + np.eye(len(answers)) * 9 > 1e-6).all()
    assert not k.ik(np.full((1, 4, 4), np.nan))[1].any()  # a NaN target: nothing valid, no error


def test_ik_method_names_how_each_package_solves(generated_root):
    import generated
    assert generated.load("puma560").IK_METHOD == "closed form (the paper's)"
    assert generated_package("kuka_kr5", generated_root).IK_METHOD == "spherical wrist"
    assert generated_package("kuka_lwr4", generated_root).IK_METHOD == "spherical wrist, joint 3 free"
    assert generated_package("kinova_jaco", generated_root).IK_METHOD == "numeric"


def test_a_urdf_package_names_its_joints_and_frames_as_the_file_does(urdf_root):
    """JOINTS are the URDF's joint names and FRAME_NAMES the link of each frame; joint_vector puts a
    joint_states message's positions (any order, other joints among them) into q's order."""
    k = urdf_package("ur5", urdf_root)
    assert k.JOINTS == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                        "wrist_2_joint", "wrist_3_joint")
    assert k.FRAME_NAMES == ("base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                             "wrist_2_link", "tool0")
    names = ["gripper_finger", *reversed(k.JOINTS)]
    positions = np.array([[0.05, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1], [0.0, 1.6, 1.5, 1.4, 1.3, 1.2, 1.1]])
    np.testing.assert_array_equal(k.joint_vector(names, positions), positions[:, :0:-1])
    with pytest.raises(ValueError, match="no position for elbow_joint"):
        k.joint_vector([n for n in names if n != "elbow_joint"], positions[:, :-1])
    assert k.frames(np.zeros(6)).shape[0] == len(k.FRAME_NAMES)
    assert math.isclose(k.load("c").jacobian_tool(np.full(6, 0.3))[0, 0], k.jacobian_tool(np.full(6, 0.3))[0, 0],
                        rel_tol=1e-12, abs_tol=1e-15)

"""The numeric inverse kinematics every package has (issue #26): ik_numeric(x, q0), and ik from
fixed seeds where no closed form exists; IK_METHOD; the names of a URDF's joints and links.

Every answer is held to the test's own forward kinematics (tests/test_zoo.py's DH product,
written from the description files), not to the package's fk.  The packages are the zoo's,
generated once per session and shared with tests/test_zoo.py.
"""
from __future__ import annotations

import math
from pathlib import Path

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
    """The Franka Panda (seven joints, no six-joint remainder in a family): ik runs ik_numeric from
    16 fixed seeds.  On 200 random reachable poses: every valid answer reaches its pose, distinct
    answers are distinct configurations, and at least one answer exists on at least 99 % of the
    poses.  (The Kinova Jaco, a general 6R, has every real solution instead: test_general_6r.py.)"""
    arm = ARMS["franka_panda"]
    k = generated_package("franka_panda", generated_root).load(backend)
    assert k.IK_METHOD == "numeric" and len(k.BRANCHES) == 16
    q = configurations(arm, 200)
    target = fk(arm, q)
    Q, valid = k.ik(target)
    assert Q.shape == (200, 16, 7) and valid.shape == (200, 16)
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
    assert generated_package("kinova_jaco", generated_root).IK_METHOD == "general 6R"
    assert generated_package("franka_panda", generated_root).IK_METHOD == "numeric"


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


# --------------------------------------------------------------------------- the solver in C (issue #26, item 4)

def _limits(arm):
    low = np.array([lim[0] if lim else -np.inf for lim in arm.limits])
    high = np.array([lim[1] if lim else np.inf for lim in arm.limits])
    return low, high


@pytest.mark.parametrize("name", ["franka_panda", "kinova_jaco"])
def test_c_ik_numeric_reaches_the_target_and_agrees_with_numpy(name, generated_root):
    """300 targets from random configurations within the limits, seeds within 0.1 rad: the C solver
    converges on all (or all but one), each converged answer's pose equal to the target's by the
    test's own fk to 1e-10; the numpy solver (the same steps, in numpy) converges on the same items to
    the same answer; and C's ik_numeric never calls the numpy solver."""
    arm = ARMS[name]
    package = generated_package(name, generated_root)
    c = package.load("c")
    q = configurations(arm, 300)
    q0 = q + np.random.default_rng(261).uniform(-0.1, 0.1, q.shape)
    target = fk(arm, q)
    found, converged = c.ik_numeric(target, q0)
    assert converged.sum() >= 299, converged.sum()
    assert np.abs(fk(arm, found[converged]) - target[converged]).max() < 1e-10
    low, high = _limits(arm)
    assert ((found >= low) & (found <= high)).all()
    numpy_found, numpy_converged = package.ik_numeric(target, q0)
    assert (numpy_converged != converged).sum() <= 1
    both = numpy_converged & converged
    assert np.abs(numpy_found[both] - found[both]).max() < 1e-8  # the same solution, the seed's
    # the 12-vector of each pose gives the same answers as its 4 x 4, and one pose at a time as a batch
    vector = np.concatenate([target[:, :3, 3], target[:, :3, :3].reshape(-1, 9)], axis=-1)
    np.testing.assert_array_equal(c.ik_numeric(vector, q0)[0], found)
    for i in range(5):
        one, ok = c.ik_numeric(target[i], q0[i])
        np.testing.assert_array_equal(one, found[i])
        assert ok.shape == () and bool(ok) == converged[i]


def test_c_ik_numeric_and_the_seeded_ik_do_not_use_the_numpy_solver(generated_root, monkeypatch):
    """On the C backend both ik_numeric and the Panda's ik from seeds solve in C: with the numpy solver
    made to fail, they still answer, and their answers reach the targets (the test's own fk)."""
    arm = ARMS["franka_panda"]
    c = generated_package("franka_panda", generated_root).load("c")

    def refuse(*args, **kwargs):
        raise AssertionError("the numpy solver was called")
    monkeypatch.setattr(c._runtime, "solve_numeric", refuse)
    q = configurations(arm, 20)
    target = fk(arm, q)
    found, converged = c.ik_numeric(target, q + 0.05)
    assert converged.all() and np.abs(fk(arm, found) - target).max() < 1e-10
    Q, valid = c.ik(target)
    assert valid.any(axis=1).all()
    assert np.abs(fk(arm, Q) - target[:, None])[valid].max() < 1e-10


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_ik_numeric_holds_the_joints_within_their_limits(backend, generated_root):
    """The Panda with joint 4 at a limit and the seed beyond it (the step would push it further): every
    answer within the limits; the targets are reached (the seed's joint 4 clipped back to its limit is
    where the generating configuration has it); and a target that needs joint 4 beyond its limit (the
    generating configuration 0.3 rad past it, the seed beside it) is never reported converged with
    joint 4 past the limit."""
    arm = ARMS["franka_panda"]
    k = generated_package("franka_panda", generated_root).load(backend)
    low, high = _limits(arm)
    rng = np.random.default_rng(262)
    q = configurations(arm, 200)
    q[:100, 3], q[100:, 3] = high[3], low[3]
    q0 = q + rng.uniform(-0.05, 0.05, q.shape)
    q0[:100, 3], q0[100:, 3] = high[3] + 0.1, low[3] - 0.1
    target = fk(arm, q)
    found, converged = k.ik_numeric(target, q0)
    assert ((found >= low) & (found <= high)).all()
    assert converged.mean() >= 0.99
    assert np.abs(fk(arm, found[converged]) - target[converged]).max() < 1e-10
    beyond = q.copy()
    beyond[:, 3] = high[3] + 0.3
    found, converged = k.ik_numeric(fk(arm, beyond), beyond)
    assert ((found >= low) & (found <= high)).all()
    reached = np.abs(fk(arm, found) - fk(arm, beyond)).max(axis=(-2, -1))
    assert (reached[converged] < 1e-10).all()  # converged only where another configuration reaches it


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_ik_numeric_reports_unreachable_and_nan_targets_as_not_converged(backend, generated_root):
    """A pose 10 times as far from the base as a reachable one, and a pose with a NaN: converged False
    and q finite (never a NaN answer); a rotation that is not orthonormal, and a seed with a NaN, are
    refused with a ValueError."""
    arm = ARMS["kinova_jaco"]
    k = generated_package("kinova_jaco", generated_root).load(backend)
    q = configurations(arm, 50)
    far = fk(arm, q)
    far[:, :3, 3] *= 10.0
    found, converged = k.ik_numeric(far, q)
    assert not converged.any() and np.isfinite(found).all()
    nan = fk(arm, q[:3])
    nan[0, 0, 3], nan[1, 1, 1], nan[2] = np.nan, np.inf, np.nan
    found, converged = k.ik_numeric(nan, q[:3])
    assert not converged.any() and np.isfinite(found).all()
    skewed = fk(arm, q[:2])
    skewed[1, :3, :3] *= 1.1
    with pytest.raises(ValueError, match="not a rigid transform"):
        k.ik_numeric(skewed, q[:2])
    with pytest.raises(ValueError, match="not a rigid transform"):
        k.ik_numeric(skewed[1], q[1])
    with pytest.raises(ValueError, match="q0 contains NaN or inf"):
        k.ik_numeric(fk(arm, q[0]), np.full(6, np.nan))
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 6\)"):
        k.ik_numeric(fk(arm, q[0]), np.zeros(5))


def test_the_c_entry_points_of_ik_numeric(generated_root):
    """<robot>_ik_numeric returns 1 (converged), 0 (not), or -1 for a pose that is not a rigid
    transform; <robot>_ik_numeric_batch the number converged, or -1 if it refused any item; the
    header declares both, with the tolerance and the iteration limit."""
    arm = ARMS["kinova_jaco"]
    package = generated_package("kinova_jaco", generated_root)
    c = package.load("c")
    header = (Path(package.__path__[0]) / "kinova_jaco.h").read_text()
    assert "#define KINOVA_JACO_IK_NUMERIC_TOLERANCE 1e-12" in header
    assert "int kinova_jaco_ik_numeric(const double *x, const double *q0" in header
    assert "long kinova_jaco_ik_numeric_batch(size_t count, const double *x, const double *q0" in header
    ffi, lib = c._ffi, c._lib
    q = configurations(arm, 3)
    x = np.concatenate([fk(arm, q)[:, :3, 3], fk(arm, q)[:, :3, :3].reshape(-1, 9)], axis=-1)
    x[1, :3] *= 10.0  # out of reach
    q0 = np.ascontiguousarray(q + 0.05)
    out, flags = np.empty((3, 6)), np.empty(3, dtype=np.intc)
    doubles, ints = ffi.typeof("double[]"), ffi.typeof("int[]")

    def single(i):
        return lib.kinova_jaco_ik_numeric(ffi.from_buffer(doubles, x[i]), ffi.from_buffer(doubles, q0[i]), ffi.NULL,
                                          ffi.from_buffer(doubles, out[i]), ffi.from_buffer(ints, flags[i:i + 1]))
    assert [single(i) for i in range(3)] == [1, 0, 1] and flags.tolist() == [1, 0, 1]
    assert np.abs(fk(arm, out[[0, 2]]) - fk(arm, q[[0, 2]])).max() < 1e-10
    batch = lib.kinova_jaco_ik_numeric_batch(3, ffi.from_buffer(doubles, x), ffi.from_buffer(doubles, q0), ffi.NULL,
                                             ffi.from_buffer(doubles, out), ffi.from_buffer(ints, flags))
    assert batch == 2
    x[2, 3:] *= 2.0  # a rotation that is not orthonormal
    assert single(2) == -1 and flags[2] == 0
    assert lib.kinova_jaco_ik_numeric_batch(3, ffi.from_buffer(doubles, x), ffi.from_buffer(doubles, q0), ffi.NULL,
                                            ffi.from_buffer(doubles, out), ffi.from_buffer(ints, flags)) == -1


# --------------------------------------------------------------------------- the single call (issue #26, item 6)

def test_a_single_4x4_pose_takes_the_c_one_point_path(generated_root):
    """ik of one pose given as a 4 x 4 goes straight to the C one-point entry (as the 12-vector does):
    the same answers, bit for bit, as the 12-vector's; a 4 x 4 with a wrong last row, or another layout
    (Fortran order), goes the general path, which names the problem or answers the same."""
    arm = ARMS["ur5"]
    c = generated_package("ur5", generated_root).load("c")
    q = configurations(arm, 5)
    for T in fk(arm, q):
        vector = np.concatenate([T[:3, 3], T[:3, :3].ravel()])
        assert c._point.ik(T) is not None  # taken in C, not by the general path
        Q, valid = c.ik(T)
        Q12, valid12 = c.ik(vector)
        np.testing.assert_array_equal(Q, Q12)
        np.testing.assert_array_equal(valid, valid12)
        assert valid.sum() >= 1 and np.abs(fk(arm, Q[valid]) - T).max() < 1e-9
        np.testing.assert_array_equal(c.ik(np.asfortranarray(T))[0], Q)
    wrong = fk(arm, q[0])
    wrong[3, 0] = 0.5
    assert c._point.ik(wrong) is None
    with pytest.raises(ValueError, match="not a homogeneous transform"):
        c.ik(wrong)

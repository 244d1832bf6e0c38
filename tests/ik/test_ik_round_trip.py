"""Inverse kinematics against forward kinematics, 10,000 configurations per robot and backend.

In the style of IKFast's robot tests, but stricter: every configuration's target
is reachable by construction (it is the task of that configuration), a quarter
of the configurations take their joints from the degenerate values 0, +-pi/2
and pi, and three rates must all be zero:

* wrong answers: a valid branch whose forward kinematics misses the target by
  more than 1e-9 (max norm over the task coordinates; phi modulo 2 pi);
* no-solution answers: a target (reachable) with no valid branch;
* missing solutions: the configuration that produced the target is not among
  the valid branches (modulo 2 pi for revolute joints, within JOINT_TOLERANCE),
  up to what a singular configuration leaves free.

Run as a script (``python tests/ik/test_ik_round_trip.py``) to print the table.
"""
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import ROBOT_NAMES, kernels  # noqa: E402

COUNT = 10_000
FK_TOLERANCE = 1e-9
# Joint agreement for "the configuration is among the branches".  At a double
# root (an arm stretched or folded, a wrist centre straight above the shoulder)
# an acos argument at +-1 turns a rounding error eps into an angle error near
# sqrt(eps) ~ 1e-8, which moves the tool by far less (the residual is second order).
JOINT_TOLERANCE = 1e-6
DEGENERATE = np.array([0.0, np.pi / 2, -np.pi / 2, np.pi])
WRIST_SINGULAR = 1e-12


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def draw_configurations(name, k, count, rng):
    """``count`` configurations: three quarters uniform, a quarter from DEGENERATE."""
    n = len(k.JOINTS)
    q = np.empty((count, n))
    degenerate = np.arange(count) >= count - count // 4
    for i, (kind, limits) in enumerate(zip(k.JOINT_TYPES, k.LIMITS)):
        if kind == "R":
            q[:, i] = rng.uniform(-np.pi, np.pi, count)
            q[degenerate, i] = rng.choice(DEGENERATE, degenerate.sum())
        else:
            low, high = limits if limits is not None else (-1.0, 1.0)
            q[:, i] = rng.uniform(low, high, count)
            q[degenerate, i] = rng.choice([low, (low + high) / 2, high, 0.0], degenerate.sum())
    if name == "avr3000":  # Sotirov Eq. 8: the frog leg's q2 spans [0, 2 pi] (R from 2a through 0 to -2a)
        q[:, 1] = rng.uniform(0.0, 2 * np.pi, count)
        q[degenerate, 1] = rng.choice([0.0, np.pi / 2, np.pi, 3 * np.pi / 2, 2 * np.pi], degenerate.sum())
    if name == "scorbot_er7":  # the gripper horizontal (Eq. 3.10); theta5 is not part of the task
        q[:, 3] = wrap(-(q[:, 1] + q[:, 2]))
        q[:, 4] = 0.0
    return q


def task_error(k, Q, x):
    """max-norm distance of task(Q) (..., k, m) from x (..., m), phi modulo 2 pi."""
    difference = k.task(Q) - x[..., None, :]
    for i, name in enumerate(k.TASK):
        if name == "phi":
            difference[..., i] = wrap(difference[..., i])
    return np.abs(difference).max(axis=-1)


def joint_distance(name, k, Q, q):
    """Distance of each branch Q (count, b, n) from q (count, n), up to what q leaves free."""
    difference = Q - q[:, None, :]
    for i, kind in enumerate(k.JOINT_TYPES):
        if kind == "R":
            difference[..., i] = wrap(difference[..., i])
    difference = np.abs(difference)
    if name == "scorbot_er7":
        return difference[..., :4].max(axis=-1)  # theta5 is free (the position task leaves it)
    if name == "planar_rp":
        # d2 = 0 puts the tool on the joint axis: theta1 is free there.
        on_axis = np.abs(q[:, 1]) == 0.0
        difference[on_axis, :, 0] = 0.0
    if name == "puma560":
        # theta5 = 0 or pi lines up axes 4 and 6: only theta4 + theta6 (theta5 = 0)
        # or theta4 - theta6 (theta5 = pi) is fixed by the pose.
        singular = np.abs(np.sin(q[:, 4])) <= WRIST_SINGULAR
        combined = np.where(np.cos(q[:, 4]) > 0, q[:, 3] + q[:, 5], q[:, 3] - q[:, 5])
        branch_combined = np.where(np.cos(q[:, 4])[:, None] > 0, Q[..., 3] + Q[..., 5], Q[..., 3] - Q[..., 5])
        free = np.abs(wrap(branch_combined - combined[:, None]))
        difference[singular, :, 3] = free[singular]
        difference[singular, :, 5] = 0.0
    return difference.max(axis=-1)


def round_trip(name, backend, count=COUNT, seed=2024):
    k = kernels(name, backend)
    rng = np.random.default_rng(seed)
    q = draw_configurations(name, k, count, rng)
    x = k.task(q)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the kernel must not warn either
        Q, valid = k.ik(x)
    revolute = [i for i, kind in enumerate(k.JOINT_TYPES) if kind == "R"]
    if name == "avr3000":
        revolute.remove(1)  # q2 in [0, 2 pi] by Eq. 8, not wrapped
    outside_turn = (np.abs(Q[..., revolute]) > np.pi).any(axis=-1) & valid  # not in (-pi, pi] as doubles
    error = np.where(valid, task_error(k, Q, x), 0.0)
    distance = np.where(valid, joint_distance(name, k, Q, q), np.inf).min(axis=-1)
    return {
        "robot": name, "backend": backend, "configurations": count,
        "degenerate": count // 4,
        "valid branches": int(valid.sum()),
        "wrong": int((error > FK_TOLERANCE).sum()),
        "no solution": int((~valid.any(axis=-1)).sum()),
        "missing": int((distance > JOINT_TOLERANCE).sum()),
        "not wrapped": int(outside_turn.sum()),
        "max fk error": float(error.max()),
        "max joint distance": float(distance.max()),
        "in limits": float(k.within_limits(Q)[valid].mean()),
    }


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_every_configuration_comes_back_and_every_answer_is_right(name, backend):
    stats = round_trip(name, backend)
    assert stats["wrong"] == 0, stats
    assert stats["no solution"] == 0, stats
    assert stats["missing"] == 0, stats
    assert stats["not wrapped"] == 0, stats
    assert stats["max fk error"] < FK_TOLERANCE
    assert stats["valid branches"] >= COUNT


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_numpy_and_c_agree_branch_by_branch(name):
    kn, kc = kernels(name, "numpy"), kernels(name, "c")
    rng = np.random.default_rng(7)
    x = kn.task(draw_configurations(name, kn, 2000, rng))
    Qn, valid_n = kn.ik(x)
    Qc, valid_c = kc.ik(x)
    np.testing.assert_array_equal(valid_n, valid_c)
    difference = np.abs(Qn - Qc)
    # angles near +-pi may land on either end of the turn after wrapping
    difference = np.where(valid_n[..., None], np.minimum(difference, np.abs(difference - 2 * np.pi)), 0.0)
    # The backends round differently (the built C takes sin and cos from libmvec, numpy
    # from a tangent of the half angle), by a few ulps.  At a double root (see
    # JOINT_TOLERANCE) that becomes up to sqrt(eps) ~ 1e-8 in the joints, with both
    # answers still on the target; everywhere else the two agree to 1e-12.
    apart = difference.max(axis=-1) > 1e-12
    assert difference.max() < JOINT_TOLERANCE
    assert task_error(kn, Qn, x)[apart].max(initial=0.0) < FK_TOLERANCE
    assert task_error(kc, Qc, x)[apart].max(initial=0.0) < FK_TOLERANCE
    assert apart.sum() <= 0.01 * valid_n.sum()  # rare: the degenerate draws at a workspace boundary


def main():
    columns = ["robot", "backend", "configurations", "degenerate", "valid branches", "wrong", "no solution",
               "missing", "not wrapped", "max fk error", "max joint distance", "in limits"]
    rows = [round_trip(name, backend) for name in ROBOT_NAMES for backend in ("numpy", "c")]
    cells = [[f"{r[c]:.1e}" if isinstance(r[c], float) and c != "in limits" else
              (f"{r[c]:.2f}" if c == "in limits" else str(r[c])) for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(columns)]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    for row in cells:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths)))
    return 0 if all(r["wrong"] == r["no solution"] == r["missing"] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())

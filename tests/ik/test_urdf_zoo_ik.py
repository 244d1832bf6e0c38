"""Inverse kinematics of the real URDF files as shipped (tests/data/urdf/zoo/, tests/urdf_zoo.py;
issue #26: every arm of the URDF tests has ``ik``).

* Which method each arm's package solves by (its ``IK_METHOD``, from the model ``kinegen generate``
  renders): a closed-form family where the file's axes have one, else the seeded numeric solver;
  and for the numeric ones, the structure the model says they lack.
* Every closed-form arm: each branch evaluated from its SymPy steps (``test_ik_short_chains.evaluate_steps``,
  what the kernels print, each distinct step compiled once) at the poses of configurations within
  the joint limits (1,000 random and 1,000 degenerate for the PR2's arm, 150 and 50 for the others),
  the poses and the answers both taken through ``urdf_zoo.XmlChain`` (batched: ``xml_walk``; the XML
  read with ElementTree, with the
  angles and axes the model reported snapping; nothing of the project's).  Counts as test_zoo's:
  wrong (a valid branch off its pose by more than 1e-9 in an entry of the 4 x 4), no solution, and,
  on the random configurations, missing (the generating configuration not among the valid answers,
  1e-6 rad per joint).  A seven-joint arm holds its free joint at the configuration's value.

* The general 6R from a URDF chain (this IRB 140 file: axes 2 and 3 parallel, 3, 4 and 5 meeting
  in turn, axis 6 two centimetres off axis 5), generated whole by the CLI: every real solution in
  both backends, counted against XmlChain as above.

The models are those of test_urdf_zoo (``derivations.load`` snapped, cached on disk).
"""
import functools
import itertools
import re
import sys
import zlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import derivations  # noqa: E402
from codegen.generate import ik_method  # noqa: E402
from conftest import shared_folder  # noqa: E402
from test_ik_short_chains import evaluate_steps, xml_walk  # noqa: E402
from test_urdf_zoo import generated_package, snapped_numbers  # noqa: E402
from urdf_zoo import ZOO, XmlChain  # noqa: E402

# IK_METHOD of each arm's package.  The numeric ones: 7 joints with no held joint leaving a family
# (iCub, Baxter: their wrists' axes do not meet, nor their shoulders'), the SO-101 and AL5D (5 and 4
# joints, which cannot reach a whole pose: their own tasks are in test_ik_short_chains.py), and
# and this IRB 140 file, whose joint_6 origin sits 2 cm off axis 5 (a wrist that is not spherical):
# every real solution of the general 6R instead.
METHOD = {
    "xarm7": "reversed spherical wrist, joint 7 free", "so101": "numeric", "z1": "three parallel", "kinova_j2s6s200": "spherical wrist",
    "icub_left_arm": "numeric", "pr2_right_arm": "spherical wrist, joint 1 free",
    "romeo_left_arm": "spherical wrist, joint 3 free", "baxter_left_arm": "numeric", "ur3": "three parallel",
    "kr210": "spherical wrist", "kr16": "spherical wrist", "irb140": "general 6R", "al5d": "numeric",
    "panda": "reversed spherical wrist, joint 7 free", "wxai": "three parallel",
}
LACKS = {
    "icub_left_arm": "7 joints: no free joint leaves a covered six-joint arm",
    "baxter_left_arm": "7 joints: no free joint leaves a covered six-joint arm",
    "so101": "the task pose has 6 degrees of freedom and the arm 5 joints",
    "al5d": "the task pose has 6 degrees of freedom and the arm 4 joints",
    "irb140": "no three consecutive axes meet in a point (axes 4, 5, 6)",
}
CLOSED = [name for name, method in METHOD.items() if method not in ("numeric", "general 6R")]
RANDOM, DEGENERATE = 150, 50
# More for the PR2's arm held at joint 1 (the only held joint its axes allow: held at joint 2, axes
# 1 and 3 meet at 0.1 tan q2): with its elbow stretched (q4 = 0, its upper limit) the wrist centre
# lies on the upper arm's roll axis, subproblem 4's P and Q are rounding and the roll is free
# (subproblems.FREE_ANGLE); 19 of 50 degenerate configurations had no valid branch before that case.
COUNTS = {"pr2_right_arm": (1000, 1000)}
FK_TOLERANCE = 1e-9
JOINT_TOLERANCE = 1e-6


def model_and_chain(name):
    arm = ZOO[name]
    model = derivations.load(arm.path, base=arm.base, tip=arm.tip, snap=True)
    chain = XmlChain(arm.path, arm.base, arm.tip)
    rpy, axes = snapped_numbers(model.notes.get("snapped", ""), chain)
    return model, XmlChain(arm.path, arm.base, arm.tip, rpy=rpy, axes=axes)


def test_the_table_covers_the_zoo():
    assert set(METHOD) == set(ZOO)


@pytest.mark.parametrize("name", list(ZOO))
def test_each_arm_solves_by_its_method(name):
    model, _ = model_and_chain(name)
    # plain values only in the asserts: pytest's repr of a failing comparison of the branches
    # themselves prints their whole expressions (minutes on the 7-joint arms)
    method, count, plan, lacks = ik_method(model), len(model.ik), (model.ik_plan or [""])[0], model.ik_unsupported
    assert method == METHOD[name]
    if name in LACKS:   # (the general 6R's answers are numeric: no closed-form branches either)
        assert count == 0 and LACKS[name] in lacks, lacks
    else:
        assert count == 8 and plan == f"family: {METHOD[name]}", plan


def floated(branch):
    """The branch with its exact irrational constants as 30-digit floats: the steps of a file's
    15-digit decimals hold such numbers as sqrt(3519564161475607455144369219509) / 5e14, which
    numpy cannot take the root of (the kernels print them as doubles)."""
    def numbers(expr):
        return expr.xreplace({p: p.evalf(30) for p in expr.atoms(sp.Pow) if p.is_number})
    return SimpleNamespace(steps=[(s, numbers(e)) for s, e in branch.steps],
                           step_condition=numbers(branch.step_condition))


def configurations(chain: XmlChain, seed: int, random: int = RANDOM, degenerate: int = DEGENERATE) -> np.ndarray:
    """``random`` configurations within the limits, then ``degenerate`` with every joint at 0,
    +-pi/2 or pi where its limits allow (else at the nearer limit)."""
    rng = np.random.default_rng(seed)
    low, high = np.array(chain.limits).T
    special = rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi], (degenerate, chain.n))
    return np.vstack([chain.configurations(random, seed), np.clip(special, low, high)])


def pose_vector(T: np.ndarray) -> np.ndarray:
    return np.concatenate([T[..., :3, 3], T[..., :3, :3].reshape(T.shape[:-2] + (9,))], axis=-1)


@pytest.mark.parametrize("name", CLOSED)
def test_closed_form_branches_reach_the_xml_pose(name):
    model, chain = model_and_chain(name)
    random, degenerate = COUNTS.get(name, (RANDOM, DEGENERATE))
    q = configurations(chain, zlib.crc32(name.encode()), random, degenerate)
    T = xml_walk(chain, q)[0]
    x = pose_vector(T)
    free = re.search(r"joint (\d) free", METHOD[name])
    extra = {model.q[int(free.group(1)) - 1]: q[:, int(free.group(1)) - 1]} if free else None
    wrong, found, solved = 0, np.zeros(len(q), bool), np.zeros(len(q), bool)
    for branch in model.ik:
        Q, valid = evaluate_steps(model, floated(branch), x, extra)
        wrong += int((valid & (np.abs(xml_walk(chain, Q)[0] - T).max(axis=(-2, -1)) > FK_TOLERANCE)).sum())
        difference = np.abs((Q - q + np.pi) % (2 * np.pi) - np.pi).max(axis=-1)
        found |= valid & (difference <= JOINT_TOLERANCE)
        solved |= valid
    counts = {"wrong": wrong, "no solution": int((~solved).sum()), "missing": int((~found[:random]).sum())}
    assert counts == dict.fromkeys(counts, 0), counts



def wrong_answers(chain: XmlChain, Q: np.ndarray, valid: np.ndarray, T: np.ndarray) -> int:
    """How many valid answers Q[i, b] the XML chain's walk (xml_walk, the batched XmlChain.walk:
    test_ik_short_chains) takes off their pose T[i]: all of them in one batch, where a walk per
    answer was most of the test (some 30,000 answers at the 4,096 degenerate poses)."""
    poses, _ = np.nonzero(valid)
    return int((np.abs(xml_walk(chain, Q[valid])[0] - T[poses]).max(axis=(-2, -1)) > FK_TOLERANCE).sum())


@pytest.fixture(scope="session")
def irb140_package(tmp_path_factory):
    """The IRB 140 file's arm generated whole by the CLI in a process of its own (test_urdf_zoo's),
    once per run: pytest-xdist's workers share it."""
    return generated_package("irb140", shared_folder(tmp_path_factory, "urdf_general_6r"))[0]


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_the_general_6r_of_a_urdf_chain_finds_every_solution(backend, irb140_package):
    """Random configurations over the whole turn (no limits: every real solution is asked for) and
    degenerate ones (every joint at 0, +-pi/2 or pi): no valid answer off its pose, every pose
    solved, the generating configuration found at every random one, at most 10 % missed at the
    degenerate ones (singular configurations with a continuum of answers, the C's double roots)."""
    _, chain = model_and_chain("irb140")
    k = irb140_package.load(backend)
    assert k.IK_METHOD == "general 6R"
    rng = np.random.default_rng(140)
    count = 200
    q = np.vstack([rng.uniform(-np.pi, np.pi, (count, 6)),
                   rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi], (count // 2, 6))])
    T = xml_walk(chain, q)[0]
    Q, valid = k.ik(T)
    wrong = wrong_answers(chain, Q, valid, T)
    difference = np.abs((Q - q[:, None, :] + np.pi) % (2 * np.pi) - np.pi).max(axis=-1)
    missing = ~(valid & (difference <= JOINT_TOLERANCE)).any(axis=-1)
    assert (wrong, int((~valid.any(axis=-1)).sum()), int(missing[:count].sum())) == (0, 0, 0)
    assert missing[count:].sum() <= 0.1 * (count // 2)
    assert valid[:count].sum(axis=-1).mean() > 4   # several real solutions per pose, not one



def every_degenerate_configuration(n: int = 6) -> np.ndarray:
    """All 4^n configurations with every joint at 0, +pi/2, -pi/2 or pi (4,096 for six joints)."""
    return np.array(list(itertools.product([0.0, np.pi / 2, -np.pi / 2, np.pi], repeat=n)))


@functools.cache
def degenerate_references(name: str):
    """(the XML chain, every degenerate configuration, their poses, which are regular: the smallest
    singular value of the chain's Jacobian above 1e-6), once for both backends."""
    _, chain = model_and_chain(name)
    q = every_degenerate_configuration()
    T = xml_walk(chain, q)[0]
    regular = np.array([np.linalg.svd(xml_jacobian(chain, row), compute_uv=False)[-1] > 1e-6 for row in q])
    return chain, q, T, regular


def xml_jacobian(chain: XmlChain, q) -> np.ndarray:
    """Geometric Jacobian [v; w] (6 x n) of the tip point in the base frame from the XML's joint
    axes and origins (XmlChain.walk), by cross products: nothing of the package's."""
    T, axes = chain.walk(q)
    return np.stack([np.concatenate([np.cross(axis, T[:3, 3] - origin), axis]) for _, _, _, axis, origin in axes], axis=-1)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_the_general_6r_misses_no_regular_degenerate_configuration(backend, irb140_package):
    """Every one of the 4,096 configurations with each joint at 0, +-pi/2 or pi: no valid answer
    off its pose, no pose without one, and the generating configuration among the answers wherever
    it is regular (the smallest singular value of the XML chain's own Jacobian above 1e-6; 1,792 of
    them).  At such poses the IRB 140's pencil has eigenvalues of multiplicity 2 and 4 (solutions
    sharing q3, or q1): the C's QR steps cycled on the multiple eigenvalue of one cut until they
    gave up (34 of them missed here), and where the other cut's eigenvalue is double, the one null
    vector it reads is a mix of two solutions.  At singular configurations (a continuum, a double
    root) which answer Newton settles on is not fixed: they are only held to no wrong answer."""
    chain, q, T, regular = degenerate_references("irb140")
    k = irb140_package.load(backend)
    Q, valid = k.ik(T)
    wrong = wrong_answers(chain, Q, valid, T)
    difference = np.abs((Q - q[:, None, :] + np.pi) % (2 * np.pi) - np.pi).max(axis=-1)
    missing = ~(valid & (difference <= JOINT_TOLERANCE)).any(axis=-1)
    assert regular.sum() > 1000   # the test covers many regular poses, not a handful
    assert (wrong, int((~valid.any(axis=-1)).sum()), int((missing & regular).sum())) == (0, 0, 0)


def test_the_turn_onto_a_urdf_axis_is_a_rotation_taking_z_there():
    """general_6r._onto_axis: for +-z, the axes and random unit axes, R z = a with R a rotation, so
    that origin Rot(a, q) = origin R Rz(q) R^T (checked at one angle against Rodrigues here)."""
    from derivations.ik.general_6r import _onto_axis
    rng = np.random.default_rng(6)
    axes = [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -1, 0)] + [tuple(v / np.linalg.norm(v)) for v in rng.normal(size=(5, 3))]
    q = 0.7
    for a in axes:
        R = np.array(_onto_axis(tuple(sp.Float(v, 20) for v in a)), dtype=float)[:3, :3]
        assert np.allclose(R @ [0, 0, 1], a, atol=1e-14) and np.allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert abs(np.linalg.det(R) - 1) < 1e-14
        K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        rodrigues = np.eye(3) + np.sin(q) * K + (1 - np.cos(q)) * K @ K
        Rz = np.array([[np.cos(q), -np.sin(q), 0], [np.sin(q), np.cos(q), 0], [0, 0, 1]])
        assert np.allclose(R @ Rz @ R.T, rodrigues, atol=1e-14)

"""Reversed chains (issue #26, item 2): arms whose special axes are at the base, solved read from the tool.

``T = E_1(q_1) ... E_n(q_n) M`` gives ``M T^-1 = E_n(-q_n) ... E_1(-q_1)``: a spherical shoulder (axes 1,
2, 3 meeting) is then a spherical wrist (derivations/ik/reverse.py).  The Franka Panda held at its joint
7 is one (axes 1, 2, 3 meet; axes 5 and 6 meet); the KUKA LWR 4 and iiwa 14 held at joint 5, 6 or 7 are
others (their S-R-S shoulder reversed).  Each is checked against this file's own forward kinematics
(the DH product of tests/test_zoo.py, the URDF's joints walked with ElementTree), over RANDOM uniform
and DEGENERATE configurations (joints at 0, +-pi/2, pi), the free joint at the configuration's value:
no valid branch off the target by more than 1e-9 (wrong), no target without a valid branch, and the
generating configuration among the valid branches within 2e-6 rad (missing), up to what a singular
configuration leaves free (below).  First from the branches' SymPy steps, then through the generated
numpy and C packages.
"""
import functools
import math
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

import derivations
from derivations.ik.structure import structure_of
from derivations.ik.reverse import reversed_structure
from conftest import shared_folder  # noqa: E402
from test_ik_short_chains import (FK_TOLERANCE, JOINT_TOLERANCE, evaluate_steps, urdf_chain, wrap,
                                  xml_walk)  # noqa: E402
from test_zoo import ARMS, fk as dh_fk, generated_package, generated_root  # noqa: E402,F401  (generated_root: a fixture)
from urdf_zoo import ZOO  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
URDF = ROOT / "tests" / "data" / "urdf"
RANDOM, DEGENERATE = 300, 100
SINGULAR = 1e-9  # metres, and |sin| of the angle between two axes: what a singular configuration leaves free


def pose_vector(T):
    """The pose task (x, y, z, r11 .. r33) of poses T (..., 4, 4)."""
    return np.concatenate([T[..., :3, 3], T[..., :3, :3].reshape(T.shape[:-2] + (9,))], axis=-1)


def dh_walk(arm, q):
    """The tool pose and the world lines of the joints (point, direction), from the DH product."""
    from test_zoo import link_frames
    frames = link_frames(arm, q)
    shift = 0 if arm.convention == "standard" else 1
    lines = [(frames[i + shift][..., :3, 3], frames[i + shift][..., :3, 2]) for i in range(arm.n)]
    return dh_fk(arm, q), lines


def urdf_walk(name):
    def walk(q):
        chain = urdf_chain(name)
        T, axes = xml_walk(chain, q)
        points = _urdf_points(chain, q)
        return T, list(zip(points, np.moveaxis(axes, 1, 0)))
    return walk


def _urdf_points(chain, q):
    """A point of each moving joint's line (its frame's origin), walked as xml_walk walks."""
    value = {name: q[:, i] for i, name in enumerate(chain.moving)}
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    points = []
    for joint in chain.joints:
        T = T @ chain._origin(joint)
        if joint.get("type") == "fixed":
            continue
        points.append(T[:, :3, 3].copy())
        axis = chain._axis(joint)
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        angle = value[joint.get("name")]
        motion = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        motion[:, :3, :3] = np.eye(3) + np.sin(angle)[:, None, None] * K + (1 - np.cos(angle))[:, None, None] * (K @ K)
        T = T @ motion
    return points


def _xml_walk(path, base, tip, q):
    """A URDF chain walked as written (its angles are pi/2 to every digit: nothing to snap)."""
    from urdf_zoo import XmlChain
    chain = XmlChain(path, base, tip)
    T, axes = xml_walk(chain, q)
    return T, list(zip(_urdf_points(chain, q), np.moveaxis(axes, 1, 0)))


class Case:
    """A seven-joint arm held at ``free`` (0-based), its reversed family, and its own forward kinematics
    ``walk(q) -> (T, [(point, direction) of each joint's line])``."""

    def __init__(self, title, load, free, walk, family="reversed spherical wrist", cli=()):
        self.title, self.load, self.free, self.walk, self.family, self.cli = title, load, free, walk, family, cli

    @functools.cached_property
    def model(self):
        path, options = self.load
        return derivations.load(path, free_joint=self.free + 1, **options)


PANDA = ARMS["franka_panda"]
LWR = ARMS["kuka_lwr4"]
CASES = {
    "panda_dh": Case("Franka Panda, DH (Franka's table), q7 free", (PANDA.path, {}), 6,
                     lambda q: dh_walk(PANDA, q), cli=(str(PANDA.path),)),
    "panda_urdf": Case("Franka Panda, URDF (example-robot-data), q7 free",
                       (ZOO["panda"].path, dict(base=ZOO["panda"].base, tip=ZOO["panda"].tip, dynamics=False)), 6,
                       urdf_walk("panda"), cli=(str(ZOO["panda"].path), "--base", ZOO["panda"].base,
                                                "--tip", ZOO["panda"].tip, "--no-dynamics")),
    "panda_urdf_tcp": Case("Franka Panda, URDF (tests/data/urdf/panda.urdf, to the hand's TCP), q7 free",
                           (URDF / "panda.urdf", dict(tip="panda_hand_tcp", dynamics=False)), 6,
                           lambda q: _xml_walk(URDF / "panda.urdf", "panda_link0", "panda_hand_tcp", q)),
    "lwr4_q5": Case("KUKA LWR 4, DH, q5 free", (LWR.path, {}), 4, lambda q: dh_walk(LWR, q)),
}


def configurations(n, seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-math.pi, math.pi, (RANDOM + DEGENERATE, n))
    q[RANDOM:] = rng.choice([0.0, math.pi / 2, -math.pi / 2, math.pi], (DEGENERATE, n))
    return q


def _distance_to_line(point, line):
    origin, direction = line
    offset = point - origin
    return np.linalg.norm(offset - direction * np.sum(offset * direction, axis=-1, keepdims=True), axis=-1)


def joint_distance(case, q, Q):
    """max |Q - q| per branch (revolute joints modulo 2 pi), up to what q leaves free.  The reversed arm's
    wrist is the real arm's shoulder, axes 1, 2, 3 meeting at s: with axes 1 and 3 in line (sin q2 = 0)
    only q1 + q3 (or q1 - q3) is fixed; with s on the line of the reversed arm's first joint (the last
    joint not held) or of its second, that joint is free and every joint of the reversed arm after it
    follows (the Panda at q4 = 0: axis 5 in line with axis 3, through s)."""
    _, lines = case.walk(q)
    difference = np.abs(wrap(Q - q[:, None, :]))
    (o1, z1), (o2, z2), (o3, z3) = lines[:3]
    in_line = np.linalg.norm(np.cross(z1, z3), axis=-1) <= SINGULAR
    plus = np.abs(wrap(Q[..., 0] + Q[..., 2] - (q[:, 0] + q[:, 2])[:, None]))
    minus = np.abs(wrap(Q[..., 0] - Q[..., 2] - (q[:, 0] - q[:, 2])[:, None]))
    difference[in_line, :, 0] = np.minimum(plus, minus)[in_line]
    difference[in_line, :, 2] = 0.0
    # the shoulder s: the point of axis 1 nearest axis 2 (they meet)
    w = o1 - o2
    b = np.sum(z1 * z2, axis=-1)
    d, e = np.sum(z1 * w, axis=-1), np.sum(z2 * w, axis=-1)
    s = o1 + ((b * e - d) / np.maximum(1 - b * b, 1e-300))[:, None] * z1
    first, second = [j for j in reversed(range(len(lines))) if j != case.free][:2]
    on_line = (_distance_to_line(s, lines[first]) <= SINGULAR) | (_distance_to_line(s, lines[second]) <= SINGULAR)
    difference[on_line] = 0.0
    return difference.max(axis=-1)


def step_counts(case, q):
    """(counts, worst FK error) of the model's branches evaluated from their SymPy steps."""
    model = case.model
    x = pose_vector(case.walk(q)[0])
    branches = [evaluate_steps(model, branch, x, {model.q[case.free]: q[:, case.free]}) for branch in model.ik]
    Q = np.stack([b[0] for b in branches], axis=1)
    valid = np.stack([b[1] for b in branches], axis=1)
    return tally(case, q, x, Q, valid)


def tally(case, q, x, Q, valid):
    reached = pose_vector(case.walk(np.where(valid[..., None], Q, 0.0).reshape(-1, q.shape[1]))[0])
    error = np.where(valid, np.abs(reached.reshape(Q.shape[:2] + (12,)) - x[:, None, :]).max(axis=-1), 0.0)
    distance = np.where(valid, joint_distance(case, q, Q), np.inf).min(axis=-1)
    counts = {"wrong": int((error > FK_TOLERANCE).sum()), "no solution": int((~valid.any(axis=-1)).sum()),
              "missing": int((distance > JOINT_TOLERANCE).sum())}
    return counts, float(error.max())


def test_the_reversal_is_the_same_lines_in_the_reverse_order():
    """M T^-1 = E_n(-q_n) ... E_1(-q_1): the reversed structure's lines, turned by the negated joint
    values in the reverse order from the identity, give M T^-1 of this file's DH product (Panda)."""
    model = derivations.load(PANDA.path)
    S = structure_of(model)
    R = reversed_structure(S)
    params = {s: float(v) for s, v in model.params.items()}
    lines = [(np.array([float(e.xreplace(params)) for e in a.p]), np.array([float(e.xreplace(params)) for e in a.h]))
             for a in R.axes]
    M = np.array(S.home.xreplace(params).tolist(), float)
    q = np.random.default_rng(2).uniform(-math.pi, math.pi, (5, 7))
    T = dh_fk(PANDA, q)
    for k in range(len(q)):
        product = np.eye(4)
        for (p, h), angle in zip(lines, -q[k, ::-1]):
            K = np.array([[0, -h[2], h[1]], [h[2], 0, -h[0]], [-h[1], h[0], 0]])
            turn = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)
            step = np.eye(4)
            step[:3, :3], step[:3, 3] = turn, p - turn @ p
            product = product @ step
        np.testing.assert_allclose(product, M @ np.linalg.inv(T[k]), atol=1e-12)


@pytest.mark.parametrize("name", list(CASES))
def test_reversed_branches_from_their_steps(name):
    case = CASES[name]
    model = case.model
    assert model.ik_plan[0] == f"family: {case.family}, joint {case.free + 1} free", model.ik_unsupported
    assert model.ik_free == case.free and len(model.ik) == len({b.name for b in model.ik}) == 8
    q = configurations(model.n, zlib.crc32(name.encode()))
    counts, worst = step_counts(case, q)
    assert counts == {"wrong": 0, "no solution": 0, "missing": 0}, (counts, worst)


def test_the_panda_holds_joint_7_by_itself_and_lists_the_held_joints():
    """Joints 4 and 5 classify reversed but their position joints have no closed form; joint 6 leaves axes
    5 and 7 meeting only where sin q6 is not 0 (at a6 / sin q6): no fixed structure.  Joint 7 is chosen."""
    model = derivations.load(PANDA.path)
    assert model.ik_plan[0] == "family: reversed spherical wrist, joint 7 free" and model.ik_free == 6
    listing = next(line for line in model.ik_plan if line.startswith("held joints: "))
    assert listing.startswith("held joints: joint 7: reversed spherical wrist family;"), listing
    for j in (1, 2, 3):
        assert f"joint {j}: no three consecutive axes meet" in listing, listing
    for j in (4, 5, 6):
        assert f"joint {j}: reversed spherical wrist family, but joints 1 to 3 (RRR)" in listing, listing


def test_an_arm_with_its_own_family_keeps_it():
    """The iiwa's joint 3 (its own spherical wrist) is ranked before its reversed joints 5, 6, 7."""
    model = derivations.load(URDF / "iiwa14.urdf", dynamics=False)
    assert model.ik_plan[0] == "family: spherical wrist, joint 3 free"
    listing = next(line for line in model.ik_plan if line.startswith("held joints: "))
    order = [listing.index(f"joint {j}: ") for j in (3, 2, 1, 5, 6, 7)]
    assert order == sorted(order), listing
    assert "joint 5: reversed spherical wrist family" in listing


@pytest.mark.parametrize("held", [6, 7])
def test_the_lwr4_held_at_joint_6_or_7_solves_every_degenerate_configuration(held):
    """The KUKA LWR 4 held at joint 6 or 7: with q4 = 0 the shoulder point lies on axis 5 and
    subproblem 4's P and Q are rounding (the angle is free, subproblems.FREE_ANGLE).  Before that
    case 14 and 31 of these 100 degenerate configurations had no valid branch.  Now every one has,
    none is wrong, and the generating configuration is among the branches wherever it is not one of
    a continuum: every one missed is singular, the Jacobian of the six solved joints (this file's DH
    product, test_zoo.jacobian) of rank below six."""
    from test_zoo import jacobian
    case = Case(f"KUKA LWR 4, DH, q{held} free", (LWR.path, {}), held - 1, lambda q: dh_walk(LWR, q))
    model = case.model
    assert model.ik_plan[0] == f"family: reversed spherical wrist, joint {held} free"
    q = configurations(model.n, zlib.crc32(f"lwr{held - 1}".encode()))
    x = pose_vector(case.walk(q)[0])
    branches = [evaluate_steps(model, b, x, {model.q[case.free]: q[:, case.free]}) for b in model.ik]
    Q, valid = np.stack([b[0] for b in branches], axis=1), np.stack([b[1] for b in branches], axis=1)
    counts, worst = tally(case, q, x, Q, valid)
    assert counts["wrong"] == counts["no solution"] == 0, (counts, worst)
    missed = np.where(valid, joint_distance(case, q, Q), np.inf).min(axis=-1) > JOINT_TOLERANCE
    assert not missed[:RANDOM].any()
    smallest = np.linalg.svd(np.delete(jacobian(LWR, q[missed]), case.free, axis=-1), compute_uv=False)[:, -1]
    assert (smallest < 1e-12).all(), smallest


# --------------------------------------------------------------------------- the generated packages

PACKAGED = {"panda_dh": ("--free-joint", "7"), "lwr4_q5": ("--free-joint", "5")}
# A case whose package is the zoo's (tests/test_zoo.py, generated once per run for both files): the
# Panda's file holds q7 free by default and has no inertials, so `kinegen generate` writes the same
# package with and without --free-joint 7 --no-dynamics, byte for byte (2026-11-27; the package's
# IK_METHOD is checked below).
ZOO_PACKAGES = {"panda_dh": ("franka_panda", "reversed spherical wrist, joint 7 free")}


_PACKAGES: dict = {}


@pytest.fixture(scope="session")
def package_root(tmp_path_factory):
    """One folder of packages for the run, shared by pytest-xdist's workers (as tests/test_zoo.py's)."""
    return shared_folder(tmp_path_factory, "reversed_packages")


def package(name, root, zoo_root):
    """The case's package (numpy and the portable C), generated by the CLI once per run, under a lock
    (the zoo's own, generated in ``zoo_root``, where ZOO_PACKAGES names it)."""
    import fcntl
    import importlib
    if name in ZOO_PACKAGES:
        arm, method = ZOO_PACKAGES[name]
        zoo = generated_package(arm, zoo_root)
        assert zoo.IK_METHOD == method
        return zoo
    if name not in _PACKAGES:
        with open(root / f"{name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # another worker may be generating it
            if not (root / name).exists():
                path, _ = CASES[name].load
                subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(path), "--out",
                                str(root / name), "--no-dynamics", *PACKAGED[name]], cwd=ROOT, check=True,
                               capture_output=True, timeout=900)
        sys.path.insert(0, str(root))
        try:
            _PACKAGES[name] = importlib.import_module(name)
        finally:
            sys.path.remove(str(root))
    return _PACKAGES[name]


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", list(PACKAGED))
def test_reversed_branches_through_the_generated_code(name, backend, package_root, generated_root):
    """The same counts through the generated kernels; the free joint comes back as given, every revolute
    value in (-pi, pi], and the kernels' branches are the model's, in its order."""
    case = CASES[name]
    kernels = package(name, package_root, generated_root).load(backend)
    assert list(kernels.BRANCHES) == [b.name for b in case.model.ik]
    q = configurations(case.model.n, zlib.crc32(f"{name} generated".encode()))
    x = pose_vector(case.walk(q)[0])
    Q, valid = kernels.ik(x, free=q[:, case.free])
    assert np.abs(wrap(Q[..., case.free] - q[:, None, case.free]))[valid].max() == 0.0
    assert (np.abs(Q[valid]) <= np.pi).all() and np.isfinite(Q[valid]).all()
    counts, worst = tally(case, q, x, Q, valid)
    assert counts == {"wrong": 0, "no solution": 0, "missing": 0}, (counts, worst)


# --------------------------------------------------------------------------- a UR read from its tool

# The mirror of a UR: axes 1 and 2 meet, axes 3, 4, 5 parallel, axis 6 across them (no real arm of the
# zoo has it).  Read from the tool it is a UR: the three-parallel family, reversed.
REVERSED_UR = """name = "reversed_ur"
convention = "standard"
[params]
d1 = 0.1
d2 = 0.12
a3 = 0.4
a4 = 0.35
d5 = 0.08
d6 = 0.1
[[joint]]
type = "R"
d = "d1"
alpha = "pi/2"
[[joint]]
type = "R"
d = "d2"
alpha = "-pi/2"
[[joint]]
type = "R"
a = "a3"
[[joint]]
type = "R"
a = "a4"
[[joint]]
type = "R"
d = "d5"
alpha = "pi/2"
[[joint]]
type = "R"
d = "d6"
"""


def test_a_ur_read_from_its_tool(tmp_path):
    """The made-up arm gets the three-parallel family reversed; its branches, from their steps, put the
    tool back on every target (this file's DH product), and find the generating configuration of every
    random one (a degenerate one may lie where the UR's free joints are, which this test does not
    mask: there it asks only that some branch reaches the target)."""
    from test_zoo import read_arm
    path = tmp_path / "reversed_ur.toml"
    path.write_text("# a UR's structure mirrored: axes 1, 2 meet, axes 3, 4, 5 parallel\n" + REVERSED_UR)
    model = derivations.load(path)
    assert model.ik_plan[0] == "family: reversed three parallel", model.ik_unsupported
    assert [b.name.split("_")[::2] for b in model.ik] == [["wrist", "shoulder", "elbow"]] * 8
    arm = read_arm(path)
    q = configurations(6, 1226)
    x = pose_vector(dh_fk(arm, q))
    branches = [evaluate_steps(model, branch, x) for branch in model.ik]
    Q = np.stack([b[0] for b in branches], axis=1)
    valid = np.stack([b[1] for b in branches], axis=1)
    reached = pose_vector(dh_fk(arm, np.where(valid[..., None], Q, 0.0).reshape(-1, 6))).reshape(Q.shape[:2] + (12,))
    error = np.where(valid, np.abs(reached - x[:, None, :]).max(axis=-1), 0.0)
    distance = np.where(valid, np.abs(wrap(Q - q[:, None, :])).max(axis=-1), np.inf).min(axis=-1)
    assert int((error > FK_TOLERANCE).sum()) == 0, error.max()
    assert valid.any(axis=-1).all()
    assert int((distance[:RANDOM] > JOINT_TOLERANCE).sum()) == 0


@pytest.mark.parametrize("held", [5, 6, 7])
def test_the_iiwa_held_past_its_elbow_is_a_reversed_spherical_wrist(held):
    """The iiwa 14's URDF held at joint 5, 6 or 7: its S-R-S shoulder read from the tool.  Round trip
    FK(IK(x)) = x on 300 random configurations (test_auto_ik.round_trip_from_steps: the branches' steps
    against the model's task, to 1e-9), each generating configuration found."""
    from test_auto_ik import round_trip_from_steps
    model = derivations.load(URDF / "iiwa14.urdf", free_joint=held, dynamics=False)
    assert model.ik_plan[0] == f"family: reversed spherical wrist, joint {held} free" and len(model.ik) == 8
    q = np.random.default_rng(held).uniform(-math.pi, math.pi, (300, 7))
    _, found = round_trip_from_steps(model, q, held - 1)
    assert found.all()

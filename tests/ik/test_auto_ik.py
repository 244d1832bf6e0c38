"""The automatic inverse kinematics (derivations.ik, issue #15) on the papers' robots.

Each robot below keeps its hand-written inverse (the paper's steps, for the LaTeX); the
decomposition must find every configuration those find.  Its branches are evaluated here
straight from their SymPy steps (each step lambdified on its own, in order), not through
the generated code, and compared with the hand-written kernels at random reachable targets:
every valid hand branch has a valid automatic branch with the same joint values (revolute
modulo 2 pi), and every valid automatic branch reaches the target.

The subproblems themselves are checked against their defining equations at random vectors.
"""
import math
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import derivations
import generated
from derivations.ik import solve
from derivations.ik.subproblems import angle_onto, angle_to_distance, angle_to_height, cone_angle, slide_to_distance

ROOT = Path(__file__).resolve().parents[2]
COUNT = 2000
JOINT_TOLERANCE = 1e-7
FK_TOLERANCE = 1e-9
ROBOTS = {"planar_2r": "parallel axes", "planar_3r": "parallel axes", "adept_three": "parallel axes",
          "puma560": "spherical wrist"}


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def snap_unit(c):
    c = np.asarray(c, dtype=float)
    return np.where(c >= 1 - 1e-12, 1.0, np.where(c <= -1 + 1e-12, -1.0, c))


COMPARE = {sp.LessThan: np.less_equal, sp.StrictLessThan: np.less, sp.GreaterThan: np.greater_equal,
           sp.StrictGreaterThan: np.greater}
MODULES = [{"WrapAngle": wrap, "ClampUnit": snap_unit, "Ramp": lambda v: np.maximum(v, 0.0)}, "numpy"]


def evaluate_steps(model, branch, x: np.ndarray, extra=None):
    """The branch's joint values and existence at targets x (N, m), step by step in numpy
    (``extra``: {symbol: values}, the free joint of a seven-joint arm)."""
    values = {s: x[:, i] for i, s in enumerate(model.task_symbols)}
    values.update(extra or {})
    values.update({p: np.full(len(x), float(v)) for p, v in model.params.items()})
    for symbol, expr in branch.steps:
        names = sorted(expr.free_symbols, key=str)
        value = sp.lambdify(names, expr, modules=MODULES)(*(values[n] for n in names))
        values[symbol] = np.broadcast_to(np.asarray(value, dtype=float), (len(x),))
    def truth(c):
        if c is sp.true:
            return np.ones(len(x), bool)
        if isinstance(c, (sp.And, sp.Or)):
            parts = [truth(a) for a in c.args]
            return np.logical_and.reduce(parts) if isinstance(c, sp.And) else np.logical_or.reduce(parts)
        names = sorted(c.free_symbols, key=str)
        lhs, rhs = (sp.lambdify(names, side, modules=MODULES)(*(values[n] for n in names)) for side in (c.lhs, c.rhs))
        return np.broadcast_to(COMPARE[type(c)](np.asarray(lhs, float), np.asarray(rhs, float)), (len(x),))

    valid = truth(branch.step_condition)
    Q = np.stack([np.broadcast_to(values[q], (len(x),)) for q in model.q], axis=-1)
    return Q, valid & np.isfinite(Q).all(axis=-1)


def round_trip_from_steps(model, q: np.ndarray, free: int | None = None):
    """(targets, found): the model's task at q (lambdified, default parameters), every branch
    evaluated from its steps at those targets (the free joint, if any, at q's value) and held
    to FK_TOLERANCE, and whether q is among the valid branches (revolute joints modulo 2 pi)."""
    params = [float(v) for v in model.params.values()]
    task = sp.lambdify([model.q, *model.params], list(model.explicit(model.task)), modules="numpy")

    def evaluate(joints):
        return np.stack([np.broadcast_to(np.asarray(v, float), (len(q),)) for v in task(joints.T, *params)], axis=-1)

    x = evaluate(q)
    extra = {} if free is None else {model.q[free]: q[:, free]}
    revolute = [i for i, kind in enumerate(model.joint_types) if kind == "R"]
    found = np.zeros(len(q), bool)
    for branch in model.ik:
        Q, valid = evaluate_steps(model, branch, x, extra)
        assert np.abs(np.where(valid[:, None], evaluate(Q) - x, 0.0)).max() < FK_TOLERANCE, branch.name
        difference = Q - q
        difference[:, revolute] = wrap(difference[:, revolute])
        found |= valid & (np.abs(difference).max(axis=-1) < JOINT_TOLERANCE)
    return x, found


@pytest.fixture(scope="module")
def solutions():
    return {name: (derivations.load(name), solve(derivations.load(name))) for name in ROBOTS}


@pytest.mark.parametrize("name", list(ROBOTS))
def test_the_decomposition_finds_every_hand_written_branch(name, solutions):
    model, solution = solutions[name]
    assert solution.family == ROBOTS[name]
    assert len(solution.branches) == len(model.ik)
    k = generated.load(name, backend="numpy")
    rng = np.random.default_rng(1501)
    q = np.stack([rng.uniform(-np.pi, np.pi, COUNT) if kind == "R" else rng.uniform(*lim, COUNT)
                  for kind, lim in zip(k.JOINT_TYPES, k.LIMITS)], axis=-1)
    x = k.task(q)
    Q_hand, valid_hand = k.ik(x)
    auto = [evaluate_steps(model, b, x) for b in solution.branches]
    Q_auto = np.stack([a[0] for a in auto], axis=1)
    valid_auto = np.stack([a[1] for a in auto], axis=1)
    revolute = np.array([kind == "R" for kind in k.JOINT_TYPES])
    # every valid automatic branch reaches the target
    miss = np.abs(k.task(np.where(valid_auto[..., None], Q_auto, 0.0)) - x[:, None, :])
    for i, task in enumerate(k.TASK):
        if task == "phi":
            miss[..., i] = np.abs(wrap(miss[..., i]))
    assert np.where(valid_auto, miss.max(axis=-1), 0.0).max() < FK_TOLERANCE
    # every valid hand-written branch is among them
    difference = np.abs(Q_hand[:, :, None, :] - Q_auto[:, None, :, :])
    difference[..., revolute] = np.abs(wrap(difference[..., revolute]))
    closest = np.where(valid_auto[:, None, :], difference.max(axis=-1), np.inf).min(axis=-1)
    unmatched = valid_hand & (closest > JOINT_TOLERANCE)
    assert unmatched.sum() == 0, (unmatched.sum(), float(closest[valid_hand].max()))
    assert valid_auto.sum() == valid_hand.sum()


# --------------------------------------------------------------------------- the subproblems

def _unit(v):
    return v / np.linalg.norm(v)


def _rotate(k, theta, v):
    k, v = np.asarray(k, float), np.asarray(v, float)
    return v * math.cos(theta) + np.cross(k, v) * math.sin(theta) + k * np.dot(k, v) * (1 - math.cos(theta))


def _numeric(expr):
    return float(sp.sympify(expr).evalf(30))


@pytest.mark.parametrize("seed", range(20))
def test_subproblems_satisfy_their_equations(seed):
    """Each root of each subproblem, at random vectors built to have roots, satisfies the equation
    it solves (rotations by Rodrigues' formula in numpy)."""
    rng = np.random.default_rng(seed)
    k = _unit(rng.normal(size=3))
    a, b, h = rng.normal(size=3), rng.normal(size=3), _unit(rng.normal(size=3))
    theta = rng.uniform(-np.pi, np.pi)
    M = lambda v: sp.Matrix([sp.Float(e, 30) for e in v])  # noqa: E731
    # subproblem 1: a turned onto rot(k, theta) a
    target = _rotate(k, theta, a)
    assert abs(wrap(_numeric(angle_onto(M(k), M(a), M(target))) - theta)) < 1e-12
    # subproblem 4: the height of rot(k, theta) b along h
    d = float(np.dot(h, _rotate(k, theta, b)))
    roots = angle_to_height(M(h), M(k), M(b), sp.Float(d, 30))
    assert any(abs(wrap(_numeric(r.value) - theta)) < 1e-9 for r in roots)
    for r in roots:
        assert bool(r.condition) and abs(np.dot(h, _rotate(k, _numeric(r.value), b)) - d) < 1e-12
    # subproblem 3: the distance of a + rot(k, theta) b from the origin
    delta2 = float(np.sum((a + _rotate(k, theta, b)) ** 2))
    roots = angle_to_distance(M(k), M(a), M(b), sp.Float(delta2, 30))
    assert any(abs(wrap(_numeric(r.value) - theta)) < 1e-9 for r in roots)
    for r in roots:
        assert abs(np.sum((a + _rotate(k, _numeric(r.value), b)) ** 2) - delta2) < 1e-12
    # beyond reach: no root exists
    far = angle_to_distance(M(k), M(a), M(b), sp.Float((np.linalg.norm(a) + np.linalg.norm(b) + 1) ** 2, 30))
    assert not any(bool(r.condition) for r in far)
    # the slide: |a + t k|^2 = delta^2
    t = rng.uniform(-2, 2)
    delta2 = float(np.sum((a + t * k) ** 2))
    roots = slide_to_distance(M(k), M(a), sp.Float(delta2, 30))
    assert any(abs(_numeric(r.value) - t) < 1e-9 for r in roots)


@pytest.mark.parametrize("seed", range(5))
def test_subproblems_leave_an_angle_free_where_the_turn_changes_nothing(seed):
    """A vector on the axis (subproblem 4: v = |v| k, rounded in its last digits; subproblem 3: the
    point b on the axis) gives P = Q = 0 up to rounding: every angle solves the equation when the
    target is the one the vector already has (the height h . v, the distance |a + b|), and both roots
    exist, 0 and pi, each satisfying it; a target 1e-6 off has no root.  Before, R^2 <= P^2 + Q^2
    compared two rounding errors and refused such targets (the PR2's stretched elbow)."""
    rng = np.random.default_rng(seed)
    k, h = _unit(rng.normal(size=3)), _unit(rng.normal(size=3))
    M = lambda v: sp.Matrix([sp.Float(e, 30) for e in v])  # noqa: E731
    v = rng.uniform(0.2, 2) * k + rng.normal(size=3) * 1e-17     # on the axis, to rounding
    a, b = rng.normal(size=3), rng.uniform(0.2, 2) * k + rng.normal(size=3) * 1e-17
    equations = [(angle_to_height, lambda theta: np.dot(h, _rotate(k, theta, v)), float(np.dot(h, v)),
                  (M(h), M(k), M(v))),
                 (angle_to_distance, lambda theta: np.sum((a + _rotate(k, theta, b)) ** 2), float(np.sum((a + b) ** 2)),
                  (M(k), M(a), M(b)))]
    for subproblem, side, target, args in equations:
        roots = subproblem(*args, sp.Float(target, 30))
        assert all(bool(r.condition) for r in roots), subproblem.__name__
        assert sorted(abs(_numeric(r.value)) for r in roots) == pytest.approx([0, np.pi], abs=1e-15)
        for r in roots:
            assert abs(side(_numeric(r.value)) - target) < 1e-12
        assert not any(bool(r.condition) for r in subproblem(*args, sp.Float(target + 1e-6, 30)))


def test_cone_angle_keeps_the_digits_near_zero():
    """Turning about k = y, v = z onto the cone about h = z through u: for u at 1e-9 rad from h the
    roots are +-1e-9 to full relative precision (acos(cos 1e-9) would give 0 or 1.49e-8)."""
    h, k, v = sp.Matrix([0, 0, 1]), sp.Matrix([0, 1, 0]), sp.Matrix([0, 0, 1])
    angle = sp.Float("1e-9", 30)
    u = sp.Matrix([sp.sin(angle), 0, sp.cos(angle)])
    values = sorted(_numeric(r.value) for r in cone_angle(h, k, v, u))
    assert values[0] == pytest.approx(-1e-9, rel=1e-12) and values[1] == pytest.approx(1e-9, rel=1e-12)


# --------------------------------------------------------------------------- URDF chains and the CLI

URDF = Path(__file__).resolve().parents[1] / "data" / "urdf"
URDF_FAMILIES = {"ur5.urdf": ("three parallel", None, "tool0"), "stanford.urdf": ("spherical wrist", None, None),
                 "iiwa14.urdf": ("spherical wrist, joint 3 free", 2, None)}


@pytest.mark.parametrize("file", list(URDF_FAMILIES))
def test_urdf_chains_decompose_like_dh_tables(file):
    """The structure is read from the joint axes, so a URDF chain gets the same families; its
    branches, evaluated from their steps, put the tool back on 300 targets from its own fk."""
    family, free, tip = URDF_FAMILIES[file]
    model = derivations.load(URDF / file, tip=tip)
    assert model.ik_plan[0] == f"family: {family}" and model.ik_free == free
    rng = np.random.default_rng(14)
    q = rng.uniform(-np.pi, np.pi, (300, model.n))
    for i, kind in enumerate(model.joint_types):
        if kind == "P":
            q[:, i] = rng.uniform(*model.limits[i], 300)
    _, found = round_trip_from_steps(model, q, free)
    assert found.all()


def test_a_derived_branch_is_its_steps_substituted_when_read():
    """A derived branch's ``solution`` and ``condition`` (the steps substituted into one another,
    which the kernels never read) are computed when first read, also after a round trip through
    the derivation cache; read, they are the branch: at 200 targets from the arm's own fk (the Adept
    Cobra 600: the flat solution of a six-joint arm takes minutes to lambdify), each joint value is
    the one its steps give (revolute modulo 2 pi), the condition holds where the steps' conditions
    do, and the valid answers put the tool back."""
    from derivations.model import SubstitutedSteps
    model = derivations.load(ROOT / "tests" / "data" / "arms" / "adept_cobra600.toml")
    assert all(isinstance(b.__dict__["_solution"], SubstitutedSteps) for b in model.ik)
    reloaded = pickle.loads(pickle.dumps(model))
    assert all(isinstance(b.__dict__["_condition"], SubstitutedSteps) for b in reloaded.ik)
    q = np.random.default_rng(27).uniform(-np.pi, np.pi, (200, model.n))
    x, found = round_trip_from_steps(model, q)
    assert found.all()
    symbols = [*model.task_symbols, *model.params]
    point = [*x.T, *(np.full(len(x), float(v)) for v in model.params.values())]
    revolute = np.array([kind == "R" for kind in model.joint_types])
    for branch in model.ik + reloaded.ik:
        Q_steps, valid_steps = evaluate_steps(model, branch, x)
        Q = np.stack([np.broadcast_to(np.asarray(sp.lambdify(symbols, e, modules=MODULES)(*point), float), (len(x),))
                      for e in branch.solution], axis=-1)
        valid = np.broadcast_to(sp.lambdify(symbols, branch.condition, modules=MODULES)(*point), (len(x),))
        assert valid.any() and np.array_equal(valid & np.isfinite(Q).all(axis=-1), valid_steps), branch.name
        difference = np.abs(Q - Q_steps)
        difference[:, revolute] = np.abs(wrap(difference[:, revolute]))
        assert difference[valid].max() < 1e-9, branch.name


@pytest.mark.parametrize("held, by", [(1, 1), (2, "iiwa_joint_2"), (3, 3)])
def test_the_user_chooses_the_held_joint_of_a_seven_joint_arm(held, by):
    """Holding joint 1, 2 or 4 of the iiwa 14 also leaves a spherical-wrist arm (issue #26): the
    user names the joint by number or by name, and its branches put the tool back on 300 targets
    with that joint at its given value; the listing says which held joints give which family."""
    model = derivations.load(URDF / "iiwa14.urdf", free_joint=by)
    assert model.ik_plan[0] == f"family: spherical wrist, joint {held} free" and model.ik_free == held - 1
    listing = next(line for line in model.ik_plan if line.startswith("held joints: "))
    assert all(f"joint {j}: spherical wrist family" in listing for j in (1, 2, 3))
    q = np.random.default_rng(26).uniform(-np.pi, np.pi, (300, 7))
    _, found = round_trip_from_steps(model, q, held - 1)
    assert found.all()


def test_a_held_joint_that_leaves_no_closed_form_is_said_and_a_bad_one_refused():
    with pytest.raises(derivations.DescriptionError, match="free joint: 8 is not a joint of the chain"):
        derivations.load(URDF / "iiwa14.urdf", free_joint=8)
    with pytest.raises(derivations.DescriptionError, match="for a seven-joint arm's ik; this chain has 6"):
        derivations.load(URDF / "ur5.urdf", tip="tool0", free_joint=1)
    # holding the elbow of the S-R-S arm leaves a spherical shoulder placing the wrist: a continuum, read
    # from the base or from the tool (holding joint 6 leaves a reversed spherical wrist: tests/ik/test_reversed.py)
    model = derivations.load(URDF / "iiwa14.urdf", free_joint=4)
    assert not model.ik and "holding joint 4 (the free joint asked for)" in model.ik_unsupported
    assert "axes 1, 2 and 3 meet in one point" in model.ik_unsupported


def test_kinegen_show_prints_the_decomposition(tmp_path):
    """`kinegen show FILE --what ik` prints the family and a subproblem per joint; for an arm outside
    the families, the numeric method and what the arm lacks."""
    arms = Path(__file__).resolve().parents[1] / "data" / "arms"
    run = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "show", str(arms / "ur5.toml"), "--what", "ik"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("family: three parallel")
    assert "q1: subproblem 4" in run.stdout and "q3: subproblem 3" in run.stdout
    assert "shoulder_left_elbow_down_wrist_flip: three parallel family; q1: subproblem 4: atan2(Q, P) - acos" in run.stdout
    run = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "show", str(arms / "kinova_jaco.toml"),
                          "--what", "ik"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("method: general 6R (every real solution, up to 16")
    assert "no closed form: no three consecutive axes meet in a point" in run.stdout


# --------------------------------------------------------------------------- three-joint positioning arms

# Siciliano, Sciavicco, Villani, Oriolo, "Robotics: Modelling, Planning and Control" (2009):
# the anthropomorphic arm of Table 2.3 (axes 2 and 3 parallel) and the spherical arm of
# Table 2.2 (axes 1 and 2 meeting, joint 3 prismatic); lengths ours.
POSITION_ARMS = {
    "anthropomorphic": ("""name = "anthropomorphic"
title = "Anthropomorphic arm (Siciliano et al. Table 2.3)"
source = "Siciliano, Sciavicco, Villani, Oriolo 2009, Table 2.3; a2 = 0.4, a3 = 0.35 ours"
convention = "standard"
task = ["x", "y", "z"]
[params]
a2 = 0.4
a3 = 0.35
[[joint]]
type = "R"
alpha = "pi/2"
[[joint]]
type = "R"
a = "a2"
[[joint]]
type = "R"
a = "a3"
""", 4),
    "spherical_arm": ("""name = "spherical_arm"
title = "Spherical arm (Siciliano et al. Table 2.2)"
source = "Siciliano, Sciavicco, Villani, Oriolo 2009, Table 2.2; d2 = 0.15 ours"
convention = "standard"
task = ["x", "y", "z"]
[params]
d2 = 0.15
[[joint]]
type = "R"
alpha = "-pi/2"
[[joint]]
type = "R"
d = "d2"
alpha = "pi/2"
[[joint]]
type = "P"
limits = [0.1, 0.9]
""", 4),
}


@pytest.mark.parametrize("name", list(POSITION_ARMS))
def test_three_joint_positioning_arms(name, tmp_path):
    """The position family: every branch puts the tool point on 1,000 targets from the arm's own
    fk (random and degenerate joints), and the generating configuration is among them (the
    spherical arm's slide is the distance from the shoulder: its two roots are +-, and the
    negative one is outside the limits the fk drew from but still a solution)."""
    text, branches = POSITION_ARMS[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    model = derivations.load(path)
    assert model.ik_plan[0] == "family: position" and len(model.ik) == branches
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (1000, 3))
    q[800:, :2] = rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi], (200, 2))
    if model.joint_types[2] == "P":
        q[:, 2] = rng.uniform(0.1, 0.9, 1000)
    else:
        q[800:, 2] = rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi], 200)
    x, found = round_trip_from_steps(model, q)
    # the anthropomorphic arm's shoulder is free with the wrist on axis 1 (q2 = q3 = +-pi/2 ...):
    # there the target is on the z axis and only the reach matters
    on_axis = np.hypot(x[:, 0], x[:, 1]) < 1e-9
    assert (found | on_axis).all(), (~found & ~on_axis).sum()

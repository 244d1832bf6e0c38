"""Closed-form ik of short chains and of the tasks a 4- to 6-joint arm reaches in full (issue #26, item 2).

* three-joint position arms with prismatic joints (``derivations.ik.decompose._position_prismatic``):
  the README's cylindrical R P P robot (Kumar, Fig. 10) and the Stanford arm's R R P position
  sub-chain (Paul, Stanford AIM-177, Fig. 2.3), plus one made-up chain of each other kind
  (P P R, P R R, R R P, R P R, P R P, P P P: no real arm of those kinds here);
* x, y, z, pitch (4 joints: the AL5D from its DH table and from its URDF), x, y, z, pitch, roll
  (5 joints: the SO-101 URDF), x, y, z, approach (a UR5 and a KUKA KR5 turning a tool about its
  approach: joint 6 free).

Each branch is evaluated from its SymPy steps (as ``test_auto_ik.evaluate_steps`` does); the targets and
the answers go through this file's own forward kinematics (``test_zoo``'s DH product, or
``urdf_zoo.XmlChain`` reading the URDF with ElementTree), and pitch, roll and approach are read off
those frames here.  Over random configurations and degenerate ones (every revolute joint at 0,
+-pi/2 or pi, every prismatic one at an end or the middle of its range) the counts are those of
test_zoo: wrong (a valid branch off the target by more than 1e-9), no solution, missing (the
generating configuration not among the valid branches, up to what a singular configuration
leaves free).  The 10,000 + 1,000 counts through both generated backends: benchmarks/short_chains.py.
"""
import functools
import math
import re
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import derivations  # noqa: E402
from test_auto_ik import COMPARE, MODULES  # noqa: E402
from test_urdf_zoo import snapped_numbers  # noqa: E402
from test_zoo import ARMS, fk as dh_fk, link_frames, read_arm, wrist_geometry  # noqa: E402
from urdf_zoo import ZOO, XmlChain  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
RANDOM, DEGENERATE = 200, 100
FK_TOLERANCE = 1e-9
# The generating configuration is "among the answers" within this.  The subproblems take an acos
# argument within 1e-12 of +-1 as +-1 (derivations.ik.primitives.UNIT_SNAP), so that a double root
# comes out exact; an angle within sqrt(2e-12) = 1.4e-6 of a double root is thereby taken at it
# (the Stanford arm with q2 = -2.5e-7 came back with q2 = 0 and q1 off by 1.4e-6, its pose off by
# 1e-12), and the zoo's 1e-6 would count it missing.
JOINT_TOLERANCE = 2e-6
SINGULAR = 1e-9

# The README's cylindrical robot (Kumar, Fig. 10: base rotation, lift, radial extension), with strokes.
CYLINDRICAL = """name = "cylindrical_rpp"
convention = "standard"
task = ["x", "y", "z"]
[params]
d1 = 0.5
[[joint]]
type = "R"
d = "d1"
[[joint]]
type = "P"
theta = "-pi/2"
alpha = "-pi/2"
limits = [0.1, 0.8]
[[joint]]
type = "P"
limits = [0.1, 0.6]
[tool]
xyz = [0, 0, 0.1]
"""
# The Stanford arm's joints 1 to 3 (tests/data/arms/stanford_arm.toml: Paul, AIM-177, Fig. 2.3).
STANFORD = """name = "stanford_rrp"
convention = "standard"
task = ["x", "y", "z"]
[params]
d1 = 0.412
d2 = 0.154
a3 = 0.0203
[[joint]]
type = "R"
d = "d1"
alpha = "-pi/2"
[[joint]]
type = "R"
d = "d2"
alpha = "pi/2"
[[joint]]
type = "P"
theta = "-pi/2"
a = "a3"
limits = ["12*0.0254", "50*0.0254"]
"""
# Made-up chains, one of each remaining kind (no real arm of these kinds in tests/data).
SYNTHETIC = {
    "ppr": ('alpha = "-pi/2"', 'theta = "pi/2"\nalpha = 0.3', "a = 0.3\nd = 0.1\nalpha = 0.4", "PPR"),
    "prr_parallel": ("", "a = 0.4\nd = 0.1", "a = 0.3", "PRR"),
    "prr_meeting": ('alpha = "pi/2"', 'alpha = "pi/2"\nd = 0.2', "a = 0.3\nd = 0.1", "PRR"),
    "rrp_parallel": ("a = 0.4", "a = 0.3\nalpha = 0.2", "", "RRP"),
    "rpr": ("a = 0.2", "a = 0.3", "a = 0.25", "RPR"),
    "prp": ("", "a = 0.2\nalpha = 0.7", "", "PRP"),
    "ppp": ('alpha = "-pi/2"', 'theta = "pi/2"\nalpha = 0.3', "", "PPP"),
}
BRANCHES = {"cylindrical": 2, "stanford": 4, "ppr": 2, "prr_parallel": 2, "prr_meeting": 4, "rrp_parallel": 2,
            "rpr": 2, "prp": 2, "ppp": 1}


def synthetic_text(name):
    *fields, kinds = SYNTHETIC[name]
    joints = "".join(f"[[joint]]\ntype = \"{k}\"\n{f}\n" + ("limits = [0, 0.5]\n" if k == "P" else "")
                     for k, f in zip(kinds, fields))
    return f'name = "synthetic_{name}"\nconvention = "standard"\ntask = ["x", "y", "z"]\n{joints}' \
           "[tool]\nxyz = [0.05, 0.02, 0.1]\n"


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def configurations(types, limits, seed):
    rng = np.random.default_rng(seed)
    count = RANDOM + DEGENERATE
    q = np.empty((count, len(types)))
    for i, (kind, lim) in enumerate(zip(types, limits)):
        if kind == "R":
            q[:, i] = rng.uniform(-math.pi, math.pi, count)  # the whole turn, limits or not
            q[RANDOM:, i] = rng.choice([0.0, math.pi / 2, -math.pi / 2, math.pi], DEGENERATE)
        else:
            low, high = lim
            q[:, i] = rng.uniform(low, high, count)
            q[RANDOM:, i] = rng.choice([low, (low + high) / 2, high], DEGENERATE)
    return q


_COMPILED: dict = {}


def _compiled(expr):
    """``expr`` as a numpy function of its free symbols (sorted by name), compiled once: the branches
    of an arm share most of their steps' expressions (with other values behind their symbols)."""
    if expr not in _COMPILED:
        names = sorted(expr.free_symbols, key=str)
        _COMPILED[expr] = names, sp.lambdify(names, expr, modules=MODULES)
    return _COMPILED[expr]


def evaluate_steps(model, branch, x, extra=None):
    """The branch's joint values and existence at targets x (N, m), step by step in numpy, as
    test_auto_ik.evaluate_steps does, each distinct expression compiled once."""
    values = {s: x[:, i] for i, s in enumerate(model.task_symbols)}
    values.update(extra or {})
    values.update({p: np.full(len(x), float(v)) for p, v in model.params.items()})

    def value(expr):
        names, function = _compiled(expr)
        return np.broadcast_to(np.asarray(function(*(values[n] for n in names)), dtype=float), (len(x),))
    for symbol, expr in branch.steps:
        values[symbol] = value(expr)

    def truth(c):   # And of the roots' conditions; a root's own is an Or where its angle can be free
        if c is sp.true:
            return np.ones(len(x), bool)
        if isinstance(c, (sp.And, sp.Or)):
            parts = [truth(a) for a in c.args]
            return np.logical_and.reduce(parts) if isinstance(c, sp.And) else np.logical_or.reduce(parts)
        return COMPARE[type(c)](value(c.lhs), value(c.rhs))
    valid = truth(branch.step_condition)
    Q = np.stack([np.broadcast_to(values[q], (len(x),)) for q in model.q], axis=-1)
    return Q, valid & np.isfinite(Q).all(axis=-1)


def counts(model, q, target_of, free=None, free_joints=None):
    """(wrong, no solution, missing, worst error) of the model's branches, from their steps, against
    ``target_of(q)`` (this file's own task); ``free_joints(q, Q)`` masks what a singular q leaves free."""
    x = target_of(q)
    extra = {} if free is None else {model.q[free]: q[:, free]}
    revolute = [i for i, kind in enumerate(model.joint_types) if kind == "R"]
    angles = [i for i, name in enumerate(model.task_names) if name in ("pitch", "roll")]
    found, any_valid, worst, wrong = np.zeros(len(q), bool), np.zeros(len(q), bool), 0.0, 0
    free_mask = None if free_joints is None else free_joints(q)
    for branch in model.ik:
        Q, valid = evaluate_steps(model, branch, x, extra)
        reached = target_of(np.where(valid[:, None], Q, 0.0))
        miss = reached - x
        miss[:, angles] = wrap(miss[:, angles])
        error = np.where(valid, np.abs(miss).max(axis=-1), 0.0)
        worst, wrong = max(worst, float(error.max())), wrong + int((error > FK_TOLERANCE).sum())
        difference = Q - q
        difference[:, revolute] = wrap(difference[:, revolute])
        difference = np.abs(difference)
        if free_mask is not None:
            difference[free_mask] = 0.0
        found |= valid & (difference.max(axis=-1) < JOINT_TOLERANCE)
        any_valid |= valid
    return {"wrong": wrong, "no solution": int((~any_valid).sum()), "missing": int((~found).sum())}, worst


# --------------------------------------------------------------------------- three-joint position arms

POSITION_ARMS = ["cylindrical", "stanford", *SYNTHETIC]


@pytest.mark.parametrize("name", POSITION_ARMS)
def test_three_joint_position_arms_with_prismatic_joints(name, tmp_path):
    text = {"cylindrical": CYLINDRICAL, "stanford": STANFORD}.get(name) or synthetic_text(name)
    path = tmp_path / f"{name}.toml"
    path.write_text("# " + name + "\n" + text)
    model = derivations.load(path)
    arm = read_arm(path)
    assert model.ik_plan[0] == "family: position", model.ik_unsupported
    assert len(model.ik) == BRANCHES[name] and len({b.name for b in model.ik}) == BRANCHES[name]
    q = configurations(arm.types, arm.limits, 26)
    result, worst = counts(model, q, lambda joints: dh_fk(arm, joints)[..., :3, 3])
    assert result == {"wrong": 0, "no solution": 0, "missing": 0}, (result, worst)


def test_a_prismatic_position_arm_that_cannot_lift_says_so(tmp_path):
    """Two slides whose plane holds the third joint's axis turn and slide the point within a plane:
    no closed form, and the message says why."""
    path = tmp_path / "flat.toml"
    path.write_text('name = "flat"\ntask = ["x", "y", "z"]\n[[joint]]\ntype = "P"\nalpha = "-pi/2"\n'
                    '[[joint]]\ntype = "P"\ntheta = "pi/2"\nalpha = "pi/2"\n[[joint]]\ntype = "R"\na = 0.3\n')
    model = derivations.load(path)
    assert not model.ik and "cannot place it in space" in model.ik_unsupported


# --------------------------------------------------------------------------- pitch, roll, approach

def dh_axes(arm, q):
    """World z axes of the joints (standard: frame i-1, modified: frame i), (count, n, 3)."""
    frames = link_frames(arm, q)
    shift = 0 if arm.convention == "standard" else 1
    return np.stack([frames[i + shift][..., :3, 2] for i in range(arm.n)], axis=-2)


def pitch_of(axes, q, joints=(1, 2, 3)):
    """The turn of the parallel joints about the first one's axis: sum of sign(h_i . h_first) q_i."""
    first = axes[:, joints[0]]
    return sum(np.sign(np.sum(axes[:, j] * first, axis=-1)) * q[:, j] for j in joints)


def xml_walk(chain, q):
    """``XmlChain.walk`` for a batch q (count, n): the tip transforms (count, 4, 4) and the world
    axes of the moving joints (count, n, 3), from the chain's own origins and axes (no mimic joints)."""
    value = {name: q[:, i] for i, name in enumerate(chain.moving)}
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    axes = []
    for joint in chain.joints:
        T = T @ chain._origin(joint)
        if joint.get("type") == "fixed":
            continue
        assert joint.find("mimic") is None
        axis = chain._axis(joint)
        axes.append(T[:, :3, :3] @ axis)
        angle = value[joint.get("name")]
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        motion = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        if joint.get("type") == "prismatic":
            motion[:, :3, 3] = angle[:, None] * axis
        else:
            motion[:, :3, :3] = (np.eye(3) + np.sin(angle)[:, None, None] * K
                                 + (1 - np.cos(angle))[:, None, None] * (K @ K))
        T = T @ motion
    return T, np.stack(axes, axis=1)


def test_the_batched_walk_is_the_chains_own():
    chain = XmlChain(ZOO["so101"].path, ZOO["so101"].base, ZOO["so101"].tip)
    q = chain.configurations(5, 3)
    T, axes = xml_walk(chain, q)
    for k, row in enumerate(q):
        tip, moving = chain.walk(row)
        assert np.allclose(T[k], tip, atol=1e-14)
        assert np.allclose(axes[k], [axis for _, _, _, axis, _ in moving], atol=1e-14)


@functools.lru_cache(maxsize=None)
def urdf_chain(name):
    """The zoo arm's chain read by ElementTree, with the angles and axes the model snapped."""
    arm = ZOO[name]
    notes = derivations.load(arm.path, base=arm.base, tip=arm.tip, dynamics=False).notes.get("snapped", "")
    chain = XmlChain(arm.path, arm.base, arm.tip)
    rpy, axes = snapped_numbers(notes, chain)
    return XmlChain(arm.path, arm.base, arm.tip, rpy=rpy, axes=axes)


class Case:
    """One real arm with a task it reaches in full: how to load its model, its own fk's task
    (``target(q)``), its free joint, and what a singular configuration leaves free."""

    def __init__(self, title, source, family, branches, load, types, target, free=None, free_joints=None,
                 limits=None, cli=()):
        self.title, self.source, self.family, self.branches = title, source, family, branches
        self.load, self.types, self.target, self.free = load, types, target, free
        self.free_joints, self.limits, self.cli = free_joints, limits or [None] * len(types), cli

    def model(self):
        path, options = self.load
        return derivations.load(path, **options)


def _dh_case(name, task, title, family, branches, approach_singular=None):
    arm = ARMS[name]

    def target(q):
        T = dh_fk(arm, q)
        if task == "x,y,z,pitch":
            return np.concatenate([T[..., :3, 3], pitch_of(dh_axes(arm, q), q)[:, None]], axis=-1)
        return np.concatenate([T[..., :3, 3], T[..., :3, 2]], axis=-1)

    def free_joints(q):
        joints, axis = approach_singular
        singular = np.abs(np.cross(dh_axes(arm, q)[:, axis], dh_fk(arm, q)[..., :3, 2])).max(axis=-1) < SINGULAR
        mask = np.zeros(q.shape, bool)
        mask[np.ix_(singular, joints)] = True
        if axis == 3:  # a spherical wrist: with its centre on axis 1, q1 is free and q4, q5 follow it
            z1, o1, centre = wrist_geometry(arm, q, 3)
            offset = centre - o1
            across = offset - z1 * np.sum(offset * z1, axis=-1, keepdims=True)
            mask[np.ix_(np.linalg.norm(across, axis=-1) <= SINGULAR, [0, 3, 4])] = True
        return mask
    return Case(title, arm.path.read_text().splitlines()[1].lstrip("# "), family, branches,
                (arm.path, {"task": task}), arm.types, target, free=5 if "approach" in task else None,
                free_joints=free_joints if approach_singular else None, limits=arm.limits,
                cli=(str(arm.path.relative_to(ROOT)), "--task", task))


def _urdf_case(name, task, title, family, free=None):
    arm = ZOO[name]

    def target(q):
        T, axes = xml_walk(urdf_chain(name), q)
        parts = [T[:, :3, 3], pitch_of(axes, q)[:, None]]
        if "roll" in task:
            parts.append(wrap(q[:, 4:5]))
        return np.concatenate(parts, axis=-1)
    # kinematics only (the files' inertials give dynamics kernels, tested in test_dynamics.py)
    return Case(title, f"{arm.file}, {arm.source}", family, 4,
                (arm.path, dict(base=arm.base, tip=arm.tip, task=task, dynamics=False)), ["R"] * arm.joints, target,
                free=free, cli=(str(arm.path.relative_to(ROOT)), "--base", arm.base, "--tip", arm.tip, "--task", task,
                     "--no-dynamics"))


SPINDLE = ROOT / "tests" / "data" / "urdf" / "so101_spindle.toml"


def _spindle_case():
    """The SO-101 to its gripper_link with the tool of so101_spindle.toml (5 cm along the roll axis,
    turned by pi/2 about x): five joints, x, y, z, approach."""
    tool = np.eye(4)
    tool[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]   # Rx(pi/2)
    tool[:3, 3] = [0, 0, 0.05]
    zoo = ZOO["so101"]

    @functools.lru_cache(maxsize=None)
    def chain():
        notes = derivations.load(SPINDLE, dynamics=False).notes.get("snapped", "")
        plain = XmlChain(zoo.path, zoo.base, "gripper_link")
        rpy, axes = snapped_numbers(notes, plain)
        return XmlChain(zoo.path, zoo.base, "gripper_link", rpy=rpy, axes=axes)

    def frames(q):
        return xml_walk(chain(), q)[0] @ tool

    def target(q):
        T = frames(q)
        return np.concatenate([T[:, :3, 3], T[:, :3, 2]], axis=-1)

    def free_joints(q):
        # the approach along the pitch axes 2 to 4: their turns trade against each other, free
        axis2 = xml_walk(chain(), q)[1][:, 1]
        singular = np.abs(np.cross(axis2, frames(q)[:, :3, 2])).max(axis=-1) < SINGULAR
        mask = np.zeros(q.shape, bool)
        mask[np.ix_(singular, [1, 2, 3])] = True
        return mask
    return Case("SO-101 with a tool across its roll (URDF)", "tests/data/urdf/so101_spindle.toml",
                "position and approach", 8, (SPINDLE, {"dynamics": False}), ["R"] * 5, target,
                free_joints=free_joints, cli=(str(SPINDLE.relative_to(ROOT)), "--no-dynamics"))


# The real arms of this file, with the task each reaches in full.  At the approach families' singular
# configurations the solutions form a continuum: with the approach along axis 4 (a spherical wrist at
# q5 = 0 or pi) q4 turns the tool about it, and with the wrist centre on axis 1 q1 turns it all
# (q4 and q5 following); with the approach along the parallel axes 2 to 4 (a UR) their turns trade
# against each other.  There "missing" asks only for the other joints.
CASES = {
    "al5d_dh": _dh_case("lynxmotion_al5d", "x,y,z,pitch", "Lynxmotion AL5D (DH)", "position and pitch", 4),
    "al5d_urdf": _urdf_case("al5d", "x,y,z,pitch", "Lynxmotion AL5D (URDF)", "position and pitch"),
    "so101_urdf": _urdf_case("so101", "x,y,z,pitch,roll", "SO-101 (URDF)", "position, pitch and roll"),
    "so101_free_roll": _urdf_case("so101", "x,y,z,pitch", "SO-101 (URDF), roll free", "position and pitch, joint 5 free",
                                  free=4),
    "so101_spindle": _spindle_case(),
    "ur5_approach": _dh_case("ur5", "x,y,z,approach", "UR5, approach", "position and approach, joint 6 free", 8,
                             approach_singular=([1, 2, 3], 1)),
    "kr5_approach": _dh_case("kuka_kr5", "x,y,z,approach", "KUKA KR5, approach", "position and approach, joint 6 free",
                             8, approach_singular=([3], 3)),
    "stanford_approach": _dh_case("stanford_arm", "x,y,z,approach", "Stanford arm, approach",
                                  "position and approach, joint 6 free", 8, approach_singular=([3], 3)),
    "fanuc_approach": _dh_case("fanuc_lrmate200ic", "x,y,z,approach", "Fanuc LR Mate 200iC, approach",
                               "position and approach, joint 6 free", 8, approach_singular=([3], 3)),
}


@pytest.mark.parametrize("name", list(CASES))
def test_real_arms_with_the_task_they_reach_in_full(name):
    """x, y, z, pitch (4 joints), x, y, z, pitch, roll (5 joints), and IKFast's TranslationDirection5D on
    six-joint arms turning a tool about its approach (joint 6 is ik's argument ``free``)."""
    case = CASES[name]
    model = case.model()
    assert model.ik_plan[0] == f"family: {case.family}" and len(model.ik) == case.branches
    assert model.ik_free == case.free
    assert model.ik_function().name == "ik"  # the kernel's program: every step of a branch named once
    q = configurations(case.types, case.limits, zlib.crc32(name.encode()))
    result, worst = counts(model, q, case.target, free=case.free, free_joints=case.free_joints)
    assert result == {"wrong": 0, "no solution": 0, "missing": 0}, (result, worst)


# --------------------------------------------------------------------------- choosing the task

def test_a_short_arm_with_the_default_pose_is_told_the_task_it_reaches():
    """The AL5D and SO-101 URDFs (whose default task is the pose) get no closed form for it, and the
    message names the task that has one and how to ask for it."""
    arm = ZOO["al5d"]
    model = derivations.load(arm.path, base=arm.base, tip=arm.tip, dynamics=False)
    assert "6 degrees of freedom and the arm 4 joints" in model.ik_unsupported
    assert "closed form for the task x, y, z, pitch" in model.ik_unsupported
    assert "--task x,y,z,pitch" in model.ik_unsupported
    arm = ZOO["so101"]
    model = derivations.load(arm.path, base=arm.base, tip=arm.tip, dynamics=False)
    assert "--task x,y,z,pitch,roll" in model.ik_unsupported


def test_a_toml_description_chooses_the_task(tmp_path):
    text = ARMS["lynxmotion_al5d"].path.read_text().replace('task = ["x", "y", "z"]', 'task = ["x", "y", "z", "pitch"]')
    path = tmp_path / "lynxmotion_al5d.toml"
    path.write_text(text)
    model = derivations.load(path)
    assert model.task_names == ("x", "y", "z", "pitch") and model.ik_plan[0] == "family: position and pitch"


def kinegen(*args):
    return subprocess.run([sys.executable, "-m", "codegen", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.parametrize("task, message", [
    ("x,y,w", "task: unknown task coordinate 'w' (expected x, y, z, phi, pitch, roll, approach or pose)"),
    ("x,,", "task: expected names separated by commas, such as x,y,z,pitch (got 'x,,')"),
    ("x,y,z,pose", "task: 'x' is asked for twice"),
    ("x,y,z,approach", "task x,y,z,approach: the task x, y, z, approach has 5 degrees of freedom and the arm 4 joints"),
])
def test_a_task_the_arm_cannot_reach_or_that_is_no_task_is_refused(task, message):
    with pytest.raises(derivations.DescriptionError, match="lynxmotion_al5d.toml: " + re.escape(message)):
        derivations.load(ARMS["lynxmotion_al5d"].path, task=task)


@pytest.mark.parametrize("task, message", [
    ("x,y,z,roll", "task coordinate 'roll' needs the last joint revolute (a wrist roll)"),
    ("x,y,z,pitch", "task coordinate 'pitch' needs two or more consecutive revolute joints with parallel axes"),
])
def test_a_task_coordinate_the_chain_does_not_have_is_the_inputs_fault(task, message, tmp_path):
    """The README's cylindrical arm (R P P) has no wrist roll and no parallel pitch joints, and the AL5D
    is no planar arm: a DescriptionError naming the file and the task (exit status 2 from the CLI),
    not a crash."""
    path = tmp_path / "cylindrical_rpp.toml"
    path.write_text("# Kumar, Fig. 10\n" + CYLINDRICAL)
    with pytest.raises(derivations.DescriptionError, match=f"cylindrical_rpp.toml: task {task}: {re.escape(message)}"):
        derivations.load(path, task=task)
    with pytest.raises(derivations.DescriptionError, match="lynxmotion_al5d.toml: task x,y,phi: task coordinate 'phi' "
                                                           "needs every revolute axis parallel to the base z axis"):
        derivations.load(ARMS["lynxmotion_al5d"].path, task="x,y,phi")


def test_the_cli_refuses_a_task_the_arm_cannot_reach_with_status_2():
    """The SO-101's approach (the z axis of gripper_link) lies along its wrist roll: joint 5 changes
    neither position nor approach, so x, y, z, approach is reached only on a 4-dimensional set."""
    result = kinegen("show", "tests/data/urdf/zoo/so101.urdf", "--tip", "gripper_link", "--task", "x,y,z,approach",
                     "--no-dynamics", "--what", "ik")
    assert result.returncode == 2, result.stderr
    assert "the approach lies along axis 5" in result.stderr and "x, y, z, pitch, roll" in result.stderr, result.stderr


def test_generate_with_a_task_gives_a_package_whose_c_and_numpy_ik_agree(tmp_path):
    """The README's cylindrical arm generated and built: ik in both backends, against this file's fk."""
    path = tmp_path / "cylindrical_rpp.toml"
    path.write_text("# Kumar, Fig. 10\n" + CYLINDRICAL)
    out = tmp_path / "cylindrical_rpp"
    result = kinegen("--quiet", "generate", str(path), "--out", str(out))
    assert result.returncode == 0, result.stderr
    sys.path.insert(0, str(tmp_path))
    try:
        import cylindrical_rpp
    finally:
        sys.path.remove(str(tmp_path))
    arm = read_arm(path)
    assert cylindrical_rpp.IK_METHOD == "position"
    q = configurations(arm.types, arm.limits, 9)
    x = dh_fk(arm, q)[..., :3, 3]
    for backend in ("numpy", "c"):
        Q, valid = cylindrical_rpp.load(backend).ik(x)
        assert valid.any(axis=-1).all()
        reached = dh_fk(arm, np.where(valid[..., None], Q, 0.0))[..., :3, 3]
        assert np.where(valid, np.abs(reached - x[:, None]).max(axis=-1), 0).max() < FK_TOLERANCE


def test_ik_numeric_wraps_the_pitch_of_its_residual(tmp_path):
    """ik_numeric's residual wraps the task's angles (phi, pitch, roll), in both backends: a target
    whose pitch is written in (-pi, pi] while task(q) gives it 2 pi higher is already reached at q, so
    from q as the seed the solver stays there (unwrapped, it would turn the pitch joints by 2 pi)."""
    path = tmp_path / "lynxmotion_al5d.toml"
    path.write_text(ARMS["lynxmotion_al5d"].path.read_text().replace('task = ["x", "y", "z"]',
                                                                     'task = ["x", "y", "z", "pitch"]'))
    out = tmp_path / "al5d_pitch"
    from codegen import build, generate
    model = derivations.load(path, dynamics=False)
    files = generate.render_robot(model, path, latex=False)  # the package without its LaTeX (5 s of LaTeX)
    generate.write_package(model, path, out, files=files, build=lambda folder: build.build_package(folder, model.name))
    sys.path.insert(0, str(tmp_path))
    try:
        import al5d_pitch
    finally:
        sys.path.remove(str(tmp_path))
    q = np.random.default_rng(5).uniform(-3.0, 3.0, (400, 4))
    q = q[np.abs(al5d_pitch.load("numpy").task(q)[:, 3]) > np.pi + 0.2][:20]  # task(q) gives the pitch beyond pi
    assert len(q) == 20
    for backend in ("numpy", "c"):
        kernels = al5d_pitch.load(backend)
        x = kernels.task(q)
        x[:, 3] = np.arctan2(np.sin(x[:, 3]), np.cos(x[:, 3]))  # the same pitch, written in (-pi, pi]
        found, converged = kernels.ik_numeric(x, q)
        assert converged.all() and np.abs(found - q).max() < 1e-9, (backend, found - q)

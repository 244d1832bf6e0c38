"""Branch names by geometry (issue #26, item 5; docs/ik.md, "Branch names").

The automatic branches are named ``shoulder_{right,left}_elbow_{up,down}_wrist_{noflip,flip}`` (the
parts an arm has).  Here, for real arms of several families, every valid answer of every branch at a
few hundred random targets is put through this file's own forward kinematics (the DH product of
``test_zoo``, or the URDF read with ElementTree as ``urdf_zoo.XmlChain`` reads it), the words are
computed again from those frames by the definitions of docs/ik.md, written out below, and compared
with the branch's name.  The branches are evaluated from their SymPy steps (``test_auto_ik``'s
``evaluate_steps``, lambdify), not by the naming code's own evaluator.

The papers' Puma 560 and planar arms keep their hand-written branches; the automatic decomposition of
them is named here by the same words, and each automatic branch is the hand-written branch of the same
name (right = right, elbow up = elbow up, noflip = noflip), which ties the definitions to Paul's.
"""
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "formats"))
import derivations  # noqa: E402
import generated  # noqa: E402
from derivations.ik import solve  # noqa: E402
from test_auto_ik import evaluate_steps, wrap  # noqa: E402
from test_ik_short_chains import CASES, SPINDLE, ZOO, XmlChain, snapped_numbers, urdf_chain  # noqa: E402
from test_zoo import ARMS, fk as dh_fk, link_frames  # noqa: E402

COUNT = 300
DEGENERATE = 1e-6   # a predicate this close to zero (relative to the arm's size) names nothing
UP = np.array([0.0, 0.0, 1.0])


# --------------------------------------------------------------------------- the arms' own frames

def dh_lines(arm, q):
    """(directions, points) of every joint's axis (count, n, 3) and the tool transforms (count, 4, 4):
    joint i turns about z of frame i-1 (standard DH) or of frame i (modified)."""
    frames = link_frames(arm, q)
    shift = 0 if arm.convention == "standard" else 1
    h = np.stack([frames[i + shift][..., :3, 2] for i in range(arm.n)], axis=-2)
    p = np.stack([frames[i + shift][..., :3, 3] for i in range(arm.n)], axis=-2)
    return h, p, dh_fk(arm, q)


def xml_lines(chain, q):
    """The same for a URDF chain: each moving joint's axis in the world at its origin, and the tip."""
    value = {name: q[:, i] for i, name in enumerate(chain.moving)}
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    h, p = [], []
    for joint in chain.joints:
        T = T @ chain._origin(joint)
        if joint.get("type") == "fixed":
            continue
        axis = chain._axis(joint)
        h.append(T[:, :3, :3] @ axis)
        p.append(T[:, :3, 3].copy())
        angle = value[joint.get("name")]
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        motion = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        motion[:, :3, :3] = np.eye(3) + np.sin(angle)[:, None, None] * K + (1 - np.cos(angle))[:, None, None] * (K @ K)
        T = T @ motion
    return np.stack(h, axis=1), np.stack(p, axis=1), T


def dot(a, b):
    return np.sum(a * b, axis=-1)


def nearest_on(p, h, point):
    """The point of the line (p, h) nearest ``point`` (arrays of (count, 3))."""
    return p + h * dot(point - p, h)[..., None]


def meeting(p1, h1, p2, h2):
    """The point of line 1 nearest line 2 (their meeting point where they meet)."""
    w = p1 - p2
    b = dot(h1, h2)
    s = (b * dot(h2, w) - dot(h1, w)) / np.maximum(1 - b * b, 1e-300)
    return p1 + h1 * s[..., None]


# --------------------------------------------------------------------------- the words, from the frames

class Parts:
    """Which joints are an arm's shoulder, elbow and wrist (0-based, in the chain), and its wrist centre."""

    def __init__(self, axes, wrist_centre, elbow_point, approach=False, planar=False):
        self.axes, self.wrist_centre, self.elbow_point = axes, wrist_centre, elbow_point
        self.approach, self.planar = approach, planar


def words(parts: Parts, lines, home_lines) -> dict:
    """{part: +1 (right, up, noflip) / -1 / 0 (degenerate)} per configuration, by docs/ik.md's definitions."""
    h, p, T = lines
    size = 1.0 + np.abs(home_lines[1][0]).sum() + np.abs(home_lines[2][0][:3, 3]).sum()
    a = parts.axes
    out = {}

    def sign(value, scale):
        return np.where(np.abs(value) > DEGENERATE * scale, np.sign(value), 0.0)

    if parts.planar:  # every axis along z: the elbow left of the shoulder-wrist line seen from above
        S, E = p[:, a[0]], p[:, a[1]]
        V = parts.elbow_point(h, p, T, S)
        out["elbow"] = sign(np.cross(V - S, E - S)[:, 2], size**2)
        return out

    def frame(h, p, T):
        u = h[:, a[0]] * np.sign(dot(home_lines[0][:, a[0]], UP))[:, None]
        S = meeting(p[:, a[1]], h[:, a[1]], p[:, a[0]], h[:, a[0]])
        E = nearest_on(p[:, a[2]], h[:, a[2]], S)
        W = parts.wrist_centre(h, p, T)
        V = parts.elbow_point(h, p, T, S)
        across = np.cross(h[:, a[1]], u)
        across = across - u * dot(across, u)[:, None]
        across /= np.linalg.norm(across, axis=-1, keepdims=True)
        return u, S, E, W, V, across
    u0, S0, E0, W0, V0, across0 = frame(*home_lines)
    # forward: across u and the shoulder axis, towards the wrist centre at q = 0 (else the elbow)
    ahead0 = dot(W0 - home_lines[1][:, a[0]], across0)
    if abs(ahead0[0]) < 1e-9:
        ahead0 = dot(E0 - home_lines[1][:, a[0]], across0)
    s_forward = np.sign(ahead0[0]) if abs(ahead0[0]) > 1e-9 else 1.0
    forward0 = s_forward * across0
    elbow_sense = np.sign(dot(home_lines[0][:, a[2]], np.cross(forward0, u0))[0])

    u, S, E, W, V, across = frame(h, p, T)
    forward = s_forward * across
    ahead = dot(W - p[:, a[0]], forward)
    out["shoulder"] = sign(ahead, size)
    n = h[:, a[2]] * (elbow_sense * out["shoulder"])[:, None]     # the elbow axis along reach x up
    out["elbow"] = sign(dot(np.cross(V - S, E - S), n), size**2)
    if len(a) >= 5:
        h4, h5 = h[:, a[3]], h[:, a[4]]
        h6 = T[:, :3, 2] if parts.approach or len(a) < 6 else h[:, a[5]]
        out["wrist"] = sign(dot(np.cross(h4, h6), h5), 1.0)
    return out


def spherical_wrist(first):
    return lambda h, p, T: meeting(p[:, first], h[:, first], p[:, first + 1], h[:, first + 1])


def point_of_axis(i):
    return lambda h, p, T, S: nearest_on(p[:, i], h[:, i], S)


def same_as(centre):
    return lambda h, p, T, S: centre(h, p, T)


def tool_point(h, p, T, *_):
    return T[:, :3, 3]


def approach_meets(i):
    """Where the tool's approach line (its z axis through the tool point) meets axis i."""
    return lambda h, p, T: meeting(p[:, i], h[:, i], T[:, :3, 3], T[:, :3, 2])


WRIST_46 = spherical_wrist(3)
ARMS_NAMED = {  # name: (how to load it, its own fk, the parts, the free joint)
    "kuka_kr5": ("dh", Parts([0, 1, 2, 3, 4, 5], WRIST_46, same_as(WRIST_46)), None),
    "abb_irb140": ("dh", Parts([0, 1, 2, 3, 4, 5], WRIST_46, same_as(WRIST_46)), None),
    "ur5": ("dh", Parts([0, 1, 2, 3, 4, 5], spherical_wrist(4), point_of_axis(3)), None),
    "ur3_inverted": ("dh", Parts([0, 1, 2, 3, 4, 5], spherical_wrist(4), point_of_axis(3)), None),
    "kuka_lwr4": ("dh", Parts([0, 1, 3, 4, 5, 6], spherical_wrist(4), same_as(spherical_wrist(4))), 2),
    "stanford_arm": ("dh", Parts([0, 1, 2, 3, 4, 5], WRIST_46, same_as(WRIST_46)), None),
    "adept_cobra600": ("dh", Parts([0, 1], None, lambda h, p, T, S: p[:, 3], planar=True), None),
    "al5d_dh": ("case", Parts([0, 1, 2, 3], tool_point, point_of_axis(3)), None),
    "al5d_urdf": ("case", Parts([0, 1, 2, 3], tool_point, point_of_axis(3)), None),
    "so101_urdf": ("case", Parts([0, 1, 2, 3], tool_point, point_of_axis(3)), None),
    "ur5_approach": ("case", Parts([0, 1, 2, 3, 4], approach_meets(4), point_of_axis(3), approach=True), 5),
    "kr5_approach": ("case", Parts([0, 1, 2, 3, 4], approach_meets(4), same_as(approach_meets(4)), approach=True),
                     5),
    "so101_spindle": ("case", Parts([0, 1, 2, 3, 4], approach_meets(4), point_of_axis(3), approach=True), None),
}
EXPECTED = {"shoulder": ("right", "left"), "elbow": ("up", "down"), "wrist": ("noflip", "flip")}


def setup(name):
    """(model, configurations (count, n), targets (count, m), lines(q))."""
    kind, parts, free = ARMS_NAMED[name]
    rng = np.random.default_rng(zlib.crc32(f"branch names {name}".encode()))
    if kind == "dh":
        arm = ARMS[name]
        model = derivations.load(arm.path)
        limits = arm.limits
        lines = lambda q: dh_lines(arm, q)  # noqa: E731
    else:
        case = CASES[name]
        model = case.model()
        limits = case.limits
        if name.endswith("_urdf"):
            chain = urdf_chain({"al5d_urdf": "al5d", "so101_urdf": "so101"}[name])
            lines = lambda q: xml_lines(chain, q)  # noqa: E731
        elif name == "so101_spindle":
            tool = np.eye(4)
            tool[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
            tool[:3, 3] = [0, 0, 0.05]
            notes = derivations.load(SPINDLE, dynamics=False).notes.get("snapped", "")
            plain = XmlChain(ZOO["so101"].path, ZOO["so101"].base, "gripper_link")
            rpy, axes = snapped_numbers(notes, plain)
            chain = XmlChain(ZOO["so101"].path, ZOO["so101"].base, "gripper_link", rpy=rpy, axes=axes)

            def lines(q):
                h, p, T = xml_lines(chain, q)
                return h, p, T @ tool
        else:
            arm = ARMS[{"al5d_dh": "lynxmotion_al5d", "ur5_approach": "ur5", "kr5_approach": "kuka_kr5"}[name]]
            lines = lambda q: dh_lines(arm, q)  # noqa: E731
    q = np.stack([rng.uniform(-np.pi, np.pi, COUNT) if t == "R" else rng.uniform(*(lim or (-1, 1)), COUNT)
                  for t, lim in zip(model.joint_types, limits or [None] * model.n)], axis=-1)
    params = [float(v) for v in model.params.values()]
    task = sp.lambdify([model.q, *model.params], list(model.explicit(model.task)), modules="numpy")
    x = np.stack([np.broadcast_to(np.asarray(v, float), (COUNT,)) for v in task(q.T, *params)], axis=-1)
    return model, parts, free, q, x, lines


@pytest.mark.parametrize("name", list(ARMS_NAMED))
def test_each_branch_is_what_its_name_says(name):
    """For every valid answer of every branch at COUNT targets: the shoulder, elbow and wrist words
    computed from this file's own frames are the branch name's (where not degenerate), each word
    of the name is checked on at least half of the answers, and the branches come in the order
    right before left, up before down, noflip before flip."""
    model, parts, free, q, x, lines = setup(name)
    home = lines(np.zeros((1, model.n)))
    extra = {} if free is None else {model.q[free]: q[:, free]}
    names = [b.name for b in model.ik]
    part_names = [[w for w in n.split("_")[::2] if w in EXPECTED] for n in names]
    assert all(parts_ == part_names[0] and parts_ for parts_ in part_names), names
    keys = []
    for branch in model.ik:
        Q, valid = evaluate_steps(model, branch, x, extra)
        assert valid.sum() > COUNT // 2, (branch.name, valid.sum())
        label = dict(zip(branch.name.split("_")[::2], branch.name.split("_")[1::2]))
        got = words(parts, lines(Q[valid]), home)
        for part in part_names[0]:
            expected = 1.0 if label[part] == EXPECTED[part][0] else -1.0
            decided = got[part] != 0
            assert decided.sum() > valid.sum() // 2, (branch.name, part, decided.sum())
            wrong = decided & (got[part] != expected)
            assert not wrong.any(), (branch.name, part, int(wrong.sum()), np.flatnonzero(valid)[wrong][:5])
        keys.append([(EXPECTED.get(part) or ("plus", "minus")).index(label[part]) for part in label])
    assert keys == sorted(keys), names


@pytest.mark.parametrize("name", ["kuka_kr5", "ur5", "kuka_lwr4"])
def test_picking_a_branch_by_name_works_on_every_arm(name):
    """The same line of user code, ``BRANCHES.index("shoulder_left_elbow_up_wrist_noflip")``, picks on a
    KR5 (spherical wrist), a UR5 (three parallel axes) and an LWR 4 (joint 3 free) an answer that
    reaches the target with the shoulder left, the elbow up and the wrist unflipped by this file's frames."""
    model, parts, free, q, x, lines = setup(name)
    branch = model.ik[[b.name for b in model.ik].index("shoulder_left_elbow_up_wrist_noflip")]
    extra = {} if free is None else {model.q[free]: q[:, free]}
    Q, valid = evaluate_steps(model, branch, x, extra)
    assert valid.sum() > COUNT // 2
    h, p, T = lines(Q[valid])
    target = lines(q[valid])[2]
    assert np.abs(T - target).max() < 1e-9
    got = words(parts, (h, p, T), lines(np.zeros((1, model.n))))
    for part, word in (("shoulder", -1.0), ("elbow", 1.0), ("wrist", 1.0)):
        assert np.all(got[part][got[part] != 0] == word), part
        assert (got[part] != 0).sum() > valid.sum() // 2


PAPERS = {"puma560": lambda auto: auto.replace("shoulder_", "").replace("wrist_", ""),
          "planar_2r": lambda auto: auto, "planar_3r": lambda auto: auto}


@pytest.mark.parametrize("name", list(PAPERS))
def test_the_automatic_names_are_the_papers_names(name):
    """The decomposition of the Puma 560 and the planar 2R and 3R, named by geometry, gives each
    hand-written branch under the same words: right (the wrist ahead of the shoulder), elbow up
    (above the shoulder-wrist line), noflip (sin theta5 >= 0); planar: elbow up (q2 <= 0)."""
    model = derivations.load(name)
    kernels = generated.load(name, backend="numpy")
    rng = np.random.default_rng(2611)
    q = np.stack([rng.uniform(-np.pi, np.pi, COUNT) if t == "R" else rng.uniform(*lim, COUNT)
                  for t, lim in zip(kernels.JOINT_TYPES, kernels.LIMITS)], axis=-1)
    x = kernels.task(q)
    Q_hand, valid_hand = kernels.ik(x)
    branches = solve(model).branches
    assert sorted(PAPERS[name](b.name) for b in branches) == sorted(kernels.BRANCHES)
    for branch in branches:
        j = list(kernels.BRANCHES).index(PAPERS[name](branch.name))
        Q, valid = evaluate_steps(model, branch, x)
        both = valid & valid_hand[:, j]
        assert both.sum() > COUNT // 2
        assert np.abs(wrap(Q - Q_hand[:, j]))[both].max() < 1e-6, branch.name


def test_the_names_come_from_the_answers_not_from_what_the_family_called_its_roots():
    """The naming is a step after the solve, from the branches and the chain's axes alone: the KR5's
    branches given meaningless root names in another order (as a family solving the chain from its
    tool end would number its own roots) come back under the same geometric names, in the same order."""
    import dataclasses
    from derivations.ik.branch_names import geometric_names
    from derivations.ik.structure import structure_of
    model = derivations.load(ARMS["kuka_kr5"].path)
    solved = list(model.ik)
    order = [5, 2, 7, 0, 3, 6, 1, 4]
    garbled = [dataclasses.replace(solved[i], name=f"a_{'plus' if k & 1 else 'minus'}_b_{'plus' if k & 2 else 'minus'}"
                                                  f"_c_{'plus' if k & 4 else 'minus'}")
               for k, i in enumerate(order)]
    renamed = geometric_names(model, structure_of(model), list(range(6)), "spherical wrist", garbled)
    assert [b.name for b in renamed] == [b.name for b in solved]
    assert [b.solution for b in renamed] == [b.solution for b in solved]

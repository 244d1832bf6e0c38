"""Inverse kinematics by decomposition into subproblems, for every arm whose axes allow it.

:func:`solve` reads the arm's axes (:mod:`derivations.ik.structure`), picks the first
family below that the axes satisfy, and writes each branch as ordered steps, every
step one subproblem (:mod:`derivations.ik.subproblems`) or a vector carried from one
frame to the next.  With ``G = T M^-1`` the target in product-of-exponentials form
(``T`` the target pose, ``M`` the tool pose at q = 0), ``G = E_1 ... E_n``:

``spherical wrist`` (6 joints, axes 4, 5, 6 meet in the point w): ``E_1 E_2 E_3 w = G w``
    fixes joints 1 to 3 (a position problem, below); then
    ``R_4 R_5 R_6 = (R_1 R_2 R_3)^T G_R``: joint 4 puts ``R_4^T v`` (``v`` the image of
    h6) at height ``h5 . h6`` along h5 (subproblem 4; ``atan2 +- pi/2`` for an
    orthogonal wrist), joint 5 turns h6 onto it and joint 6 turns h5 onto what is left
    (subproblem 1 each).  Branches: 2 x 2 x 2.
``three parallel`` (6 revolute joints, axes 2, 3, 4 parallel, axes 5 and 6 meet at o;
    the UR family): the height of ``E_1^-1 G o`` along h2 does not depend on joints 2
    to 5, so joint 1 is subproblem 4; joint 5 turns h6 onto the cone that the image of
    h6 defines about h2 (``cone_angle``: no ``acos``); joint 6 and the sum of joints
    2 to 4 are subproblem 1 each; the point on axis 4, now known, is a planar two-link
    problem in joints 2 and 3 (subproblems 3 and 1).  Branches: 2 x 2 x 2.
``position`` (3 joints, the task x, y, z): the position problem on the tool point.
``parallel axes`` (every revolute axis and every prismatic direction along the base z
    axis; the task x, y with z and phi as the joints allow: planar arms and SCARAs):
    the prismatic joint takes the height, the last revolute joint the orientation phi,
    and the first two the position of the point on the last axis (subproblems 3 and 1).

``reversed`` (a six-joint arm, or seven with one held, whose special axes are at the base: a
    spherical shoulder, three parallel axes from the base): read from the tool,
    ``M T^-1 = E_6(-q_6) ... E_1(-q_1)`` is an arm of a family above on the same lines in the
    reverse order (:mod:`derivations.ik.reverse`); its branches end with ``q_{7-k} = -q'_k``.

The position problem of joints 1 to 3 on a point w with target c:

* axes 2 and 3 parallel, axis 1 not: joint 1 by subproblem 4 (the height of
  ``E_1^-1 c`` along h2 is that of w), joint 3 by subproblem 3 (the distance from
  axis 2's point), joint 2 by subproblem 1: branches ``shoulder`` x ``elbow``;
* axes 1 and 2 meet at o: joint 3 by subproblem 3 (revolute) or its slide
  (prismatic) from ``|E_3 w - o| = |c - o|``, then subproblem 2 for joints 2 and 1:
  branches ``elbow`` (or ``slide``) x ``shoulder``.

Each branch name is the sequence of root choices, ``plus`` or ``minus``: the sign of
the ``acos`` (or ``pi/2``, or ``atan2``) term in that joint's root, as the branch's doc
spells out.  A branch is valid where each of its roots exists; the generated code also
marks it invalid where a value is not finite.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp
from sympy.functions.elementary.piecewise import ExprCondPair

from ..chain import PRISMATIC, REVOLUTE
from ..model import APPROACH_NAMES, POSE_NAMES, IKBranch, SubstitutedSteps
from .branch_names import geometric_names
from .primitives import ClampUnit, WrapAngle, written_piecewise
from .reverse import SWAPPED_LABELS, reversed_joints, reversed_structure, reversed_target
from .structure import Axis, Structure, check_product_of_exponentials, cross, dot, is_zero, rotate, structure_of, tidy
from .subproblems import (TINY, angle_onto, angle_to_distance, angle_to_height, cone_angle, distance_coefficients,
                          slide_to_distance)

__all__ = ["IKUnsupported", "TaskUnreachable", "IKSolution", "solve", "attach", "IK_BUDGET", "suggest_task"]


class IKUnsupported(ValueError):
    """The arm's structure is outside every family with a closed form (the message says what it lacks)."""


class TaskUnreachable(IKUnsupported):
    """The arm cannot reach its task in full: the task has more degrees of freedom than the joints give
    it (a pose with 4 joints), or a joint changes none of it."""


@dataclass
class IKSolution:
    family: str
    branches: list[IKBranch]
    plan: list[str]                     # one line per step of the decomposition
    structure: list[str] = field(default_factory=list)
    free: int | None = None             # the 0-based index of the free joint of a seven-joint arm


class _Steps:
    """One branch under construction: ordered scalar steps, root choices, existence conditions."""

    def __init__(self, items=(), choices=(), conditions=(), docs=()):
        self.items = list(items)
        self.choices = list(choices)
        self.conditions = list(conditions)
        self.docs = list(docs)

    def fork(self) -> "_Steps":
        return _Steps(self.items, self.choices, self.conditions, self.docs)

    def scalar(self, name: str, expr):
        expr = sp.sympify(expr)
        if expr.is_Atom:
            return expr
        symbol = sp.Symbol(name, real=True)
        self.items.append((symbol, expr))
        return symbol

    def vector(self, name: str, vec) -> sp.Matrix:
        return sp.Matrix([self.scalar(f"{name}_{c}", e) for c, e in zip("xyz", vec)])

    def joint(self, q, expr):
        self.items.append((q, sp.sympify(expr)))
        return q

    def choose(self, label: str, root, q):
        self.choices.append(f"{label}_{root.name}")
        if root.condition is not sp.true:
            self.conditions.append(root.condition)
        self.docs.append(f"q{q}: {root.doc}")


class _Arm:
    """The axes and the target of one arm, with the vector helpers the families share."""

    def __init__(self, model, structure: Structure, q=None, target=None):
        self.model = model
        self.S = structure
        self.q = tuple(model.q if q is None else q)  # the joint symbol of each axis of ``structure``
        # the pose to reach as (rotation, position) in the task symbols: the task's pose unless the
        # arm is read from its tool (derivations.ik.reverse: the target is then M T^-1)
        self.target = target
        self.plan: list[str] = []

    def axis(self, i):
        return self.S.axes[i]

    def turn(self, i, vec, sign=1):
        """``vec`` turned by joint i's rotation (sign +1) or its inverse (-1), joint i revolute."""
        a = self.axis(i)
        return rotate(a.h, sp.cos(self.q[i]), sign * sp.sin(self.q[i]), vec)

    def move_point(self, i, point, sign=1):
        """``E_i^sign point``: the point moved by joint i (or by its inverse)."""
        a = self.axis(i)
        if a.kind == PRISMATIC:
            return point + a.h * (sign * self.q[i])
        return a.p + self.turn(i, point - a.p, sign)

    def say(self, line: str):
        if line not in self.plan:
            self.plan.append(line)


def _pose_target(arm: _Arm, steps: _Steps):
    """``G = T M^-1`` as (rotation applied to a vector, point map), in the task symbols (a reversed
    arm's target ``M T^-1``, as steps ``g11 .. g33`` and ``g_x .. g_z``)."""
    if arm.target is None:
        x, y, z, *r = arm.model.task_symbols
        R, position = sp.Matrix(3, 3, r), sp.Matrix([x, y, z])
    else:
        R, position = arm.target
        R = sp.Matrix(3, 3, [steps.scalar(f"g{i + 1}{j + 1}", R[i, j]) for i in range(3) for j in range(3)])
        position = steps.vector("g", position)
    home = arm.S.home
    RM, pM = home[:3, :3], home[:3, 3]
    GR = R if RM == sp.eye(3) else (R * RM.T)

    def rotation(vec):
        return GR * sp.Matrix(vec)

    def point(p):
        return rotation(sp.Matrix(p) - pM) + position
    return rotation, point


# --- the position problem of joints 1 to 3 --------------------------------------------------

def _position_parallel_23(arm: _Arm, base: _Steps, w, c) -> list[_Steps]:
    a1, a2, a3 = arm.axis(0), arm.axis(1), arm.axis(2)
    arm.say("q1: subproblem 4, the height of E1^-1 c along h2 equals that of w (axes 2 and 3 parallel)")
    arm.say("q3: subproblem 3, the distance of E3 w from axis 2's point equals that of E1^-1 c")
    arm.say("q2: subproblem 1, turns E3 w onto E1^-1 c about axis 2")
    out = []
    d = tidy(dot(a2.h, w - a1.p))
    for root1 in angle_to_height(c - a1.p, a1.h, a2.h, d):
        s1 = base.fork()
        s1.choose("shoulder", root1, 1)
        s1.joint(arm.q[0], root1.value)
        c1 = s1.vector("c1", arm.move_point(0, c, -1))
        for root3 in angle_to_distance(a3.h, (a3.p - a2.p).applyfunc(tidy), (w - a3.p).applyfunc(tidy),
                                       dot(c1 - a2.p, c1 - a2.p)):
            s3 = s1.fork()
            s3.choose("elbow", root3, 3)
            s3.joint(arm.q[2], root3.value)
            e3 = s3.vector("e3", arm.move_point(2, w))
            s3.joint(arm.q[1], angle_onto(a2.h, e3 - a2.p, c1 - a2.p))
            out.append(s3)
    return out


def _position_meet_12(arm: _Arm, base: _Steps, w, c, o) -> list[_Steps]:
    a1, a2, a3 = arm.axis(0), arm.axis(1), arm.axis(2)
    u_expr = c - o
    if a3.kind == REVOLUTE:
        arm.say("q3: subproblem 3, the distance of E3 w from the point where axes 1 and 2 meet equals that of c")
        roots3 = angle_to_distance(a3.h, (a3.p - o).applyfunc(tidy), (w - a3.p).applyfunc(tidy), dot(u_expr, u_expr))
        label = "elbow"
    else:
        arm.say("q3: the slide that puts w + q3 h3 at the distance of c from the point where axes 1 and 2 meet")
        roots3 = slide_to_distance(a3.h, (w - o).applyfunc(tidy), dot(u_expr, u_expr))
        label = "slide"
    arm.say("q2: subproblem 4 (of subproblem 2), the height of E2 (E3 w - o) along h1 equals that of c - o")
    arm.say("q1: subproblem 1 (of subproblem 2), turns E2 (E3 w - o) onto c - o about axis 1")
    out = []
    for root3 in roots3:
        s3 = base.fork()
        s3.choose(label, root3, 3)
        s3.joint(arm.q[2], root3.value)
        v = s3.vector("e3", arm.move_point(2, w) - o)
        u = s3.vector("u", u_expr)
        for root2 in angle_to_height(a1.h, a2.h, v, dot(a1.h, u)):
            s2 = s3.fork()
            s2.choose("shoulder", root2, 2)
            s2.joint(arm.q[1], root2.value)
            f = s2.vector("f", arm.turn(1, v))
            s2.joint(arm.q[0], angle_onto(a1.h, f, u))
            out.append(s2)
    return out


def _unit(vec) -> sp.Matrix:
    vec = sp.Matrix(vec).applyfunc(tidy)
    norm2 = tidy(dot(vec, vec))
    return vec if norm2 == 1 else (vec / sp.sqrt(norm2)).applyfunc(tidy)


def _solve_slides(steps: _Steps, u, h_a, h_b):
    """(t_a, t_b) with ``t_a h_a + t_b h_b = u`` for unit ``h_a``, ``h_b`` not parallel and ``u`` in
    their plane: the normal equations, ``g = h_a . h_b``."""
    g = tidy(dot(h_a, h_b))
    ua, ub = steps.scalar("ua", dot(u, h_a)), steps.scalar("ub", dot(u, h_b))
    den = tidy(1 - g**2)
    return (ua - g * ub) / den, (ub - g * ua) / den


def _no_lift(arm: _Arm, what: str, i: int, j: int):
    raise IKUnsupported(f"joints {arm.S.kinds[:3]}: the slides of joints {i + 1} and {j + 1} and the turns keep the "
                        f"{what} in a plane or on a surface: three joints of this kind cannot place it in space")


def _position_prismatic(arm: _Arm, base: _Steps, w, c, what: str) -> list[_Steps] | None:
    """Joints 1 to 3 with a prismatic joint among them that carry ``w`` to ``c``, or None if the
    case is not one below.  Each slide ``T_i`` moves every point by ``q_i h_i``; a turn keeps the
    height along its axis and the distance from it, a slide the components across its direction.

    * RPP: ``E1^-1 c = w + q2 h2 + q3 h3``: q1 by subproblem 4 (``E1^-1 c - w`` has no part along
      n = h2 x h3), the slides from the 2 x 2 normal equations; branches ``shoulder``.
    * PPR: ``E3 w = c - q1 h1 - q2 h2``: q3 by subproblem 4 (no part along n = h1 x h2), the slides
      as above; branches ``elbow``.
    * PRR with axes 2 and 3 parallel: q1 from the height along h2 (linear), q3 by subproblem 3,
      q2 by subproblem 1; with axes 2 and 3 meeting at o: q1 the slide that puts ``c - q1 h1`` at
      the distance of w from o, then subproblem 2; branches ``slide`` (x ``elbow``).
    * RRP with axes 1 and 2 parallel: q3 from the height along h1 (linear), q2 by subproblem 3,
      q1 by subproblem 1; branches ``elbow``.  (Axes 1 and 2 meeting: :func:`_position_meet_12`.)
    * RPR with axes 1, 2, 3 parallel: q2 from the height, q3 by subproblem 3, q1 by subproblem 1.
    * PRP with axes 1 and 2 parallel: q3 the slide that puts ``w + q3 h3`` at the distance of c
      from axis 2, q1 from the height along h2, q2 by subproblem 1; branches ``slide``.
    * PPP: the 3 x 3 linear system; one branch ``unique``.
    """
    S = arm.S
    kinds = S.kinds[:3]
    a1, a2, a3 = arm.axis(0), arm.axis(1), arm.axis(2)
    h1, h2, h3 = a1.h, a2.h, a3.h
    out = []
    if kinds == "PPP":
        A = sp.Matrix.hstack(h1, h2, h3)
        det = tidy(A.det())
        if is_zero(det):
            _no_lift(arm, what, 0, 2)
        arm.say(f"q1, q2, q3: the linear system q1 h1 + q2 h2 + q3 h3 = c - w (three slides)")
        inverse = A.adjugate().applyfunc(tidy) / det
        s = base.fork()
        u = s.vector("u", c - w)
        for q, row in zip(arm.q[:3], range(3)):
            s.joint(q, dot(inverse[row, :].T, u))
        s.choices.append("unique")
        return [s]
    if kinds == "RPP":
        if S.parallel(1, 2):
            _no_lift(arm, what, 1, 2)
        n = _unit(cross(h2, h3))
        if S.parallel_to(0, n):
            _no_lift(arm, what, 1, 2)
        arm.say("q1: subproblem 4, E1^-1 c - w has no part along n = h2 x h3 (the slides move in their plane)")
        arm.say("q2, q3: the slides, u = E1^-1 c - w = q2 h2 + q3 h3 (the 2 x 2 normal equations)")
        for root1 in angle_to_height(c - a1.p, h1, n, tidy(dot(n, w - a1.p))):
            s = base.fork()
            s.choose("shoulder", root1, 1)
            s.joint(arm.q[0], root1.value)
            u = s.vector("u", arm.move_point(0, c, -1) - w)
            t2, t3 = _solve_slides(s, u, h2, h3)
            s.joint(arm.q[1], t2)
            s.joint(arm.q[2], t3)
            out.append(s)
        return out
    if kinds == "PPR":
        if S.parallel(0, 1):
            _no_lift(arm, what, 0, 1)
        n = _unit(cross(h1, h2))
        if S.parallel_to(2, n) or S.on_axis(w, 2):
            _no_lift(arm, what, 0, 1)
        arm.say("q3: subproblem 4, E3 w - c has no part along n = h1 x h2 (the slides move in their plane)")
        arm.say("q1, q2: the slides, u = c - E3 w = q1 h1 + q2 h2 (the 2 x 2 normal equations)")
        for root3 in angle_to_height(n, h3, (w - a3.p).applyfunc(tidy), dot(n, c - a3.p)):
            s = base.fork()
            s.choose("elbow", root3, 3)
            s.joint(arm.q[2], root3.value)
            u = s.vector("u", c - arm.move_point(2, w))
            t1, t2 = _solve_slides(s, u, h1, h2)
            s.joint(arm.q[0], t1)
            s.joint(arm.q[1], t2)
            out.append(s)
        return out
    if kinds == "PRR":
        if S.parallel(1, 2):
            lift = tidy(dot(h2, h1))
            if is_zero(lift):
                _no_lift(arm, what, 1, 2)
            arm.say("q1: the slide that gives c - q1 h1 the height of w along h2 (axes 2 and 3 parallel)")
            arm.say("q3: subproblem 3, the distance of E3 w from axis 2's point equals that of c - q1 h1")
            arm.say("q2: subproblem 1, turns E3 w onto c - q1 h1 about axis 2")
            s1 = base.fork()
            s1.joint(arm.q[0], (dot(h2, c - a2.p) - tidy(dot(h2, w - a2.p))) / lift)
            c1 = s1.vector("c1", c - h1 * arm.q[0])
            for root3 in angle_to_distance(h3, (a3.p - a2.p).applyfunc(tidy), (w - a3.p).applyfunc(tidy),
                                           dot(c1 - a2.p, c1 - a2.p)):
                s3 = s1.fork()
                s3.choose("elbow", root3, 3)
                s3.joint(arm.q[2], root3.value)
                e3 = s3.vector("e3", arm.move_point(2, w))
                s3.joint(arm.q[1], angle_onto(h2, e3 - a2.p, c1 - a2.p))
                out.append(s3)
            return out
        o = S.meet(1, 2)
        if o is None:
            return None
        if S.on_axis(w, 2) or S.on_axis(w, 1):
            _no_lift(arm, what, 1, 2)
        arm.say("q1: the slide that puts c - q1 h1 at the distance of w from the point o where axes 2 and 3 meet")
        arm.say("q3: subproblem 4 (of subproblem 2), the height of E3 (w - o) along h2 equals that of c - q1 h1 - o")
        arm.say("q2: subproblem 1 (of subproblem 2), turns E3 (w - o) onto c - q1 h1 - o about axis 2")
        wo = (w - o).applyfunc(tidy)
        for root1 in slide_to_distance(-h1, c - o, tidy(dot(wo, wo))):
            s1 = base.fork()
            s1.choose("slide", root1, 1)
            s1.joint(arm.q[0], root1.value)
            u = s1.vector("u", c - h1 * arm.q[0] - o)
            for root3 in angle_to_height(h2, h3, wo, dot(h2, u)):
                s3 = s1.fork()
                s3.choose("elbow", root3, 3)
                s3.joint(arm.q[2], root3.value)
                f = s3.vector("f", arm.turn(2, wo))
                s3.joint(arm.q[1], angle_onto(h2, f, u))
                out.append(s3)
        return out
    if kinds == "RRP" and S.parallel(0, 1):
        lift = tidy(dot(h1, h3))
        if is_zero(lift):
            _no_lift(arm, what, 0, 2)
        arm.say("q3: the slide that gives w + q3 h3 the height of c along h1 (axes 1 and 2 parallel)")
        arm.say("q2: subproblem 3, the distance of E2 (w + q3 h3) from axis 1's point equals that of c")
        arm.say("q1: subproblem 1, turns E2 (w + q3 h3) onto c about axis 1")
        s = base.fork()
        s.joint(arm.q[2], (dot(h1, c - w)) / lift)
        w3 = s.vector("w3", w + h3 * arm.q[2])
        for root2 in angle_to_distance(h2, (a2.p - a1.p).applyfunc(tidy), w3 - a2.p, dot(c - a1.p, c - a1.p)):
            s2 = s.fork()
            s2.choose("elbow", root2, 2)
            s2.joint(arm.q[1], root2.value)
            e2 = s2.vector("e2", arm.move_point(1, w3))
            s2.joint(arm.q[0], angle_onto(h1, e2 - a1.p, c - a1.p))
            out.append(s2)
        return out
    if kinds == "RPR" and S.parallel(0, 1) and S.parallel(0, 2):
        lift = tidy(dot(h1, h2))
        arm.say("q2: the slide that gives E3 w + q2 h2 the height of c along h1 (axes 1, 2, 3 parallel)")
        arm.say("q3: subproblem 3, the distance of E3 w + q2 h2 from axis 1's point equals that of c")
        arm.say("q1: subproblem 1, turns E3 w + q2 h2 onto c about axis 1")
        s = base.fork()
        s.joint(arm.q[1], (dot(h1, c - w)) / lift)
        for root3 in angle_to_distance(h3, a3.p + h2 * arm.q[1] - a1.p, (w - a3.p).applyfunc(tidy),
                                       dot(c - a1.p, c - a1.p)):
            s3 = s.fork()
            s3.choose("elbow", root3, 3)
            s3.joint(arm.q[2], root3.value)
            e3 = s3.vector("e3", arm.move_point(2, w) + h2 * arm.q[1])
            s3.joint(arm.q[0], angle_onto(h1, e3 - a1.p, c - a1.p))
            out.append(s3)
        return out
    if kinds == "PRP" and S.parallel(0, 1):
        lift = tidy(dot(h2, h1))
        across = (h3 - h2 * tidy(dot(h2, h3))).applyfunc(tidy)
        size2 = tidy(dot(across, across))
        if is_zero(size2):
            _no_lift(arm, what, 0, 2)
        size = sp.sqrt(size2)
        k = (across / size).applyfunc(tidy)
        arm.say("q3: the slide that puts w + q3 h3 at the distance of c from axis 2 (axes 1 and 2 parallel)")
        arm.say("q1: the slide that gives c - q1 h1 the height of w + q3 h3 along h2")
        arm.say("q2: subproblem 1, turns w + q3 h3 onto c - q1 h1 about axis 2")
        a_perp = (w - a2.p) - h2 * dot(h2, w - a2.p)
        rel = c - a2.p
        c_perp = rel - h2 * dot(h2, rel)
        for root3 in slide_to_distance(k, a_perp.applyfunc(tidy), dot(c_perp, c_perp)):
            s = base.fork()
            s.choose("slide", root3, 3)
            s.joint(arm.q[2], root3.value / size)
            w3 = s.vector("w3", w + h3 * arm.q[2])
            s.joint(arm.q[0], dot(h2, c - w3) / lift)
            c1 = s.vector("c1", c - h1 * arm.q[0])
            s.joint(arm.q[1], angle_onto(h2, w3 - a2.p, c1 - a2.p))
            out.append(s)
        return out
    return None


def _position(arm: _Arm, base: _Steps, w, c, what: str) -> list[_Steps]:
    """Joints 1 to 3 that carry the point ``w`` to ``c`` (``what`` names w in messages)."""
    S = arm.S
    kinds = S.kinds[:3]
    if kinds == "RRR" and S.parallel(1, 2) and not S.parallel(0, 1):
        return _position_parallel_23(arm, base, w, c)
    if PRISMATIC in kinds and not (kinds == "RRP" and S.meet(0, 1) is not None):
        found = _position_prismatic(arm, base, w, c, what)
        if found is not None:
            return found
    o = S.meet(0, 1)
    if o is not None and kinds[2] in "RP":
        if kinds[2] == REVOLUTE and S.parallel(1, 2):
            raise IKUnsupported(f"axes 1, 2 and 3 are parallel: they cannot place the {what} in space")
        if kinds[2] == REVOLUTE and (S.meet_in_one_point(0, 1, 2) is not None or S.on_axis(w, 2)):
            # the S of an S-R-S arm held at its elbow: the three axes only turn the point about o
            raise IKUnsupported(f"axes 1, 2 and 3 meet in one point (or axis 3 holds the {what}): they turn the "
                                f"{what} about it, a continuum of solutions, not a finite set")
        return _position_meet_12(arm, base, w, c, o)
    raise IKUnsupported(f"joints 1 to 3 ({kinds}) place the {what}, but axes 2 and 3 are not parallel "
                        "and axes 1 and 2 do not meet")


# --- the families ---------------------------------------------------------------------------

def _spherical_wrist(arm: _Arm, w) -> list[_Steps]:
    a4, a5, a6 = arm.axis(3), arm.axis(4), arm.axis(5)
    base = _Steps()
    rotation, point = _pose_target(arm, base)
    c = base.vector("c", point(w))
    arm.say("c = G w: the wrist centre w (where axes 4, 5 and 6 meet) carried to the target")
    branches = _position(arm, base, w, c, "wrist centre")
    arm.say("q4: subproblem 4, R4^T v (v = (R1 R2 R3)^T G_R h6) at height h5 . h6 along h5"
            + (" (orthogonal wrist: atan2 +- pi/2)" if is_zero(dot(a4.h, a5.h)) and is_zero(dot(a5.h, a6.h)) else ""))
    arm.say("q5: subproblem 1, turns h6 onto R4^T v about axis 5")
    arm.say("q6: subproblem 1, turns h5 onto R5^T R4^T (R1 R2 R3)^T G_R h5 about axis 6")
    out = []
    for s in branches:
        v, x = rotation(a6.h), rotation(a5.h)
        for i in range(3):
            if arm.axis(i).kind == REVOLUTE:
                v = s.vector(f"v{i + 1}", arm.turn(i, v, -1))
                x = s.vector(f"x{i + 1}", arm.turn(i, x, -1))
        for root4 in angle_to_height(v, a4.h, a5.h, tidy(dot(a5.h, a6.h))):
            s4 = s.fork()
            s4.choose("wrist", root4, 4)
            s4.joint(arm.q[3], root4.value)
            v4 = s4.vector("v4", arm.turn(3, v, -1))
            s4.joint(arm.q[4], angle_onto(a5.h, a6.h, v4))
            x5 = s4.vector("x5", arm.turn(4, arm.turn(3, x, -1), -1))
            s4.joint(arm.q[5], angle_onto(a6.h, a5.h, x5))
            out.append(s4)
    return out


def _three_parallel(arm: _Arm, o) -> list[_Steps]:
    S = arm.S
    a1, a2, a3, a4, a5, a6 = S.axes
    base = _Steps()
    rotation, point = _pose_target(arm, base)
    c = base.vector("c", point(o))
    z6 = base.vector("z6", rotation(a6.h))
    n = perpendicular(a2.h)
    cone = is_zero(dot(a2.h, a5.h)) and is_zero(dot(a5.h, a6.h))
    arm.say("c = G o: the point o where axes 5 and 6 meet, carried to the target")
    arm.say("q1: subproblem 4, the height of E1^-1 c along h2 equals that of o (axes 2, 3, 4 parallel)")
    arm.say("q5: " + ("the cone about h2 that R1^T G_R h6 defines, reached by turning h6 about axis 5 "
                      "(atan2 of |h2 x u| and h2 . u: no acos)" if cone else
                      "subproblem 4, the height of R5 h6 along h2 equals that of R1^T G_R h6"))
    arm.say("q6: subproblem 1, turns G_R^T R1 h2 onto R5^T h2 about axis 6; at the wrist singularity "
            "(|h2 x u| < 1e-12) the free q6 that keeps p4 nearest the middle of the elbow's reach (subproblem 3)")
    arm.say("q2 + q3 + q4: subproblem 1, turns n onto R1^T G_R R6^T R5^T n about h2 (n a unit vector "
            "perpendicular to h2)")
    arm.say("q3: subproblem 3, the distance of E3 p4 from axis 2's point equals that of E1^-1 G E6^-1 E5^-1 p4")
    arm.say("q2: subproblem 1, turns E3 p4 onto that point about axis 2; q4 from the sum")
    signs = [tidy(dot(a.h, a2.h)) for a in (a2, a3, a4)]
    out = []
    for root1 in angle_to_height(c - a1.p, a1.h, a2.h, tidy(dot(a2.h, o - a1.p))):
        s1 = base.fork()
        s1.choose("shoulder", root1, 1)
        s1.joint(arm.q[0], root1.value)
        u = s1.vector("u", arm.turn(0, z6, -1))
        roots5 = cone_angle(a2.h, a5.h, a6.h, u) if cone else angle_to_height(a2.h, a5.h, a6.h, dot(a2.h, u))
        for root5 in roots5:
            s5 = s1.fork()
            s5.choose("wrist", root5, 5)
            s5.joint(arm.q[4], root5.value)
            h2_back = s5.vector("k", _transpose_apply(rotation, arm.turn(0, a2.h)))
            regular = angle_onto(a6.h, h2_back, arm.turn(4, a2.h, -1))
            s5.joint(arm.q[5], sp.Piecewise((_free_wrist_angle(arm, s5, rotation, point), _wrist_singular(u, a2.h)),
                                            (regular, True), evaluate=False))
            # R234 = R1^T G_R R6^T R5^T, read on a unit vector n perpendicular to h2: the angle
            # is as well conditioned as it can be at every pose (a vector of the wrist, such
            # as h5, can come to lie along h2 and leave the angle to rounding).
            b = s5.vector("b", arm.turn(0, rotation(arm.turn(5, arm.turn(4, n, -1), -1)), -1))
            total = s5.scalar("theta234", angle_onto(a2.h, n, b))
            p4 = arm.move_point(5, arm.move_point(4, a4.p, -1), -1)
            X4 = s5.vector("X4", point(p4))
            y4 = s5.vector("y4", arm.move_point(0, X4, -1))
            for root3 in angle_to_distance(a3.h, (a3.p - a2.p).applyfunc(tidy), (a4.p - a3.p).applyfunc(tidy),
                                           dot(y4 - a2.p, y4 - a2.p)):
                s3 = s5.fork()
                s3.choose("elbow", root3, 3)
                s3.joint(arm.q[2], root3.value)
                e3 = s3.vector("e3", arm.move_point(2, a4.p))
                s3.joint(arm.q[1], angle_onto(a2.h, e3 - a2.p, y4 - a2.p))
                s3.joint(arm.q[3], signs[2] * (total - signs[0] * arm.q[1] - signs[1] * arm.q[2]))
                out.append(s3)
    return out


# |h2 x u| below this is the wrist singularity of the three-parallel family (q5 at 0 or pi):
# q6 is then free, and chosen by _free_wrist_angle.  A wrist this close to it and given the
# free choice moves the tool by at most 1e-12 times its size.
WRIST_SINGULAR = sp.Float("1e-12")


def _wrist_singular(u, h2):
    side = cross(h2, u)
    return sp.StrictLessThan(dot(side, side), WRIST_SINGULAR**2, evaluate=False)


def _free_wrist_angle(arm: _Arm, steps: _Steps, rotation, point):
    """q6 at the wrist singularity of the three-parallel family, where axis 6 joins axes 2 to 4.

    Turning q6 (with q2 + q3 + q4 following it) carries the point p4 on axis 4 around a
    circle, and its squared distance from axis 2's point over the interval ``S +- rho``
    (subproblem 3's coefficients).  The planar two-link reaches squared distances
    ``S3 +- rho3``.  q6 puts it at ``clamp(S3, S - rho, S + rho)``: inside the reach
    whenever any q6 is (the interval's point nearest the centre of the reach), so a
    reachable singular target always has a valid branch, and the choice is the same in
    every backend.
    """
    a2, a3, a4, a6 = (arm.axis(i) for i in (1, 2, 3, 5))
    z = arm.move_point(4, a4.p, -1)                    # E5^-1 p4
    A = arm.move_point(0, point(a6.p), -1) - a2.p      # E1^-1 G p6 - p2
    a_vec = steps.vector("a6", _transpose_apply(rotation, arm.turn(0, A)))
    P, Q, S = distance_coefficients(a6.h, a_vec, z - a6.p)
    centre = tidy(distance_coefficients(a3.h, (a3.p - a2.p).applyfunc(tidy), (a4.p - a3.p).applyfunc(tidy))[2])
    theta = sp.atan2(Q, P) + sp.acos(ClampUnit((centre - S) / (sp.sqrt(P**2 + Q**2) + TINY)))
    return -theta                                       # E6^-1 turns by -q6


def perpendicular(h) -> sp.Matrix:
    """A unit vector perpendicular to the unit vector ``h``: a coordinate axis where one is, else
    ``h x e / |h x e|`` with ``e`` the coordinate axis least along ``h``."""
    basis = [sp.Matrix([1 if j == i else 0 for j in range(3)]) for i in range(3)]
    for e in basis:
        if is_zero(dot(h, e)):
            return e
    e = min(basis, key=lambda e: abs(float(dot(h, e).evalf())) if dot(h, e).is_number else 1.0)
    side = cross(h, e)
    return (side / sp.sqrt(tidy(dot(side, side)))).applyfunc(tidy)


def _transpose_apply(rotation, vec):
    """``G_R^T vec`` from the map ``rotation(v) = G_R v``."""
    columns = [rotation(sp.Matrix([1 if j == i else 0 for j in range(3)])) for i in range(3)]
    return sp.Matrix([dot(col, vec) for col in columns])


def _position_family(arm: _Arm) -> list[_Steps]:
    base = _Steps()
    x, y, z = arm.model.task_symbols
    c = sp.Matrix([x, y, z])
    arm.say("the tool point w = M p (the tool's origin at q = 0) to the target (x, y, z)")
    return _position(arm, base, arm.S.home[:3, 3], c, "tool point")


def _task_symbol(arm: _Arm, name: str):
    return dict(zip(arm.model.task_names, arm.model.task_symbols))[name]


def _pitch_run(S: Structure) -> bool:
    """Axes 2, 3, 4 revolute and parallel, axis 1 not along them, and axis 5 (if any) not either:
    the pitch joints of a base turn, shoulder, elbow and wrist pitch (the AL5D, the SO-101)."""
    return (S.n >= 4 and S.kinds[:4] == "RRRR" and S.parallel(1, 2) and S.parallel(2, 3)
            and not S.parallel(0, 1) and (S.n == 4 or not S.parallel(3, 4)))


def _planar_tail(arm: _Arm, s: _Steps, theta, y4):
    """q2, q3, q4 of a pitch arm from the image ``y4`` of p4 (a point on axis 4) under E2 E3 and the
    pitch ``theta`` = s2 q2 + s3 q3 + s4 q4: q3 by subproblem 3, q2 by subproblem 1, q4 from the sum."""
    a2, a3, a4 = arm.axis(1), arm.axis(2), arm.axis(3)
    signs = [tidy(dot(a.h, a2.h)) for a in (a2, a3, a4)]
    out = []
    for root3 in angle_to_distance(a3.h, (a3.p - a2.p).applyfunc(tidy), (a4.p - a3.p).applyfunc(tidy),
                                   dot(y4 - a2.p, y4 - a2.p)):
        s3 = s.fork()
        s3.choose("elbow", root3, 3)
        s3.joint(arm.q[2], root3.value)
        e3 = s3.vector("e3", arm.move_point(2, a4.p))
        s3.joint(arm.q[1], angle_onto(a2.h, e3 - a2.p, y4 - a2.p))
        s3.joint(arm.q[3], signs[2] * (theta - signs[0] * arm.q[1] - signs[1] * arm.q[2]))
        out.append(s3)
    return out


def _position_pitch(arm: _Arm, base: _Steps | None = None, pitch=None) -> list[_Steps]:
    """x, y, z and pitch of a 4-joint pitch arm (or of a 5-joint one whose joint 5 is held)."""
    S = arm.S
    a1, a2, a4 = arm.axis(0), arm.axis(1), arm.axis(3)
    base = base or _Steps()
    x, y, z = (_task_symbol(arm, n) for n in "xyz")
    c = sp.Matrix([x, y, z])
    w = S.home[:3, 3]
    theta = _task_symbol(arm, "pitch") if pitch is None else pitch
    arm.say("q1: subproblem 4, the height of E1^-1 c along h2 equals that of the tool point (joints 2 to 4 "
            "turn about parallel axes and keep it)")
    arm.say("pitch = s2 q2 + s3 q3 + s4 q4 (s_i = h_i . h2): R2 R3 R4 = Rot(h2, pitch)")
    arm.say("y4 = E1^-1 c - Rot(h2, pitch) (w - p4): where E2 E3 puts p4, the point of axis 4")
    arm.say("q3: subproblem 3, the distance of E3 p4 from axis 2's point equals that of y4")
    arm.say("q2: subproblem 1, turns E3 p4 onto y4 about axis 2; q4 from the pitch")
    out = []
    for root1 in angle_to_height(c - a1.p, a1.h, a2.h, tidy(dot(a2.h, w - a1.p))):
        s1 = base.fork()
        s1.choose("shoulder", root1, 1)
        s1.joint(arm.q[0], root1.value)
        c1 = s1.vector("c1", arm.move_point(0, c, -1))
        turned = rotate(a2.h, sp.cos(theta), sp.sin(theta), (w - a4.p).applyfunc(tidy))
        y4 = s1.vector("y4", c1 - turned)
        out.extend(_planar_tail(arm, s1, theta, y4))
    return out


def _approach_line(S: Structure):
    """(o, L): the point o where the line of the tool's approach (its z axis) through the tool point
    meets axis 5, and the signed distance L from o to the tool point along the approach; or
    IKUnsupported.  The line turns with link 5, so ``o`` is on axis 5 at every q and the wrist
    point of a target is ``c - L a``."""
    P, d0 = S.home[:3, 3], S.home[:3, 2]
    a5 = S.axes[4]
    if a5.kind != REVOLUTE:
        raise IKUnsupported("x, y, z, approach needs joint 5 revolute")
    if all(is_zero(e) for e in cross(d0, a5.h)):
        if S.on_axis(P, 4):
            raise TaskUnreachable("the approach lies along axis 5 through the tool point: joint 5 turns the tool "
                                  "about it and changes neither position nor approach, so x, y, z, approach is "
                                  "reached only on a 4-dimensional set (task x, y, z, pitch, roll reaches it in full "
                                  "on an arm of a base turn, three pitch joints and a roll)")
        raise IKUnsupported("the approach is parallel to axis 5 but off it")
    normal = cross(d0, a5.h)
    if not is_zero(dot(a5.p - P, normal)):
        raise IKUnsupported("the tool's approach line (its z axis through the tool point) does not meet axis 5")
    t = dot(cross(a5.p - P, a5.h), normal) / dot(normal, normal)
    o = (P + d0 * t).applyfunc(tidy)
    return o, tidy(-t)


def _unit_target(arm: _Arm, base: _Steps):
    a = sp.Matrix([_task_symbol(arm, n) for n in ("ax", "ay", "az")])
    norm = base.scalar("anorm", sp.sqrt(dot(a, a)) + TINY)
    return base.vector("a", a / norm)


def _position_approach(arm: _Arm, o, L) -> list[_Steps]:
    """x, y, z and the approach a of a five-joint arm whose approach line meets axis 5 at o."""
    S = arm.S
    a1, a2, a4, a5 = arm.axis(0), arm.axis(1), arm.axis(3), arm.axis(4)
    d0 = S.home[:3, 2]
    base = _Steps()
    u = _unit_target(arm, base)
    c = sp.Matrix([_task_symbol(arm, n) for n in "xyz"])
    co = base.vector("co", c - u * L)
    arm.say("a = (ax, ay, az) / |(ax, ay, az)|; o: where the approach line through the tool point meets "
            "axis 5; co = c - L a, its target")
    out = []
    if S.meet(3, 4) is not None and all(is_zero(e) for e in S.meet(3, 4) - o):
        branches = _position(arm, base, o, co, "wrist point")
        arm.say("q5: subproblem 4, the height of R5 a0 along h4 equals that of v = (R1 R2 R3)^T a "
                "(axes 4 and 5 meet at o)")
        arm.say("q4: subproblem 1, turns R5 a0 onto v about axis 4")
        for s in branches:
            v = u
            for i in range(3):
                if arm.axis(i).kind == REVOLUTE:
                    v = s.vector(f"v{i + 1}", arm.turn(i, v, -1))
            for root5 in angle_to_height(a4.h, a5.h, d0, dot(a4.h, v)):
                s5 = s.fork()
                s5.choose("wrist", root5, 5)
                s5.joint(arm.q[4], root5.value)
                f = s5.vector("r5", arm.turn(4, d0))
                s5.joint(arm.q[3], angle_onto(a4.h, f, v))
                out.append(s5)
        return out
    if not _pitch_run(S):
        raise IKUnsupported("x, y, z, approach: axes 4 and 5 do not meet where the approach line meets axis 5, "
                            "and axes 2, 3, 4 are not parallel")
    arm.say("q1: subproblem 4, the height of E1^-1 co along h2 equals that of o (axes 2, 3, 4 parallel)")
    arm.say("q5: subproblem 4, the height of R5 a0 along h2 equals that of R1^T a")
    arm.say("theta = s2 q2 + s3 q3 + s4 q4: subproblem 1, turns R5 a0 onto R1^T a about h2; where R1^T a is "
            "along h2 (within 1e-12) theta is free and is chosen to put p4 nearest the middle of the elbow's reach")
    arm.say("y4 = E1^-1 co - Rot(h2, theta) (o - p4); q3 by subproblem 3, q2 by subproblem 1, q4 from theta")
    centre = tidy(distance_coefficients(arm.axis(2).h, (arm.axis(2).p - a2.p).applyfunc(tidy),
                                        (a4.p - arm.axis(2).p).applyfunc(tidy))[2])
    for root1 in angle_to_height(co - a1.p, a1.h, a2.h, tidy(dot(a2.h, o - a1.p))):
        s1 = base.fork()
        s1.choose("shoulder", root1, 1)
        s1.joint(arm.q[0], root1.value)
        u1 = s1.vector("u1", arm.turn(0, u, -1))
        c1 = s1.vector("c1", arm.move_point(0, co, -1))
        for root5 in angle_to_height(a2.h, a5.h, d0, dot(a2.h, u1)):
            s5 = s1.fork()
            s5.choose("wrist", root5, 5)
            s5.joint(arm.q[4], root5.value)
            f = s5.vector("r5", arm.turn(4, d0))
            regular = angle_onto(a2.h, f, u1)
            # free theta: |c1 - p2 - Rot(h2, theta) (o - p4)|^2 = S + P cos + Q sin, put at the reach's centre
            P, Q, Sd = distance_coefficients(a2.h, c1 - a2.p, -(o - a4.p).applyfunc(tidy))
            free = sp.atan2(Q, P) + sp.acos(ClampUnit((centre - Sd) / (sp.sqrt(P**2 + Q**2) + TINY)))
            theta = s5.scalar("theta", sp.Piecewise((free, _wrist_singular(u1, a2.h)), (regular, True),
                                                    evaluate=False))
            turned = rotate(a2.h, sp.cos(theta), sp.sin(theta), (o - a4.p).applyfunc(tidy))
            y4 = s5.vector("y4", c1 - turned)
            out.extend(_planar_tail(arm, s5, theta, y4))
    return out


def _parallel_axes(arm: _Arm) -> list[_Steps]:
    S, model = arm.S, arm.model
    ez = sp.Matrix([0, 0, 1])
    task = list(model.task_names)
    revolute = [a for a in S.axes if a.kind == REVOLUTE]
    prismatic = [a for a in S.axes if a.kind == PRISMATIC]
    need_r = 2 + ("phi" in task)
    need_p = int("z" in task)
    if len(revolute) != need_r or len(prismatic) != need_p:
        raise IKUnsupported(f"every axis is along the base z axis, but the task {', '.join(task)} needs "
                            f"{need_r} revolute joints and {need_p} prismatic ones (the arm has "
                            f"{len(revolute)} and {len(prismatic)})")
    symbols = dict(zip(task, model.task_symbols))
    base = _Steps()
    signs = {a.index: tidy(dot(a.h, ez)) for a in S.axes}
    if prismatic:
        (slide,) = prismatic
        arm.say(f"q{slide.index + 1}: the height z of the tool point above its height at q = 0")
        base.joint(model.q[slide.index], signs[slide.index] * (symbols["z"] - S.home[2, 3]))
    r1, r2 = revolute[0], revolute[1]
    if "phi" in task:
        r3 = revolute[2]
        phi = model.task[task.index("phi")]
        phi0 = tidy(phi.xreplace({qi: 0 for qi in model.q}))
        angle = symbols["phi"] - phi0
        turn = sp.Matrix([[sp.cos(angle), -sp.sin(angle), 0], [sp.sin(angle), sp.cos(angle), 0], [0, 0, 1]])
        w = r3.p
        offset = (S.home[:3, 3] - w).applyfunc(tidy)
        target = base.vector("c", sp.Matrix([symbols["x"], symbols["y"], 0]) - turn * offset)
        arm.say(f"c = (x, y) - Rz(phi - phi0) (p_tool - p{r3.index + 1}): the point on axis {r3.index + 1}")
    else:
        w = S.home[:3, 3]
        target = sp.Matrix([symbols["x"], symbols["y"], 0])
        arm.say("c = (x, y): the tool point")
    arm.say(f"q{r2.index + 1}: subproblem 3, the distance of E{r2.index + 1} w from axis {r1.index + 1} in the plane")
    arm.say(f"q{r1.index + 1}: subproblem 1, turns E{r2.index + 1} w onto c about axis {r1.index + 1}")
    planar = sp.Matrix([1, 1, 0])
    a_vec = sp.matrix_multiply_elementwise(r2.p - r1.p, planar).applyfunc(tidy)
    b_vec = sp.matrix_multiply_elementwise(w - r2.p, planar).applyfunc(tidy)
    delta = sp.matrix_multiply_elementwise(target - r1.p, planar)
    out = []
    for root in angle_to_distance(ez, a_vec, b_vec, dot(delta, delta)):
        s = base.fork()
        s.choose("elbow", root, r2.index + 1)
        s.joint(model.q[r2.index], signs[r2.index] * root.value)
        e = s.vector("e", a_vec + rotate(ez, sp.cos(root.value), sp.sin(root.value), b_vec))
        s.joint(model.q[r1.index], signs[r1.index] * angle_onto(ez, e, delta))
        if "phi" in task:
            arm.say(f"q{r3.index + 1}: phi - phi0 less the other revolute joints' turns")
            s.joint(model.q[r3.index], signs[r3.index] * (angle - signs[r1.index] * model.q[r1.index]
                                                          - signs[r2.index] * model.q[r2.index]))
        out.append(s)
    return out


# --- the entry point ------------------------------------------------------------------------

# Rebuilt without evaluation: SymPy would compare the (long) arguments of each pairwise,
# sort them by size, or put a relation in canonical form, at seconds per node.
_UNEVALUATED = (sp.Min, sp.Max, sp.Piecewise, sp.Rel, sp.Function)


def _conjunction(func, args):
    """``And(*args)`` (or ``Or``) as written: SymPy's constructor sorts the arguments by their
    tree size, which on a six-joint inverse counts millions of nodes."""
    func = {sp.And: Conjunction, sp.Or: Disjunction}.get(func, func)
    return sp.Basic.__new__(func, *args)


class Conjunction(sp.And):
    """An ``And`` built as written (:func:`_conjunction`), and unpickled the same way: loading a
    six-joint arm's model from the cache re-sorted its branch conditions for seconds."""

    def __reduce_ex__(self, protocol):
        return _conjunction, (Conjunction, self.args)


class Disjunction(sp.Or):
    """An ``Or`` built as written, as :class:`Conjunction` (a subproblem's existence: the root
    exists, or the angle is free)."""

    def __reduce_ex__(self, protocol):
        return _conjunction, (Disjunction, self.args)


def substitute_unevaluated(expr, subs: dict, memo: dict):
    """``expr.xreplace(subs)``, but each shared subexpression rebuilt once and ``Min``/``Max`` left
    unevaluated (SymPy compares their arguments pairwise, which on long ones takes minutes)."""
    if expr in subs:
        return subs[expr]
    if not expr.args:
        return expr
    try:
        return memo[expr]
    except KeyError:
        pass
    args = tuple(substitute_unevaluated(a, subs, memo) for a in expr.args)
    if args == expr.args:
        result = expr
    elif isinstance(expr, (sp.And, sp.Or)):
        result = _conjunction(expr.func, args)
    elif isinstance(expr, sp.Piecewise):   # as written (primitives.WrittenPiecewise)
        result = written_piecewise(*(pair.args for pair in args))
    elif isinstance(expr, ExprCondPair):
        result = sp.Basic.__new__(ExprCondPair, *args)
    elif isinstance(expr, _UNEVALUATED):
        result = expr.func(*args, evaluate=False)
    else:
        result = expr.func(*args)
    memo[expr] = result
    return result


class _Substituted(SubstitutedSteps):
    """A derived branch's ``solution`` and ``condition``: its steps substituted in order, each
    revolute joint read by later steps as its wrapped value, the free joint its own symbol."""

    def __init__(self, q, revolute, free=None):
        self.q, self.revolute, self.free = tuple(q), tuple(revolute), free

    def substitute(self, branch: IKBranch):
        revolute = dict(zip(self.q, self.revolute))
        subs, values = {}, {}
        if self.free is not None:  # the free joint's value is the kernel's argument: the joint symbol itself
            values[self.free] = self.free
        for symbol, expr in branch.steps:
            value = substitute_unevaluated(expr, subs, {})
            if symbol in revolute:
                values[symbol] = value
                subs[symbol] = WrapAngle(value) if revolute[symbol] else value
            else:
                subs[symbol] = value
        return tuple(values[q] for q in self.q), substitute_unevaluated(branch.step_condition, subs, {})


def _branch(model, steps: _Steps, doc_head: str, free=None) -> IKBranch:
    """The branch of ``steps``: its kernel is emitted from the steps, and its solution and condition
    (the steps substituted) are computed if read (:class:`derivations.model.SubstitutedSteps`)."""
    solved = {symbol for symbol, _ in steps.items} | {free}
    missing = [str(q) for q in model.q if q not in solved]
    if missing:
        raise AssertionError(f"decomposition left {missing} unsolved")
    step_condition = (_conjunction(Conjunction, steps.conditions) if len(steps.conditions) > 1
                      else steps.conditions[0] if steps.conditions else sp.true)
    name = "_".join(steps.choices)
    doc = f"{doc_head}; " + "; ".join(steps.docs)
    substituted = _Substituted(model.q, (t == REVOLUTE for t in model.joint_types), free)
    return IKBranch(name, substituted, substituted, doc, tuple(steps.items), step_condition=step_condition)


def _six_joint_family(S: Structure):
    """(family, builder) of a six-joint arm that reaches a full pose, or IKUnsupported."""
    kinds = S.kinds
    w = S.meet_in_one_point(3, 4, 5)
    if w is not None:
        return "spherical wrist", lambda arm: _spherical_wrist(arm, w)
    if kinds == "RRRRRR" and S.parallel(1, 2) and S.parallel(2, 3) and not S.parallel(0, 1):
        o = S.meet(4, 5)
        if o is not None:
            return "three parallel", lambda arm: _three_parallel(arm, o)
        raise IKUnsupported("axes 2, 3 and 4 are parallel but axes 5 and 6 do not meet")
    raise IKUnsupported("no three consecutive axes meet in a point (axes 4, 5, 6) and axes 2, 3, 4 "
                        "are not parallel")


def _pose_families(S: Structure) -> list[tuple[bool, str, object]]:
    """[(reversed, family, builder)] of a six-joint arm reaching a full pose: its own family, then
    the family of the arm read from its tool (:mod:`derivations.ik.reverse`: a spherical shoulder,
    or three parallel axes from the base), those that classify; or IKUnsupported naming what both
    lack."""
    found, reasons = [], []
    for backwards in (False, True):
        try:
            family, build = _six_joint_family(reversed_structure(S) if backwards else S)
            found.append((backwards, f"reversed {family}" if backwards else family, build))
        except IKUnsupported as error:
            reasons.append(str(error))
    if not found:
        raise IKUnsupported(f"{reasons[0]}; nor read from the tool (axes 1, 2, 3 do not meet in a point and axes 3, "
                            "4, 5 are not parallel)")
    return found


def _reversed_steps(arm: _Arm, q, built: list[_Steps]) -> list[_Steps]:
    """The branches of the reversed arm ``arm`` given back in the real joints ``q`` (the reversed
    arm's joint k is ``-q[n - k]``), root choices named for where they are on the real arm."""
    n = len(q)
    for steps in built:
        for k, real in enumerate(reversed(tuple(q))):
            steps.joint(real, -arm.q[k])
        steps.choices = [_swap_label(choice) for choice in steps.choices]
        docs = []
        for doc in steps.docs:
            head, _, rest = doc.partition(": ")
            k = int(head[1:])
            docs.append(f"{q[n - k]} (= -{arm.q[k - 1]}, reversed joint {k}): {rest}")
        steps.docs = docs
    return built


def _swap_label(choice: str) -> str:
    label, _, root = choice.rpartition("_")
    return f"{SWAPPED_LABELS.get(label, label)}_{root}" if label else choice


def _pose_solution(model, S: Structure, q, families=None):
    """(family, arm, branches' steps) of a six-joint arm reaching a full pose, over the joints ``q``
    (model.q less a held joint): the first of :func:`_pose_families` whose builder takes the arm (a
    spherical wrist whose position joints have no closed form leaves the reversed family to try)."""
    reasons = []
    for backwards, family, build in families or _pose_families(S):
        try:
            if not backwards:
                arm = _Arm(model, S, q)
                return family, arm, build(arm)
            x, y, z, *r = model.task_symbols
            arm = _Arm(model, reversed_structure(S), reversed_joints(q),
                       target=reversed_target(S.home, sp.Matrix(3, 3, r), sp.Matrix([x, y, z])))
            arm.say("read from the tool (its special axes are at the base): M T^-1 = E6(-q6) ... E1(-q1), the same "
                    "lines in the reverse order; joints 1 to 6 below are the reversed arm's: "
                    + ", ".join(f"{k + 1} = -{real}" for k, real in enumerate(reversed(tuple(q))))
                    + "; its target g = M T^-1 (M the tool pose at q = 0)")
            return family, arm, _reversed_steps(arm, q, build(arm))
        except IKUnsupported as error:
            reasons.append(str(error))
    raise IKUnsupported("; ".join(reasons))


# The joint held at the free value in a seven-joint arm, in the order tried (0-based): the
# elbow's neighbours first, as IKFast's choice for S-R-S arms (the KUKA iiwa and LWR: joint 3).
FREE_ORDER = (2, 4, 3, 1, 5, 0, 6)


def held(S: Structure, j: int, value) -> Structure:
    """The six-joint arm left when joint j of ``S`` is held at ``value`` (a symbol).

    ``E_j E_{j+1} ... E_n M = (E_j E_{j+1} E_j^-1) ... (E_j E_n E_j^-1) E_j M``: each axis after
    j is carried by the rigid motion ``E_j(value)``, and so is the home pose.
    """
    a = S.axes[j]
    c, s_ = sp.cos(value), sp.sin(value)

    def carry(point):
        if a.kind == PRISMATIC:
            return point + a.h * value
        return a.p + rotate(a.h, c, s_, point - a.p)

    def carry_vector(vec):
        return vec if a.kind == PRISMATIC else rotate(a.h, c, s_, vec)

    axes = []
    for k, other in enumerate(S.axes):
        if k == j:
            continue
        h, point = other.h, other.p
        if k > j:
            h, point = carry_vector(h).applyfunc(sp.expand), carry(point).applyfunc(sp.expand)
        axes.append(Axis(len(axes), other.kind, h, point))
    R = sp.eye(4)
    R[:3, :3] = sp.Matrix.hstack(*(carry_vector(sp.Matrix([1 if r == i else 0 for r in range(3)]))
                                   for i in range(3)))
    R[:3, 3] = carry(sp.zeros(3, 1))
    return Structure(tuple(axes), (R * S.home).applyfunc(sp.expand), S.task, S.held + (value,))


def held_joints(model, S: Structure) -> list[tuple[int, list | None, str]]:
    """Per joint of a seven-joint arm, ranked: (j, the families of the six-joint arm left with joint
    j held (:func:`_pose_families`) or None, what holding it gives).  Those with a family come first,
    an arm's own family before a reversed one (no target to carry), then in FREE_ORDER; then those
    without one, in FREE_ORDER, saying why."""
    ranked, without = [], []
    for order, j in enumerate(FREE_ORDER):
        try:
            families = _pose_families(held(S, j, model.q[j]))
        except IKUnsupported as error:
            without.append((j, None, str(error)))
            continue
        what = " family, or ".join(family for _, family, _ in families) + " family"
        ranked.append(((families[0][0], order), (j, families, what)))
    return [entry for _, entry in sorted(ranked, key=lambda item: item[0])] + without


def _free_joint_solution(model, S: Structure, choice: int | None, table):
    """(free joint, family, the arm, its branches' steps, table) for the first held joint of
    ``table`` (:func:`held_joints`) whose six-joint arm both classifies and builds (or only
    ``choice``, 0-based): a family whose builder refuses this arm (a spherical wrist with an
    offset it cannot take) does not end the search, the next joint is tried; the table comes back
    with what each refused joint lacks, the chosen joint first and the refused ones last."""
    reasons, table = [], list(table)
    for row, (j, families, what) in enumerate(table):
        if choice is not None and j != choice:
            continue
        if families is None:
            reasons.append(f"joint {j + 1}: {what}")
            continue
        try:
            family, arm, built = _pose_solution(model, held(S, j, model.q[j]),
                                                [q for i, q in enumerate(model.q) if i != j], families)
            # the chosen joint first, then those that classify and were not tried, then those refused
            table.sort(key=lambda entry: (entry[0] != j, entry[1] is None))
            return j, family, arm, built, table
        except IKUnsupported as error:
            reasons.append(f"joint {j + 1}: {error}")
            table[row] = (j, None, f"{what}, but {error}")
    chosen = f"holding joint {choice + 1} (the free joint asked for)" if choice is not None else "no free joint"
    raise IKUnsupported(f"7 joints: {chosen} leaves a covered six-joint arm ("
                        + "; ".join(reasons[:2]) + ("; ..." if len(reasons) > 2 else "") + ")")


# Degrees of freedom of each task item: a direction (approach) has two.
TASK_FREEDOM = {"pose": 6, "approach": 2}


def task_freedom(items) -> int:
    return sum(TASK_FREEDOM.get(t, 1) for t in items)


def task_items(names) -> tuple[str, ...]:
    """The task items (x, pose, approach, ...) of a model's task coordinate names."""
    names, items, i = tuple(names), [], 0
    while i < len(names):
        if names[i:i + 12] == POSE_NAMES:
            items.append("pose"); i += 12
        elif names[i:i + 3] == APPROACH_NAMES:
            items.append("approach"); i += 3
        else:
            items.append(names[i]); i += 1
    return tuple(items)


def _check_pitch(model, S: Structure):
    """The model's pitch coordinate is s2 q2 + s3 q3 + s4 q4 (the run of the family)."""
    pitch = model.task[list(model.task_names).index("pitch")]
    expected = sum((tidy(dot(S.axes[i].h, S.axes[1].h)) * model.q[i] for i in (1, 2, 3)), sp.S.Zero)
    if sp.expand(pitch - expected) != 0:
        raise IKUnsupported(f"the pitch coordinate {pitch} is not the turn of joints 2 to 4")


def _reduced_family(model, S: Structure):
    """(free joint or None, family, arm, builder) for the tasks of 4- to 6-joint arms that the
    families below reach with one joint held or set from the task, or None."""
    items, n = set(task_items(model.task_names)), model.n
    if items == {"x", "y", "z", "pitch", "roll"} and n == 5:
        if not _pitch_run(S):
            raise IKUnsupported("x, y, z, pitch, roll needs axes 2, 3, 4 parallel and axis 1 not (a base turn, "
                                "three pitch joints and a roll)")
        _check_pitch(model, S)
        roll = _task_symbol(_Arm(model, S), "roll")
        reduced = held(S, 4, roll)
        arm = _Arm(model, reduced, model.q[:4])
        arm.say(f"q5 = roll; held at that value, joint 5 carries the tool: a 4-joint pitch arm is left")

        def build(arm):
            base = _Steps()
            base.joint(model.q[4], roll)
            return _position_pitch(arm, base)
        return None, "position, pitch and roll", arm, build
    if items == {"x", "y", "z", "pitch"} and n == 5:
        if not _pitch_run(S):
            raise IKUnsupported("x, y, z, pitch with 5 joints needs axes 2, 3, 4 parallel and axis 1 not")
        _check_pitch(model, S)
        reduced = held(S, 4, model.q[4])
        arm = _Arm(model, reduced, model.q[:4])
        arm.say("q5 is free (the argument `free` of ik): held at that value, joint 5 carries the tool; "
                "a 4-joint pitch arm is left")
        return 4, "position and pitch, joint 5 free", arm, _position_pitch
    if items == {"x", "y", "z", "approach"} and n == 6:
        a6, P, d0 = S.axes[5], S.home[:3, 3], S.home[:3, 2]
        if not (a6.kind == REVOLUTE and S.on_axis(P, 5) and all(is_zero(e) for e in cross(d0, a6.h))):
            raise IKUnsupported("x, y, z, approach with 6 joints: covered where joint 6 turns the tool about its "
                                "approach (the tool point on axis 6, its z axis along it)")
        reduced = Structure(S.axes[:5], S.home, S.task)
        o, L = _approach_line(reduced)
        arm = _Arm(model, reduced, model.q[:5])
        arm.say("q6 is free (the argument `free` of ik): joint 6 turns the tool about its approach and changes "
                "neither position nor approach; joints 1 to 5 reach them")
        return 5, "position and approach, joint 6 free", arm, lambda arm: _position_approach(arm, o, L)
    return None


def classify(model, S: Structure):
    """(family name, builder) for the model, or IKUnsupported naming what the arm lacks."""
    task, n = tuple(model.task_names), model.n
    items = task_items(task)
    if task_freedom(items) > n:
        raise TaskUnreachable(f"the task {', '.join(items)} has {task_freedom(items)} degrees of freedom and the "
                              f"arm {n} joints: it cannot reach it in full")
    if set(items) == {"x", "y", "z", "pitch"} and n == 4:
        if not _pitch_run(S):
            raise IKUnsupported("x, y, z, pitch needs axes 2, 3, 4 parallel and axis 1 not (a base turn and "
                                "three pitch joints)")
        _check_pitch(model, S)
        return "position and pitch", _position_pitch
    if set(items) == {"x", "y", "z", "approach"} and n == 5:
        o, L = _approach_line(S)
        return "position and approach", lambda arm: _position_approach(arm, o, L)
    if task == POSE_NAMES:
        if n != 6:
            raise IKUnsupported(f"a full pose with {n} joints: the closed forms cover 6 joints, "
                                "and 7 with one of them free")
        return _six_joint_family(S)  # (solve reads such an arm from its tool too: _pose_solution)
    if set(task) == {"x", "y", "z"} and task == ("x", "y", "z") and n == 3:
        return "position", _position_family
    if "x" in task and "y" in task and set(task) <= {"x", "y", "z", "phi"}:
        ez = sp.Matrix([0, 0, 1])
        if all(S.parallel_to(a.index, ez) for a in S.axes):
            return "parallel axes", _parallel_axes
        if set(task) == {"x", "y", "z"}:
            raise IKUnsupported(f"a position task with {n} joints: the closed forms cover 3 "
                                "(or every axis along the base z axis)")
        raise IKUnsupported(f"the task {', '.join(task)} needs every axis along the base z axis")
    raise IKUnsupported(f"no closed form for the task {', '.join(task)} with {n} joints")


def solve(model, free_joint: int | None = None) -> IKSolution:
    """Every inverse-kinematics branch of ``model`` by decomposition, or IKUnsupported saying why not.

    ``free_joint`` (0-based) is the joint a seven-joint arm holds at ik's argument ``free``;
    None: the first in FREE_ORDER that leaves a six-joint arm with a closed form."""
    chain = model.chain
    if chain is None:
        raise IKUnsupported("the model is not one serial chain")
    if chain.coupled(model.q):
        raise IKUnsupported("a joint drives a fixed transform (a mimic joint): not a plain serial chain")
    S = structure_of(model)
    error = check_product_of_exponentials(model, S)
    if not error < 1e-9:
        raise AssertionError(f"{model.name}: the product of exponentials misses the chain's fk by {error:.2e}")
    free = None
    structure = S.describe()
    if tuple(model.task_names) == POSE_NAMES and model.n == 7:
        if free_joint is not None and not 0 <= free_joint < 7:
            raise IKUnsupported(f"free joint {free_joint + 1}: a seven-joint arm holds one of joints 1 to 7")
        free, family, arm, built, table = _free_joint_solution(model, S, free_joint, held_joints(model, S))
        structure.append("held joints: " + "; ".join(f"joint {j + 1}: {what}" for j, _, what in table)
                         + f" (ranked: joint {free + 1} is held; a family after it is found from the axes, "
                           "its branches not built)")
        if family.startswith("reversed"):
            arm.plan.insert(0, f"q{free + 1} is free (the argument `free` of ik): held at that value, joint "
                               f"{free + 1} carries the axes after it; the other six joints form a {family} arm")
        else:
            numbering = ", ".join(f"{i + 1} = q{k + 1}" for i, k in enumerate(k for k in range(7) if k != free))
            arm.plan.insert(0, f"q{free + 1} is free (the argument `free` of ik): held at that value, joint "
                               f"{free + 1} carries the axes after it; the other six joints form a {family} arm, "
                               f"numbered 1 to 6 below ({numbering})")
        family = f"{family}, joint {free + 1} free"
    elif (reduced := _reduced_family(model, S)) is not None:
        free, family, arm, build = reduced
        built = build(arm)
    elif tuple(model.task_names) == POSE_NAMES and model.n == 6:
        family, arm, built = _pose_solution(model, S, model.q)
    else:
        family, build = classify(model, S)
        arm = _Arm(model, S)
        built = build(arm)
    free_symbol = None if free is None else model.q[free]
    branches = [_branch(model, steps, f"{family} family", free_symbol) for steps in built]
    try:
        branches = geometric_names(model, S, [list(model.q).index(q) for q in arm.q], family, branches, free)
    except ValueError:
        pass  # a step the naming cannot evaluate in double precision: the branches keep their root choices
    return IKSolution(family, branches, arm.plan, structure, free)


# CPU seconds the automatic inverse kinematics of one arm may take (CPU time, so that the verdict
# does not depend on how busy the machine is): the target of issue #15 (the
# arms of the zoo take 0.01-0.2 s; an arm past it gets no ik and a message saying so).
IK_BUDGET = 10.0


# The tasks a 3- to 5-joint arm may reach in full with a closed form, in the order suggested.
CANDIDATE_TASKS = {3: (("x", "y", "z"),),
                   4: (("x", "y", "z", "pitch"), ("x", "y", "z", "phi")),
                   5: (("x", "y", "z", "pitch", "roll"), ("x", "y", "z", "approach"))}


class _TaskView:
    """The parts of a model the families read, with another task (for :func:`suggest_task`)."""

    def __init__(self, model, items):
        from ..kinematics import joint_angle_task
        self.name, self.q, self.n, self.chain = model.name, model.q, model.n, model.chain
        names, values = [], []
        for item in items:
            if item == "approach":
                names += list(APPROACH_NAMES); values += [sp.S.Zero] * 3
            elif item in ("pitch", "roll"):
                names.append(item); values.append(joint_angle_task(item, model.chain, model.q))
            else:
                names.append(item); values.append(sp.S.Zero)
        self.task_names, self.task = tuple(names), sp.Matrix(values)

    @property
    def task_symbols(self):
        return tuple(sp.Symbol(name, real=True) for name in self.task_names)


def suggest_task(model, S: Structure | None = None) -> tuple[str, ...] | None:
    """The first task of CANDIDATE_TASKS that this arm reaches in full with a closed form (other
    than its own), or None."""
    if model.chain is None or model.n not in CANDIDATE_TASKS:
        return None
    S = S or structure_of(model)
    own = task_items(model.task_names)
    for items in CANDIDATE_TASKS[model.n]:
        if items == own:
            continue
        try:
            view = _TaskView(model, items)
            view_S = Structure(S.axes, S.home, view.task_names)
            reduced = _reduced_family(view, view_S)
            if reduced is not None:
                free, _, arm, build = reduced
                if free is not None:
                    continue  # a task that leaves a joint free is no task the arm reaches in full
                build(arm)
            else:
                _, build = classify(view, view_S)
                build(_Arm(view, view_S))
            return items
        except (IKUnsupported, ValueError):
            continue
    return None


def _suggestion(model) -> str:
    items = suggest_task(model)
    if items is None:
        return ""
    listed = ", ".join(f'"{t}"' for t in items)
    return (f"; this arm's ik has a closed form for the task {', '.join(items)} (task = [{listed}] in a TOML "
            f"description, --task {','.join(items)} on the command line and for a URDF)")


def attach(model, free_joint: int | None = None) -> None:
    """Give ``model`` its inverse kinematics by :func:`solve`, or record why it has none.

    Sets ``model.ik`` (the branches) and ``model.ik_plan`` (family, structure and steps),
    or ``model.ik_unsupported`` (what the arm lacks, or the budget that ran out); the rest
    of the package is generated either way.
    """
    from ..support.budget import BudgetExceeded, budget, degraded
    try:
        with budget(IK_BUDGET, f"{model.name}: automatic inverse kinematics", clock="cpu"):
            solution = solve(model, free_joint)
    except IKUnsupported as error:
        model.ik_unsupported = str(error)
        model.ik_task_unreachable = isinstance(error, TaskUnreachable)
        try:
            with budget(IK_BUDGET, f"{model.name}: a task with a closed form", clock="cpu"):
                model.ik_unsupported += _suggestion(model)
        except BudgetExceeded:
            pass
        return
    except BudgetExceeded as error:
        model.ik_unsupported = f"{error} (the decomposition found no closed form within it)"
        degraded(model.ik_unsupported)  # cut short: not to be cached
        return
    model.ik = solution.branches
    model.ik_free = solution.free
    model.ik_plan = (f"family: {solution.family}", *solution.structure, *solution.plan)

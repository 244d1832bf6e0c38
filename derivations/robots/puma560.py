"""PUMA 560: closed-form inverse kinematics of a full pose, all eight branches.

The classical Paul/Craig decoupling, derived for this file's DH table (standard
DH, alpha = pi/2, 0, -pi/2, pi/2, -pi/2, 0; a2, a3 on joints 2 and 3; the
shoulder offset d3 along z2).  Joints 4 to 6 meet at one point, the wrist
centre, which is the tool point here (d6 = 0), so the position p of the pose
fixes joints 1 to 3 and the rotation R fixes joints 4 to 6.  Every step is one
of the primitives of ``derivations.ik``; ``extend`` checks the structure it
relies on against the model's own frames before using it.

1. Seen from frame 1 the wrist is at ``(u, v, d3)`` with
   ``u = a2 c2 + a3 c23 - d4 s23``, ``v = a2 s2 + a3 s23 + d4 c23`` and
   ``p = d1 z0 + u x1 + v y1 + d3 z1``.  The lateral part,
   ``-px s1 + py c1 = -d3``, is P cos + Q sin + R = 0 in theta1 with
   ``(P, Q, R) = (py, -px, d3)``: two roots.  sigma = +1 gives
   ``u = px c1 + py s1 >= 0`` (the wrist ahead of the shoulder; with d3 > 0 the
   upper arm then sits on the robot's right): ``right``; sigma = -1 is ``left``.
2. ``u^2 + v^2 = a2^2 + a3^2 + d4^2 + 2 a2 (a3 c3 - d4 s3)`` with
   ``u^2 = px^2 + py^2 - d3^2`` and ``v = pz - d1`` is P cos + Q sin + R = 0 in
   theta3: ``(P, Q, R) = (2 a2 a3, -2 a2 d4, a2^2 + a3^2 + d4^2 - u^2 - v^2)``.
   The root with sigma = -1 (right) or +1 (left) puts the elbow above the line
   from the shoulder to the wrist: ``elbow_up``; the other is ``elbow_down``.
   a3 != 0 is kept throughout.
3. ``(u, v)`` is ``(a2 + a3 c3 - d4 s3, a3 s3 + d4 c3)`` turned by theta2: a
   sine/cosine pair, one root.
4. ``R36 = R03^T R = Rz(t4) Rx(pi/2) Rz(t5) Rx(-pi/2) Rz(t6)`` has third column
   ``(-c4 s5, -s4 s5, c5)``: ``theta4 = atan2(-r23, -r13)`` of R36 gives
   ``s5 >= 0`` (``noflip``); theta4 + pi gives ``s5 <= 0`` (``flip``).  Then
   ``M = Rot(A4)^T R36 = Rz(t5) Rx(-pi/2) Rz(t6)`` gives
   ``theta5 = atan2(-m13, m23)`` and ``theta6 = atan2(-m31, -m32)`` from entries
   of size one, so an error in theta4 near the singularity is absorbed by
   theta5 and theta6 (the pose error stays at the order of s5 times that error).

Wrist singularity: where ``s5^2 = r13^2 + r23^2`` of R36 is at most
``WRIST_SINGULAR^2`` (theta5 = 0 or pi: axes 4 and 6 line up), theta4 is left
free by the pose; the defined choice is theta4 = 0 (``noflip``) or pi
(``flip``), and theta6 then carries theta4 + theta6 (theta5 = 0) or
theta6 - theta4 (theta5 = pi).  Detect it in a solution by |sin(q5)| <= 1e-12.

Shoulder singularity: with d3 = 0 (not the Puma's value) a wrist centre on the
base axis leaves theta1 free; the branches report it as not valid
(P^2 + Q^2 > 0 in step 1).  With d3 != 0 the wrist centre cannot come closer
to the axis than |d3|, and there the two shoulder roots coincide.

Branch names: ``{right|left}_{elbow_up|elbow_down}_{noflip|flip}``.
"""
from __future__ import annotations

import sympy as sp

from derivations.chain import simplify_entry
from derivations.ik import p_cos_q_sin_r, sine_cosine_pair, substitute_steps
from derivations.model import POSE_NAMES, IKBranch

from ._common import parameters

# |sin(theta5)| at or below which the wrist is singular and theta4 := 0 (or pi).
WRIST_SINGULAR = sp.Rational(1, 10**12)


def _same(a, b) -> bool:
    return sp.simplify(sp.expand_trig(sp.expand(a - b))) == 0


def _check_structure(model, u, v):
    """The decoupling's premises, checked on the model's own frames."""
    q1, q2, q3, q4, q5, q6 = model.q
    d1, d3 = parameters(model, "d1", "d3")
    frames = model.frames
    A1 = frames[1]
    wrist_in_1 = A1[:3, :3].T * (frames[6][:3, 3] - A1[:3, 3])
    expected = [u, v, d3]
    assert all(_same(w, e) for w, e in zip(wrist_in_1, expected)), "wrist centre in frame 1"
    assert all(_same(frames[4][i, 3] - frames[6][i, 3], 0) for i in range(3)), "wrist centre = tool point"
    chain = model.chain
    R36 = (chain.link_transform(3, q4) * chain.link_transform(4, q5) * chain.link_transform(5, q6))[:3, :3]
    third = [-sp.cos(q4) * sp.sin(q5), -sp.sin(q4) * sp.sin(q5), sp.cos(q5)]
    assert all(_same(R36[i, 2], third[i]) for i in range(3)), "third column of R36"
    R46 = (chain.link_transform(4, q5) * chain.link_transform(5, q6))[:3, :3].applyfunc(simplify_entry)
    assert _same(R46[0, 2], -sp.sin(q5)) and _same(R46[1, 2], sp.cos(q5)), "theta5 entries of R46"
    assert _same(R46[2, 0], -sp.sin(q6)) and _same(R46[2, 1], -sp.cos(q6)), "theta6 entries of R46"


# What each factor of det J means (derivations.rates.velocity's singular sets), keyed by the joints it involves.
SINGULAR_NAMES = {("q2", "q3"): ("shoulder", "the wrist centre in the plane of the axes of joints 1 and 2"),
                  ("q3",): ("elbow", "the wrist centre in line with the shoulder and the elbow (arm stretched or folded)"),
                  ("q5",): ("wrist", "axes 4 and 6 aligned (q5 = 0 or pi)")}


def extend(model):
    model.singular_names = SINGULAR_NAMES
    assert model.task_names == POSE_NAMES
    model.rate_form = "wrist partition"  # the velocity slides' 6-DOF model: Paul's partition
    px, py, pz, *r = model.task_symbols
    R = sp.Matrix(3, 3, r)
    d1, a2, a3, d3, d4 = parameters(model, "d1", "a2", "a3", "d3", "d4")
    q1, q2, q3, q4, q5, q6 = model.q
    chain = model.chain
    u_of_q = a2 * sp.cos(q2) + a3 * sp.cos(q2 + q3) - d4 * sp.sin(q2 + q3)
    v_of_q = a2 * sp.sin(q2) + a3 * sp.sin(q2 + q3) + d4 * sp.cos(q2 + q3)
    _check_structure(model, u_of_q, v_of_q)

    u = sp.Symbol("u", real=True)               # the wrist's reach ahead of the shoulder, in frame 1
    # The wrist centre's height above the shoulder, and the pair (u, V) = (K1, K2) turned by theta2.
    V, K1, K2 = sp.symbols("v k1 k2", real=True)
    W = sp.Matrix(3, 3, sp.symbols("w11:14 w21:24 w31:34", real=True))   # W = R36 = R03^T R
    m13, m23, m31, m32 = sp.symbols("m13 m23 m31 m32", real=True)       # entries of M = Rot(A4)^T R36
    shoulder = {("right" if root.name == "sigma_plus" else "left"): root
                for root in p_cos_q_sin_r(py, -px, d3)}                                   # step 1
    v = pz - d1
    u_squared = px**2 + py**2 - d3**2
    elbow_roots = {root.name: root for root in
                   p_cos_q_sin_r(2 * a2 * a3, -2 * a2 * d4, a2**2 + a3**2 + d4**2 - u_squared - v**2)}  # step 2
    R36 = model.frames[3][:3, :3].T * R
    M = chain.link_transform(3, q4)[:3, :3].T * W
    branches = []
    for side in ("right", "left"):
        for elbow in ("elbow_up", "elbow_down"):
            up_root = "sigma_minus" if side == "right" else "sigma_plus"
            down_root = "sigma_plus" if side == "right" else "sigma_minus"
            root3 = elbow_roots[up_root if elbow == "elbow_up" else down_root]
            A = a2 + a3 * sp.cos(q3) - d4 * sp.sin(q3)
            B = a3 * sp.sin(q3) + d4 * sp.cos(q3)
            (pair,) = sine_cosine_pair(K1, K2, u, V)                                      # step 3
            singular = W[0, 2]**2 + W[1, 2]**2 <= WRIST_SINGULAR**2
            for wrist in ("noflip", "flip"):
                turn = 0 if wrist == "noflip" else sp.pi
                steps = (
                    (q1, shoulder[side].value),
                    (u, px * sp.cos(q1) + py * sp.sin(q1)),
                    (q3, root3.value),
                    (V, v), (K1, A), (K2, B),
                    (q2, pair.value),
                    *((W[i, j], R36[i, j]) for i, j in ((0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2), (2, 2))),
                    (q4, sp.Piecewise((turn, singular), (sp.atan2(-W[1, 2], -W[0, 2]) + turn, True))),  # step 4
                    (m13, M[0, 2]), (m23, M[1, 2]), (m31, M[2, 0]), (m32, M[2, 1]),
                    (q5, sp.atan2(-m13, m23)),
                    (q6, sp.atan2(-m31, -m32)),
                )
                solution = tuple(substitute_steps(qi, steps) for qi in model.q)
                condition = substitute_steps(sp.And(shoulder[side].condition, root3.condition,
                                                    pair.condition), steps)
                name = f"{side}_{elbow}_{wrist}"
                branches.append(IKBranch(
                    name, solution, condition,
                    f"Paul/Craig decoupling (module docstring): shoulder {side} (theta1 root sigma = "
                    f"{'+1' if side == 'right' else '-1'}), {elbow.replace('_', ' ')} (theta3 root sigma = "
                    f"{'+1' if root3.name == 'sigma_plus' else '-1'}), wrist {wrist} "
                    f"(sin(theta5) {'>=' if wrist == 'noflip' else '<='} 0; at the wrist singularity "
                    f"theta4 := {'0' if wrist == 'noflip' else 'pi'}); exists while the wrist centre is at least "
                    "|d3| from the base axis and within the arm's reach",
                    steps))
    model.ik = branches

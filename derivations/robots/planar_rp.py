"""Planar R-P arm: inverse kinematics, Kumar Eqs. (6)-(8), both signs of d2.

``x = d2 cos(t1)``, ``y = d2 sin(t1)`` (Eq. 5) give ``d2 = sigma sqrt(x^2 + y^2)``
and ``t1 = atan2(y / d2, x / d2)`` (section 5.4), written here as
``atan2(sigma y, sigma x)`` (the same angle, and defined at d2 = 0).
``d2_positive`` is Eqs. (6)-(7), ``d2_negative`` Eq. (8): the slide passed
through the joint axis.  Every target is reachable; at the origin t1 is free
and atan2 gives 0 (or pi, by the sign of the zero).

Orientation: Kumar writes the R-P arm's end-effector coordinates (x, y, phi)
with ``phi = theta1`` (section 5.3), the direction of the slide.  The task stays
(x, y), as Kumar takes it for the inverse problem (two joints cannot reach an
arbitrary (x, y, phi)); ``kumar_pose(q)`` is an extra kernel giving
(x, y, phi) with Kumar's phi, derived as the direction of joint 2's slide and
checked to be theta1.  The tool frame of the modified DH chain has its z axis
along the slide, so its x axis lies at theta1 - pi/2: phi is not the angle of
the tool x axis here.
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import atan2_of_sine_cosine
from derivations.model import Argument, IKBranch, Output, SymbolicFunction


def kumar_phi(model) -> sp.Expr:
    """Kumar's phi of the R-P arm: the direction of the slide of joint 2 in the base xy plane, which is theta1.

    The slide's direction is the prismatic column of the geometric Jacobian (its z_1 axis); the
    angle is read off it exactly and checked against (cos theta1, sin theta1).
    """
    q1 = model.q[0]
    slide = model.jacobian[:3, 1]
    if sp.simplify(slide - sp.Matrix([sp.cos(q1), sp.sin(q1), 0])) != sp.zeros(3, 1):
        raise ValueError(f"planar_rp: the slide of joint 2 is not along theta1: {list(slide)}")
    return q1


def kumar_pose_functions(model) -> list[SymbolicFunction]:
    """``kumar_pose(q) -> (..., 3)``: x, y and Kumar's phi = theta1 (section 5.3)."""
    q = Argument("q", model.q, "joint coordinates, shape (..., 2) (q1: rad, q2: m)")
    values = (model.task[0], model.task[1], kumar_phi(model))
    return [SymbolicFunction("kumar_pose", (q,), (Output("x", values, (3,)),),
                             "Kumar's end-effector coordinates of the R-P arm (section 5.3): x, y (m) and "
                             "phi = theta1 (rad), the direction of the slide, shape (..., 3).")]


# What each factor of det J means (derivations.rates.velocity's singular sets), keyed by the joints it involves.
SINGULAR_NAMES = {("q2",): ("slide at the axis", "the slide retracted onto the joint-1 axis (d2 = 0): "
                                          "turning joint 1 moves nothing")}


def extend(model):
    model.singular_names = SINGULAR_NAMES
    x, y = model.task_symbols
    branches = []
    for name, sigma, eqs in (("d2_positive", 1, "Eqs. (6)-(7)"), ("d2_negative", -1, "Eq. (8)")):
        d2 = sigma * sp.sqrt(x**2 + y**2)
        q1 = atan2_of_sine_cosine(sigma * y, sigma * x)[0].value
        branches.append(IKBranch(name, (q1, d2), sp.true,
                                 f"Kumar {eqs}: d2 = {'+' if sigma > 0 else '-'}sqrt(x^2 + y^2), "
                                 f"q1 = atan2({'' if sigma > 0 else '-'}y, {'' if sigma > 0 else '-'}x); always exists"))
    model.ik = branches
    model.extra_functions = tuple(kumar_pose_functions(model))  # the robot's own kernel: Kumar's (x, y, phi)

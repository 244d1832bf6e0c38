"""Planar R-P arm: inverse kinematics, Kumar Eqs. (6)-(8), both signs of d2.

``x = d2 cos(t1)``, ``y = d2 sin(t1)`` (Eq. 5) give ``d2 = sigma sqrt(x^2 + y^2)``
and ``t1 = atan2(y / d2, x / d2)`` (section 5.4), written here as
``atan2(sigma y, sigma x)`` (the same angle, and defined at d2 = 0).
``d2_positive`` is Eqs. (6)-(7), ``d2_negative`` Eq. (8): the slide passed
through the joint axis.  Every target is reachable; at the origin t1 is free
and atan2 gives 0 (or pi, by the sign of the zero).
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import atan2_of_sine_cosine
from derivations.model import IKBranch


def extend(model):
    x, y = model.task_symbols
    branches = []
    for name, sigma, eqs in (("d2_positive", 1, "Eqs. (6)-(7)"), ("d2_negative", -1, "Eq. (8)")):
        d2 = sigma * sp.sqrt(x**2 + y**2)
        q1 = atan2_of_sine_cosine(sigma * y, sigma * x)[0].value
        branches.append(IKBranch(name, (q1, d2), sp.true,
                                 f"Kumar {eqs}: d2 = {'+' if sigma > 0 else '-'}sqrt(x^2 + y^2), "
                                 f"q1 = atan2({'' if sigma > 0 else '-'}y, {'' if sigma > 0 else '-'}x); always exists"))
    model.ik = branches

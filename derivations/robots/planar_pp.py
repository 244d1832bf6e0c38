"""Planar P-P (Cartesian) arm: the one inverse-kinematics solution, Kumar Eq. (10).

``x = d2``, ``y = d1``: each slide is a prismatic joint along a known direction
(joint 1 along the base y axis, joint 2 along the base x axis).
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import prismatic_along
from derivations.model import IKBranch


def extend(model):
    x, y = model.task_symbols
    target = sp.Matrix([x, y])
    d1 = prismatic_along(target, sp.zeros(2, 1), sp.Matrix([0, 1]))[0].value
    d2 = prismatic_along(target, sp.zeros(2, 1), sp.Matrix([1, 0]))[0].value
    model.ik = [IKBranch("unique", (d1, d2), sp.true, "Kumar Eq. (10): d1 = y, d2 = x; always exists")]

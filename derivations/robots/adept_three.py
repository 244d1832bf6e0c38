"""AdeptThree SCARA: inverse kinematics, lefty and righty (Rehiara, section 3.2).

The arm (joints 1 and 2) is Rehiara's two-link chain: theta2 from the law of
cosines (Eqs. 15-18 geometric, 22-27 algebraic, the same result) and theta1 by
the algebraic method (Eqs. 28-34) written as a sine/cosine pair solved with atan2
(``derivations.ik.two_link``); ``geometric_method`` gives the geometric route
(Eqs. 19-21), which the tests check gives the same angles.  Rehiara prints
theta1 with arcsin and arctan(y/x), which lose the quadrant, and Eq. 21 with the wrong sign: README errata E4, E5.
The quill (joint 3) is a slide along -z: ``d3 = d1 - d4 - z`` (Eq. 14), and the
wrist closes the orientation: ``phi = q1 + q2 - q4`` gives ``q4 = q1 + q2 - phi``.

Branch names, seen from above (z up): ``righty`` has theta2 in [0, pi], the elbow
to the right of the line from the shoulder to the quill like a human right arm;
``lefty`` has theta2 in [-pi, 0] (the controller's LEFTY/RIGHTY, Rehiara section 2.1).
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import prismatic_along, two_link
from derivations.model import IKBranch

from ._common import parameters

NAMES = {"positive": "righty", "negative": "lefty"}


def _branches(model, method):
    x, y, z, phi = model.task_symbols
    l1, l2, d1, d4 = parameters(model, "l1", "l2", "d1", "d4")
    q4 = model.q[3]
    d3 = prismatic_along(z, d1 - d4, -1)[0].value                  # Eq. 14: z = d1 - d4 - d3
    branches = {}
    for root, q1, q2, condition in two_link(x, y, l1, l2, method=method):
        # The wrist: phi (the model's task coordinate, linear in q) solved for q4.
        wrist = sp.solve(sp.Eq(model.task[3], phi), q4)
        assert len(wrist) == 1, wrist
        theta4 = wrist[0].xreplace({model.q[0]: q1, model.q[1]: q2})
        name = NAMES[root]
        branches[name] = IKBranch(
            name, (q1, q2, d3, theta4), condition,
            f"Rehiara Eqs. 15-18 and {'19-21' if method == 'geometric' else '28-34'} with atan2 "
            f"(q2 {'>=' if root == 'positive' else '<='} 0), d3 = d1 - d4 - z (Eq. 14), q4 = q1 + q2 - phi; "
            "exists while |l1 - l2| <= sqrt(x^2 + y^2) <= l1 + l2")
    return [branches["lefty"], branches["righty"]]


def geometric_method(model) -> list[IKBranch]:
    """The same branches with theta1 by Rehiara's geometric method (Eqs. 19-21, atan2 form)."""
    return _branches(model, "geometric")


def algebraic_method(model) -> list[IKBranch]:
    """The branches with theta1 by Rehiara's algebraic method (Eqs. 28-34, atan2 form)."""
    return _branches(model, "algebraic")


def extend(model):
    model.ik = algebraic_method(model)

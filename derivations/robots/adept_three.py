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

from derivations.ik import law_of_cosines, prismatic_along, sine_cosine_pair, substitute_steps, two_link
from derivations.model import IKBranch
from derivations.robots.extras.tool_configuration import tool_configuration_functions

from ._common import parameters

NAMES = {"positive": "righty", "negative": "lefty"}
# Rehiara's Eq. 28 groups x = (l1 + l2 c2) c1 - (l2 s2) s1, y = (l1 + l2 c2) s1 + (l2 s2) c1: k1, k2.
K1, K2 = sp.symbols("k1 k2", real=True)
STEP_CITES = ("Rehiara Eq.~27", "Rehiara Eq.~28", "Rehiara Eq.~28", "Rehiara Eqs.~29--34, atan2 form (E5)",
              "Rehiara Eq.~14", "")


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
    """The branches with theta1 by Rehiara's algebraic method (Eqs. 28-34, atan2 form), in steps as Rehiara
    writes them: theta2 (Eq. 27), k1 = l1 + l2 c2 and k2 = l2 s2 (the grouping of Eq. 28), theta1 from the
    pair x = k1 c1 - k2 s1, y = k1 s1 + k2 c1 (Eqs. 29-34, with atan2 for arcsin), d3 (Eq. 14), theta4."""
    x, y, z, phi = model.task_symbols
    l1, l2, d1, d4 = parameters(model, "l1", "l2", "d1", "d4")
    q1, q2, q3, q4 = model.q
    (wrist,) = sp.solve(sp.Eq(model.task[3], phi), q4)
    d3 = prismatic_along(z, d1 - d4, -1)[0].value                  # Eq. 14: z = d1 - d4 - d3
    branches = {}
    for elbow in law_of_cosines(x**2 + y**2, l1, l2):               # Eqs. 26-27
        (pair,) = sine_cosine_pair(K1, K2, x, y)
        steps = ((q2, elbow.value), (K1, l1 + l2 * sp.cos(q2)), (K2, l2 * sp.sin(q2)), (q1, pair.value),
                 (q3, d3), (q4, wrist))
        name = NAMES[elbow.name]
        branches[name] = IKBranch(
            name, tuple(substitute_steps(qi, steps) for qi in model.q), elbow.condition,
            f"Rehiara Eqs. 15-18 and 28-34 with atan2 (q2 {'>=' if elbow.name == 'positive' else '<='} 0), "
            "d3 = d1 - d4 - z (Eq. 14), q4 = q1 + q2 - phi; exists while |l1 - l2| <= sqrt(x^2 + y^2) <= l1 + l2",
            steps, STEP_CITES)
    return [branches["lefty"], branches["righty"]]


# What each factor of det J means (derivations.rates.velocity's singular sets), keyed by the joints it involves.
SINGULAR_NAMES = {("q2",): ("elbow", "the two arm links aligned (q2 = 0 or pi)")}


def extend(model):
    model.singular_names = SINGULAR_NAMES
    model.ik = algebraic_method(model)
    # The robot's own kernels: Rehiara's tool configuration vector and its Jacobian (Eqs. 39-42).
    model.extra_functions = tuple(tool_configuration_functions(model))

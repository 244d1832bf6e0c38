"""SCORBOT ER-VII: inverse kinematics of the tool point P5 with the gripper horizontal.

Predescu and Stroe, section 3 (Eqs. 3.1-3.11).  The task is the position of P5;
the gripper is held parallel to the base plane (Eq. 3.10,
theta2 + theta3 + theta4 = 0), and theta5 (the roll of the gripper about its own
axis) does not move P5, so the position task leaves it free: every branch sets
theta5 = 0.

In the arm's vertical plane, with the horizontal distance from the shoulder
``O2B = rho - a1 - d5`` and the height ``O4B = z - d1`` of the wrist O4 above it:

* theta1 = atan2(y, x) (Eq. 3.1), so rho = +sqrt(x^2 + y^2);
* theta3 = +-acos((O2B^2 + O4B^2 - a2^2 - a3^2) / (2 a2 a3)) (Eqs. 3.2-3.5);
* theta2 = beta - alpha with beta = atan2(O4B, O2B), alpha = atan2(a3 s3, a2 + a3 c3)
  (Eqs. 3.6-3.9), theta4 = -theta2 - theta3 (Eq. 3.11).

The shoulder flip turns the base by pi (theta1 = atan2(-y, -x), rho = -sqrt(x^2 + y^2))
and reaches P5 over the back of the robot, where the links allow it.

Branch names (stable; trajectories build on them).  ``up`` and ``down`` say whether
the elbow O3 lies above or below the line from the shoulder O2 to the wrist O4
while the wrist is ahead of the shoulder in the direction the arm reaches (along
the gripper for the direct branches, against it for the flips); the sign of
theta3 names the branch everywhere, and where the wrist passes behind the
shoulder (targets close to the base axis) above and below swap:

=============================  ==========================  ===============
name                           theta1                      theta3
=============================  ==========================  ===============
``elbow_up``                   atan2(y, x)                 -acos(...) <= 0
``elbow_down``                 atan2(y, x)                 +acos(...) >= 0
``shoulder_flip_elbow_up``     atan2(-y, -x)               +acos(...) >= 0
``shoulder_flip_elbow_down``   atan2(-y, -x)               -acos(...) <= 0
=============================  ==========================  ===============

The paper's numbers (theta2 = 13.4685 deg at M, 126.62 deg at N, Eq. 4.1) are
on ``elbow_up``, theta3 = -acos(...); Eq. 3.5 prints +acos (README, erratum E11).
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import atan2_of_sine_cosine, law_of_cosines, substitute_steps
from derivations.model import IKBranch

from ._common import parameters

ORDER = ("elbow_up", "elbow_down", "shoulder_flip_elbow_up", "shoulder_flip_elbow_down")
STEP_CITES = ("Predescu--Stroe Eq.~3.1", "Predescu--Stroe Fig.~3", "Predescu--Stroe Fig.~3",
              "Predescu--Stroe Eq.~3.4", "Predescu--Stroe Eq.~3.6", "Predescu--Stroe Eq.~3.7",
              "Predescu--Stroe Eq.~3.8", "Predescu--Stroe Eq.~3.11", "")


# The paper's intermediate quantities (Fig. 3): the horizontal and vertical distances
# from the shoulder O2 to the wrist O4, and the angles of Eqs. 3.6, 3.7.
O2B, O4B, ALPHA, BETA = sp.symbols("O2B O4B alpha beta", real=True)


# What each factor of det J means (derivations.rates.velocity's singular sets), keyed by the joints it involves.
SINGULAR_NAMES = {("q2", "q3", "q4"): ("shoulder", "the tool point P5 on the axis of joint 1"),
                  ("q3", "q4"): ("elbow", "upper arm, forearm and gripper in one line (q3 and q4 each 0 or pi)")}


def extend(model):
    model.singular_names = SINGULAR_NAMES
    x, y, z = model.task_symbols
    q1, q2, q3, q4, q5 = model.q
    a1, a2, a3, d1, d5 = parameters(model, "a1", "a2", "a3", "d1", "d5")
    branches = {}
    for flip in (False, True):
        sign = -1 if flip else 1
        for root in law_of_cosines(O2B**2 + O4B**2, a2, a3):                             # Eqs. 3.2-3.5
            steps = (
                (q1, atan2_of_sine_cosine(sign * y, sign * x)[0].value),                # Eq. 3.1 (flip: turned by pi)
                (O2B, sign * sp.sqrt(x**2 + y**2) - a1 - d5),
                (O4B, z - d1),
                (q3, root.value),                                                         # Eq. 3.5
                (ALPHA, atan2_of_sine_cosine(a3 * sp.sin(q3), a2 + a3 * sp.cos(q3))[0].value),  # Eq. 3.6
                (BETA, atan2_of_sine_cosine(O4B, O2B)[0].value),                          # Eq. 3.7
                (q2, BETA - ALPHA),                                                       # Eqs. 3.8-3.9
                (q4, -q2 - q3),                                                           # Eq. 3.11
                (q5, sp.S.Zero),                                                          # free: the choice
            )
            up = (root.name == "negative") != flip
            name = ("shoulder_flip_" if flip else "") + ("elbow_up" if up else "elbow_down")
            branches[name] = IKBranch(
                name, tuple(substitute_steps(qi, steps) for qi in model.q), substitute_steps(root.condition, steps),
                f"Predescu and Stroe Eqs. 3.1-3.11, theta1 = atan2({'-y, -x' if flip else 'y, x'}), "
                f"theta3 = {'-' if root.name == 'negative' else '+'}acos(...), theta4 = -(theta2 + theta3), "
                "theta5 = 0 (free: the position task does not fix it); exists while the wrist O4 lies between "
                "|a2 - a3| and a2 + a3 from the shoulder O2", steps, STEP_CITES)
    model.ik = [branches[name] for name in ORDER]

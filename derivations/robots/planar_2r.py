"""Planar 2R arm: inverse kinematics, elbow up and elbow down.

Rehiara's two-link chain (Eqs. 15-21, geometric method): theta2 from the law of
cosines, theta1 as the direction of the target minus the angle the first link
makes with it, both written with atan2 (see ``derivations.ik.two_link``).

Branch names: ``elbow_up`` has theta2 in [-pi, 0] (the elbow lies to the left
of the directed line from shoulder to target, that is above it when the target
is to the right of the base), ``elbow_down`` has theta2 in [0, pi].
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import atan2_of_sine_cosine, law_of_cosines, substitute_steps
from derivations.model import IKBranch

from ._common import parameters

NAMES = {"negative": "elbow_up", "positive": "elbow_down"}
# Rehiara's alpha (the direction of the target, Eq. 19) and beta (the angle of the first link from it, Eq. 20).
ALPHA, BETA = sp.symbols("alpha beta", real=True)


# What each factor of det J means (derivations.rates.velocity's singular sets), keyed by the joints it involves.
SINGULAR_NAMES = {("q2",): ("elbow", "the links aligned: arm stretched (q2 = 0) or folded (q2 = pi); "
                              "slides: |J| = l1 l2 s2 = 0")}


def extend(model):
    model.singular_names = SINGULAR_NAMES
    x, y = model.task_symbols
    q1, q2 = model.q
    l1, l2 = parameters(model, "l1", "l2")
    branches = {}
    for elbow in law_of_cosines(x**2 + y**2, l1, l2):                         # Eqs. 15-18
        root, condition = elbow.name, elbow.condition
        # Rehiara's geometric steps in his order, with atan2 for arctan and arcsin (errata E4)
        steps = ((q2, elbow.value),                                              # Eq. 18
                 (ALPHA, atan2_of_sine_cosine(y, x)[0].value),                   # Eq. 19
                 (BETA, atan2_of_sine_cosine(l2 * sp.sin(q2), l1 + l2 * sp.cos(q2))[0].value),  # Eq. 20
                 (q1, ALPHA - BETA))                                             # Eq. 21, corrected
        sign = "<=" if root == "negative" else ">="
        branches[NAMES[root]] = IKBranch(
            NAMES[root], tuple(substitute_steps(qi, steps) for qi in model.q), condition,
            f"Rehiara Eqs. 18 and 21 with atan2: q2 = {'-' if root == 'negative' else '+'}acos((x^2 + y^2 - l1^2 - l2^2)"
            f" / (2 l1 l2)) (q2 {sign} 0), q1 = atan2(y, x) - atan2(l2 sin q2, l1 + l2 cos q2); "
            "exists while |l1 - l2| <= sqrt(x^2 + y^2) <= l1 + l2", steps)
    model.ik = [branches["elbow_up"], branches["elbow_down"]]

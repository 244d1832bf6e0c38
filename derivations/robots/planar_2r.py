"""Planar 2R arm: inverse kinematics, elbow up and elbow down.

Rehiara's two-link chain (Eqs. 15-21, geometric method): theta2 from the law of
cosines, theta1 as the direction of the target minus the angle the first link
makes with it, both written with atan2 (see ``derivations.ik.two_link``).

Branch names: ``elbow_up`` has theta2 in [-pi, 0] (the elbow lies to the left
of the directed line from shoulder to target, that is above it when the target
is to the right of the base), ``elbow_down`` has theta2 in [0, pi].
"""
from __future__ import annotations

from derivations.ik import two_link
from derivations.model import IKBranch

from ._common import parameters

NAMES = {"negative": "elbow_up", "positive": "elbow_down"}


def extend(model):
    x, y = model.task_symbols
    l1, l2 = parameters(model, "l1", "l2")
    branches = {}
    for root, q1, q2, condition in two_link(x, y, l1, l2, method="geometric"):
        sign = "<=" if root == "negative" else ">="
        branches[NAMES[root]] = IKBranch(
            NAMES[root], (q1, q2), condition,
            f"Rehiara Eqs. 18 and 21 with atan2: q2 = {'-' if root == 'negative' else '+'}acos((x^2 + y^2 - l1^2 - l2^2)"
            f" / (2 l1 l2)) (q2 {sign} 0), q1 = atan2(y, x) - atan2(l2 sin q2, l1 + l2 cos q2); "
            "exists while |l1 - l2| <= sqrt(x^2 + y^2) <= l1 + l2")
    model.ik = [branches["elbow_up"], branches["elbow_down"]]

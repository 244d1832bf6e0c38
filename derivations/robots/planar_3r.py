"""Planar 3R arm: inverse kinematics by Kumar's Eqs. (d)-(j), both values of sigma.

Kumar, section 5.4: with the wrist point ``x' = x - l3 cos(phi)``,
``y' = y - l3 sin(phi)`` (Eqs. d, e), squaring and adding gives Eq. (f),
``(-2 l1 x') cos(t1) + (-2 l1 y') sin(t1) + (x'^2 + y'^2 + l1^2 - l2^2) = 0``,
of the form P cos + Q sin + R = 0 (Eq. g), solved by Appendix 2: Eq. (h) as Kumar
prints it, ``t1 = gamma + sigma acos(-(x'^2 + y'^2 + l1^2 - l2^2) / (2 l1 sqrt(x'^2 + y'^2)))``
with ``gamma = atan2(-y' / sqrt(x'^2 + y'^2), -x' / sqrt(x'^2 + y'^2))`` (the roots of
``derivations.ik.p_cos_q_sin_r`` for Eq. (f), divided through by 2 l1 > 0; tested);
then ``t2 = atan2((y' - l1 s1)/l2, (x' - l1 c1)/l2) - t1`` (Eq. i) and
``t3 = phi - t1 - t2`` (Eq. j).  The steps are these, in Kumar's order.

Branch names follow the planar 2R arm: ``elbow_up`` has t2 in [-pi, 0] (sigma = -1),
``elbow_down`` has t2 in [0, pi] (sigma = +1).  Kumar's Fig. 14 caption calls
sigma = +1 "elbow-up"; with Eq. (h) as printed, sigma = +1 puts the elbow to the
right of the line from the base to the wrist, below it for a wrist to the right
of the base (README, "Choices the papers leave open"; tests/ik/test_ik.py).
"""
from __future__ import annotations

import sympy as sp

from derivations.ik import acos_clamped, atan2_of_sine_cosine, substitute_steps, within_unit
from derivations.model import IKBranch

from ._common import parameters

NAMES = {"sigma_minus": "elbow_up", "sigma_plus": "elbow_down"}


WRIST = sp.symbols("x' y'", real=True)   # Kumar's x', y': the wrist point
GAMMA = sp.Symbol("gamma", real=True)     # Kumar's gamma of Eq. (h) (Appendix 2)
STEP_CITES = ("Kumar Eq.~(d)", "Kumar Eq.~(e)", "Kumar Eq.~(h)", "Kumar Eq.~(h)", "Kumar Eq.~(i)", "Kumar Eq.~(j)")


def wrist_point(model):
    """Kumar Eqs. (d), (e): the point the first two links must reach."""
    x, y, phi = model.task_symbols
    (l3,) = parameters(model, "l3")
    return x - l3 * sp.cos(phi), y - l3 * sp.sin(phi)


def kumar_eq_f(model, xw=None, yw=None):
    """Kumar Eq. (f) as (P, Q, R) of Eq. (g): P cos(t1) + Q sin(t1) + R = 0 (in x', y' if given)."""
    l1, l2 = parameters(model, "l1", "l2")
    if xw is None:
        xw, yw = wrist_point(model)
    return -2 * l1 * xw, -2 * l1 * yw, xw**2 + yw**2 + l1**2 - l2**2


# What each factor of det J means (derivations.rates.velocity's singular sets), keyed by the joints it involves.
SINGULAR_NAMES = {("q2",): ("elbow", "links 1 and 2 aligned (q2 = 0 or pi); Kumar Eq. 13: |J| = l1 l2 sin(theta2)")}


def extend(model):
    model.singular_names = SINGULAR_NAMES
    x, y, phi = model.task_symbols
    q1, q2, q3 = model.q
    l1, l2 = parameters(model, "l1", "l2")
    xw, yw = WRIST
    reach = sp.sqrt(xw**2 + yw**2)
    # Kumar Eq. (h): Appendix 2 for Eq. (f), P = -2 l1 x', Q = -2 l1 y', sqrt(P^2 + Q^2) = 2 l1 sqrt(x'^2 + y'^2).
    cosine = -(xw**2 + yw**2 + l1**2 - l2**2) / (2 * l1 * reach)
    branches = {}
    for root_name, sigma in (("sigma_plus", 1), ("sigma_minus", -1)):
        q12 = atan2_of_sine_cosine((yw - l1 * sp.sin(q1)) / l2, (xw - l1 * sp.cos(q1)) / l2)[0].value
        steps = (
            (xw, wrist_point(model)[0]),                                           # Kumar Eq. (d)
            (yw, wrist_point(model)[1]),                                           # Kumar Eq. (e)
            (GAMMA, sp.atan2(-yw / reach, -xw / reach)),                           # Kumar Eq. (h), gamma
            (q1, GAMMA + sigma * acos_clamped(cosine)),                            # Kumar Eq. (h)
            (q2, q12 - q1),                                                        # Kumar Eq. (i)
            (q3, phi - q1 - q2),                                                   # Kumar Eq. (j)
        )
        name = NAMES[root_name]
        condition = sp.And(xw**2 + yw**2 > 0, within_unit(cosine))
        branches[name] = IKBranch(
            name, tuple(substitute_steps(qi, steps) for qi in model.q), substitute_steps(condition, steps),
            f"Kumar Eqs. (h)-(j) with sigma = {sigma:+d}; exists while the wrist point (x - l3 cos phi, "
            "y - l3 sin phi) lies between |l1 - l2| and l1 + l2 from the base (and not on it)", steps, STEP_CITES)
    model.ik = [branches["elbow_up"], branches["elbow_down"]]

"""Geometric subproblems on the joint axes, each with every root and its existence condition.

The names follow Paden and Kahan's subproblems as IK-Geo (Elias and Wen, 2022)
numbers them; the forms are ours, written so that the generated code never divides
by zero and never takes ``acos`` of more than one in magnitude (:class:`ClampUnit`,
:class:`Ramp`: clips that SymPy leaves alone on long arguments):

* :func:`angle_onto` (subproblem 1): the angle about a unit axis ``k`` that turns
  ``a`` onto ``b``: one root, ``atan2(k . (a x b), a . b - (k . a)(k . b))``, exact
  wherever the two have the same height along ``k`` and the same distance from it;
  where both lie on the axis the angle is free and atan2 gives 0.
* :func:`angle_to_height` (subproblem 4): the angles that give ``rot(k, theta) v``
  the height ``d`` along ``h``: ``P cos + Q sin + R = 0`` with ``P = h . v_perp``,
  ``Q = h . (k x v)``, ``R = (h . k)(k . v) - d``.  Two roots
  ``atan2(Q, P) +- acos(-R / sqrt(P^2 + Q^2))``, existing while
  ``R^2 <= (1 + 2 ACOS_TOLERANCE)(P^2 + Q^2)`` (squared: no ``Abs`` of a long expression,
  which SymPy would try to simplify).  Where ``R`` is zero for every
  value of the parameters (an orthogonal wrist) the roots are ``atan2(Q, P) +- pi/2``:
  no ``acos`` at all.  Where ``P`` and ``Q`` vanish (``v`` on the axis ``k``: an arm
  stretched along a roll axis) the turn leaves the height alone and the angle is free
  (:data:`FREE_ANGLE`).
* :func:`angle_to_distance` (subproblem 3): the angles that put ``a + rot(k, theta) b``
  at distance ``delta`` from the origin: the same equation with
  ``P = 2 a . b_perp``, ``Q = 2 a . (k x b)``,
  ``R = |a|^2 + |b|^2 + 2 (k . a)(k . b) - delta^2``.
* :func:`slide_to_distance`: the displacements ``t`` that put ``a + t k`` at distance
  ``delta``: ``t = -k . a +- sqrt((k . a)^2 - |a|^2 + delta^2)``.
* :func:`cone_angle`: the angles that turn the unit vector ``v`` about ``k`` onto the
  cone of half-angle ``acos(h . u)`` about ``h`` where ``h``, ``k`` and ``v`` are mutually
  perpendicular (``h . k = k . v = 0``): ``theta = beta +- atan2(|h x u|, h . u)``,
  ``beta = atan2(h . (k x v), h . v)``.  The same roots as subproblem 4 with
  ``d = h . u`` but from a whole known vector ``u``, so an angle near 0 or pi keeps
  every digit (``acos`` near one loses half of them).

Subproblem 2 (two rotations about axes that meet) is subproblem 4 for the second
angle and subproblem 1 for the first, composed in :mod:`derivations.ik.decompose`.
"""
from __future__ import annotations

import sympy as sp

from .primitives import ACOS_TOLERANCE, ClampUnit, Ramp, Root, written_piecewise
from .structure import cross, dot

__all__ = ["angle_onto", "angle_to_height", "angle_to_distance", "distance_coefficients", "slide_to_distance",
           "cone_angle", "TINY", "FREE_ANGLE"]

# Added to sqrt(P^2 + Q^2) in -R / sqrt(P^2 + Q^2): keeps the division finite where
# P = Q = 0 (the root is then free, or does not exist; the condition says which) and
# changes no other quotient (a double norm below 1e-284 is the only one it moves).
TINY = sp.Float("1e-300")

# sqrt(P^2 + Q^2) at or below FREE_ANGLE times the equation's scale (``|h| |v|`` for subproblem 4,
# ``2 |a| |b|`` for subproblem 3, its largest value) is a turn that changes nothing the equation
# measures: the vector lies on the axis (an arm stretched along its upper arm's roll axis, the
# PR2's at q4 = 0), and P and Q are rounding, ~1e-16 of the scale.  The equation is then
# ``R = 0`` for every angle: it holds where |R| is within FREE_ANGLE of the scale, and the angle
# is chosen, 0 (the joint's zero) for the root ``plus`` and pi for ``minus``, two configurations
# of the continuum, the same in every backend.  Before, ``R^2 <= P^2 + Q^2`` compared one
# rounding error with another and refused such targets (19 of the PR2's 50 degenerate ones).
# A chosen angle moves the pose by at most 2 FREE_ANGLE times the scale.
FREE_ANGLE = sp.Float("1e-12")


def angle_onto(k, a, b) -> sp.Expr:
    """Subproblem 1: theta with ``rot(k, theta) a = b`` (one root, always defined)."""
    return sp.atan2(dot(k, cross(a, b)), dot(a, b) - dot(k, a) * dot(k, b))


def _two_roots(P, Q, R, scale_squared, what: str) -> list[Root]:
    """Both roots of ``P cos + Q sin + R = 0``; ``scale_squared`` the square of the largest
    ``sqrt(P^2 + Q^2)`` the equation can have, for its free case (:data:`FREE_ANGLE`)."""
    gamma = sp.atan2(Q, P)
    if R == 0:   # every angle's root exists; at P = Q = 0 (free) atan2 gives 0: +-pi/2
        return [Root("plus", gamma + sp.pi / 2, sp.true, f"{what}: atan2(Q, P) + pi/2 (R = 0)"),
                Root("minus", gamma - sp.pi / 2, sp.true, f"{what}: atan2(Q, P) - pi/2 (R = 0)")]
    norm_squared = P**2 + Q**2
    spread = sp.acos(ClampUnit(-R / (sp.sqrt(norm_squared) + TINY)))
    exists = R**2 <= (1 + 2 * ACOS_TOLERANCE) * norm_squared
    small = FREE_ANGLE**2 * scale_squared
    if (norm_squared - small).is_number and norm_squared - small > 0:   # never free (constant P and Q)
        return [Root("plus", gamma + spread, exists, f"{what}: atan2(Q, P) + acos(-R / sqrt(P^2 + Q^2))"),
                Root("minus", gamma - spread, exists, f"{what}: atan2(Q, P) - acos(-R / sqrt(P^2 + Q^2))")]
    free = sp.LessThan(norm_squared, small, evaluate=False)
    # (R^2 <= small with P^2 + Q^2 above it is within the first condition: one Or covers both)
    exists = sp.Or(exists, R**2 <= small)
    free_doc = "; free where P = Q = 0 (0 or pi)"
    return [Root("plus", written_piecewise((0, free), (gamma + spread, sp.true)), exists,
                 f"{what}: atan2(Q, P) + acos(-R / sqrt(P^2 + Q^2)){free_doc}"),
            Root("minus", written_piecewise((sp.pi, free), (gamma - spread, sp.true)), exists,
                 f"{what}: atan2(Q, P) - acos(-R / sqrt(P^2 + Q^2)){free_doc}")]


def height_coefficients(h, k, v, d):
    """(P, Q, R) of ``h . rot(k, theta) v = d`` as ``P cos + Q sin + R = 0``."""
    along = dot(k, v)
    v_perp = sp.Matrix(v) - sp.Matrix(k) * along
    return dot(h, v_perp), dot(h, cross(k, v)), dot(h, k) * along - d


def angle_to_height(h, k, v, d) -> list[Root]:
    """Subproblem 4: theta with ``h . rot(k, theta) v = d``."""
    P, Q, R = height_coefficients(h, k, v, d)
    return _two_roots(P, Q, R, dot(h, h) * dot(v, v), "subproblem 4")


def distance_coefficients(k, a, b):
    """(P, Q, S) with ``|a + rot(k, theta) b|^2 = S + P cos(theta) + Q sin(theta)``: the squared
    distance ranges over ``S +- sqrt(P^2 + Q^2)`` as theta turns."""
    along = dot(k, b)
    b_perp = sp.Matrix(b) - sp.Matrix(k) * along
    return 2 * dot(a, b_perp), 2 * dot(a, cross(k, b)), dot(a, a) + dot(b, b) + 2 * dot(k, a) * along


def angle_to_distance(k, a, b, delta_squared) -> list[Root]:
    """Subproblem 3: theta with ``|a + rot(k, theta) b|^2 = delta_squared``."""
    P, Q, S = distance_coefficients(k, a, b)
    return _two_roots(P, Q, S - delta_squared, 4 * dot(a, a) * dot(b, b), "subproblem 3")


def slide_to_distance(k, a, delta_squared) -> list[Root]:
    """t with ``|a + t k|^2 = delta_squared`` (``k`` a unit vector): two roots."""
    b = dot(k, a)
    discriminant = b**2 - dot(a, a) + delta_squared
    root = sp.sqrt(Ramp(discriminant))
    exists = discriminant >= -ACOS_TOLERANCE * (b**2 + delta_squared)
    return [Root("plus", -b + root, exists, "t = -k.a + sqrt((k.a)^2 - |a|^2 + delta^2)"),
            Root("minus", -b - root, exists, "t = -k.a - sqrt((k.a)^2 - |a|^2 + delta^2)")]


def cone_angle(h, k, v, u) -> list[Root]:
    """theta with ``h . rot(k, theta) v = h . u`` for mutually perpendicular unit h, k, v (see the module)."""
    beta = sp.atan2(dot(h, cross(k, v)), dot(h, v))
    side = cross(h, u)
    spread = sp.atan2(sp.sqrt(dot(side, side)), dot(h, u))
    return [Root("plus", beta + spread, sp.true, "beta + atan2(|h x u|, h . u)"),
            Root("minus", beta - spread, sp.true, "beta - atan2(|h x u|, h . u)")]

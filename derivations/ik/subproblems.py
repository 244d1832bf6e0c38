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
  no ``acos`` at all.
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

from .primitives import ACOS_TOLERANCE, ClampUnit, Ramp, Root
from .structure import cross, dot

__all__ = ["angle_onto", "angle_to_height", "angle_to_distance", "distance_coefficients", "slide_to_distance",
           "cone_angle", "TINY"]

# Added to sqrt(P^2 + Q^2) in -R / sqrt(P^2 + Q^2): keeps the division finite where
# P = Q = 0 (the root is then free, or does not exist; the condition says which) and
# changes no other quotient (a double norm below 1e-284 is the only one it moves).
TINY = sp.Float("1e-300")


def angle_onto(k, a, b) -> sp.Expr:
    """Subproblem 1: theta with ``rot(k, theta) a = b`` (one root, always defined)."""
    return sp.atan2(dot(k, cross(a, b)), dot(a, b) - dot(k, a) * dot(k, b))


def _two_roots(P, Q, R, what: str) -> list[Root]:
    gamma = sp.atan2(Q, P)
    if R == 0:
        return [Root("plus", gamma + sp.pi / 2, sp.true, f"{what}: atan2(Q, P) + pi/2 (R = 0)"),
                Root("minus", gamma - sp.pi / 2, sp.true, f"{what}: atan2(Q, P) - pi/2 (R = 0)")]
    norm = sp.sqrt(P**2 + Q**2)
    spread = sp.acos(ClampUnit(-R / (norm + TINY)))
    exists = R**2 <= (1 + 2 * ACOS_TOLERANCE) * (P**2 + Q**2)
    return [Root("plus", gamma + spread, exists, f"{what}: atan2(Q, P) + acos(-R / sqrt(P^2 + Q^2))"),
            Root("minus", gamma - spread, exists, f"{what}: atan2(Q, P) - acos(-R / sqrt(P^2 + Q^2))")]


def height_coefficients(h, k, v, d):
    """(P, Q, R) of ``h . rot(k, theta) v = d`` as ``P cos + Q sin + R = 0``."""
    along = dot(k, v)
    v_perp = sp.Matrix(v) - sp.Matrix(k) * along
    return dot(h, v_perp), dot(h, cross(k, v)), dot(h, k) * along - d


def angle_to_height(h, k, v, d) -> list[Root]:
    """Subproblem 4: theta with ``h . rot(k, theta) v = d``."""
    P, Q, R = height_coefficients(h, k, v, d)
    return _two_roots(P, Q, R, "subproblem 4")


def distance_coefficients(k, a, b):
    """(P, Q, S) with ``|a + rot(k, theta) b|^2 = S + P cos(theta) + Q sin(theta)``: the squared
    distance ranges over ``S +- sqrt(P^2 + Q^2)`` as theta turns."""
    along = dot(k, b)
    b_perp = sp.Matrix(b) - sp.Matrix(k) * along
    return 2 * dot(a, b_perp), 2 * dot(a, cross(k, b)), dot(a, a) + dot(b, b) + 2 * dot(k, a) * along


def angle_to_distance(k, a, b, delta_squared) -> list[Root]:
    """Subproblem 3: theta with ``|a + rot(k, theta) b|^2 = delta_squared``."""
    P, Q, S = distance_coefficients(k, a, b)
    return _two_roots(P, Q, S - delta_squared, "subproblem 3")


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

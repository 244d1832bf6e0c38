"""An arm read from its tool to its base: the families of :mod:`derivations.ik.decompose` for arms
whose special structure is at the base (a spherical shoulder, three parallel axes from the base).

With the product of exponentials of :mod:`derivations.ik.structure`,

    T = E_1(q_1) ... E_n(q_n) M    gives    M T^-1 = E_n(-q_n) ... E_1(-q_1),

a product of exponentials about the same lines, taken in the reverse order, with the joint values
negated and the identity as its home pose.  The reversed arm's joint k is the line of joint
n + 1 - k, its value ``q'_k = -q_{n+1-k}``, and its target pose ``T' = M T^-1``.  An arm whose
axes 1, 2, 3 meet (a spherical shoulder) is, reversed, an arm whose axes 4, 5, 6 meet: the
spherical-wrist family solves it and the answers come back by reversing the order and negating.

(The same reversal is often written ``T^-1 = E'_1(q'_1) ... E'_n(q'_n) M^-1`` with
``E'_k = M^-1 E_{n+1-k} M``, the twists carried by ``Ad_{M^-1}``: conjugating both sides by M
gives the form above.  Keeping the lines where they are keeps them free of a held joint's angle,
which a seven-joint arm's ``M`` carries when its last joint is held; only the target carries it.)
"""
from __future__ import annotations

import sympy as sp

from .structure import Axis, Structure

__all__ = ["reversed_structure", "reversed_joints", "reversed_target", "SWAPPED_LABELS"]


def reversed_structure(S: Structure) -> Structure:
    """The axes of ``S`` in the reverse order (joint k the line of joint n + 1 - k, as it lies at
    q = 0), with the identity for home pose."""
    axes = tuple(Axis(k, a.kind, a.h, a.p) for k, a in enumerate(reversed(S.axes)))
    return Structure(axes, sp.eye(4), S.task, S.held)


def reversed_joints(q) -> list[sp.Symbol]:
    """The reversed arm's joint symbols, in its order: ``q_k_rev`` stands for ``-q_k``."""
    return [sp.Symbol(f"{qi.name}_rev", real=True) for qi in reversed(tuple(q))]


def reversed_target(home: sp.Matrix, R: sp.Matrix, p: sp.Matrix) -> tuple[sp.Matrix, sp.Matrix]:
    """The reversed arm's target ``M T^-1`` as (rotation, position), for the target pose T = (R, p)
    and the arm's home pose M: ``(R_M R^T, p_M - R_M R^T p)``."""
    RM, pM = home[:3, :3], home[:3, 3]
    rotation = R.T if RM == sp.eye(3) else RM * R.T
    return rotation, pM - rotation * p


# A reversed arm's root choices, named for where they are on the real arm: the reversed arm's
# wrist (its joints 4 to 6) is the real arm's shoulder, and its joint 1 (a UR's "shoulder") the
# real arm's last joint.
SWAPPED_LABELS = {"shoulder": "wrist", "wrist": "shoulder"}

"""Paul's wrist-partitioned velocity model of a 6-joint arm with a spherical wrist.

Velocity-model slides, "6 DOF serial robot velocity model (Paul)": when the axes
of joints 4, 5 and 6 meet in one point, the wrist centre ``O_wrist``, the
Jacobian of that point is block lower-triangular,

    [V_wrist; w] = J_wrist q_dot,    J_wrist = [[A, 0], [C, D]]
    A = [z_0 x (O_wrist - o_0), z_1 x (O_wrist - o_1), z_2 x (O_wrist - o_2)]
    C = [z_0, z_1, z_2],   D = [z_3, z_4, z_5]

(the slides write ``Z_w0 Z_w1 Z_w2`` for the wrist axes ``z_3 z_4 z_5``; a
prismatic arm joint contributes ``z`` to A and 0 to C), and the tool point
follows as ``V_E = V_wrist + w x (O_E - O_wrist)``, ``w_E = w``.

The inverse therefore needs two 3 x 3 solves instead of one 6 x 6 solve:

    V_wrist = V_E - w x (O_E - O_wrist)
    q_dot[1:3] = A^-1 V_wrist                        (arm: shoulder and elbow)
    q_dot[4:6] = D^-1 (w - C q_dot[1:3])             (wrist)

and ``det J = det A det D`` splits the singularities into arm and wrist terms.
Axes are those of :meth:`Chain.joint_axes` (``z_{i-1}`` through ``o_{i-1}`` in
standard DH), so the same code serves either DH convention.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ..chain import PRISMATIC, REVOLUTE, simplify_product
from .damping import (ClosedFormInverse, Minors, Scaling, closed_form_inverse, measure_squared,
                      regularised_solve, singular_flag)

__all__ = ["WristBlocks", "WristPartition", "wrist_blocks", "wrist_partition", "skew"]


def skew(v) -> sp.Matrix:
    """``[v]x``: the matrix with ``[v]x u = v x u``."""
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


@dataclass(frozen=True)
class WristPartition:
    """Paul's partition of one arm (all matrices in the base frame).

    ``wrist_centre`` O_wrist (3 x 1); ``tool_offset`` O_E - O_wrist (3 x 1);
    ``A``, ``C``, ``D`` (3 x 3 blocks); ``arm_inverse``, ``wrist_inverse`` the closed
    forms of ``A^-1`` and ``D^-1``; ``arm_scaling``, ``wrist_scaling`` their units.
    """

    wrist_centre: sp.Matrix
    tool_offset: sp.Matrix
    A: sp.Matrix
    C: sp.Matrix
    D: sp.Matrix
    arm_inverse: ClosedFormInverse
    wrist_inverse: ClosedFormInverse
    arm_scaling: Scaling
    wrist_scaling: Scaling
    arm_minors: Minors
    wrist_minors: Minors

    @property
    def wrist_jacobian(self) -> sp.Matrix:
        """``J_wrist = [[A, 0], [C, D]]``: the geometric Jacobian of the wrist centre."""
        return sp.Matrix.vstack(sp.Matrix.hstack(self.A, sp.zeros(3, 3)), sp.Matrix.hstack(self.C, self.D))

    @property
    def tool_jacobian(self) -> sp.Matrix:
        """``[[I, -[r]x], [0, I]] J_wrist`` with ``r = O_E - O_wrist``: V_E = V_wrist + w x r."""
        return WristBlocks(self.wrist_centre, self.tool_offset, self.A, self.C, self.D).tool_jacobian

    @property
    def determinant(self) -> sp.Expr:
        """``det J = det A det D`` (the shift has determinant 1)."""
        return self.arm_inverse.determinant * self.wrist_inverse.determinant

    def solve(self, twist: sp.Matrix) -> tuple[sp.Matrix, sp.Basic]:
        """Joint rates from the tool twist ``[V_E; w]`` by two 3 x 3 solves; and the singular flag.

        Each block is solved by :func:`derivations.rates.damping.regularised_solve` with
        its own measure (``|det A| / L^3`` for the arm, ``|det D|`` for the wrist),
        so a wrist singularity damps only the wrist rates.
        """
        v, w = twist[:3, 0], twist[3:, 0]
        v_wrist = v - w.cross(self.tool_offset)
        arm = regularised_solve(self.A, v_wrist, self.arm_scaling, self.arm_minors, self.arm_inverse)
        wrist = regularised_solve(self.D, w - self.C * arm.solution, self.wrist_scaling, self.wrist_minors,
                                  self.wrist_inverse)
        return sp.Matrix.vstack(arm.solution, wrist.solution), sp.Or(arm.singular, wrist.singular)

    def singular_flags(self) -> tuple[sp.Basic, sp.Basic]:
        """The arm and the wrist singular flags (``mu < mu_0`` of each block)."""
        return (singular_flag(measure_squared(self.arm_minors, self.arm_scaling)),
                singular_flag(measure_squared(self.wrist_minors, self.wrist_scaling)))


@dataclass(frozen=True)
class WristBlocks:
    """The blocks of Paul's partition (no inverses): see :class:`WristPartition`."""

    wrist_centre: sp.Matrix
    tool_offset: sp.Matrix
    A: sp.Matrix
    C: sp.Matrix
    D: sp.Matrix

    @property
    def tool_jacobian(self) -> sp.Matrix:
        """``[[I, -[r]x], [0, I]] [[A, 0], [C, D]]`` with ``r = O_E - O_wrist``: V_E = V_wrist + w x r."""
        wrist = sp.Matrix.vstack(sp.Matrix.hstack(self.A, sp.zeros(3, 3)), sp.Matrix.hstack(self.C, self.D))
        shift = sp.Matrix.vstack(sp.Matrix.hstack(sp.eye(3), -skew(self.tool_offset)),
                                 sp.Matrix.hstack(sp.zeros(3, 3), sp.eye(3)))
        return (shift * wrist).applyfunc(simplify_product)


def wrist_blocks(model) -> WristBlocks | None:
    """Paul's blocks of ``model``, or None when it has no spherical wrist.

    Needs six joints, the last three revolute, and a point common to their axes;
    the candidates are the points the axes are given through, and one is accepted
    only when ``z_i x (O_wrist - o_i)`` simplifies to zero for each wrist axis
    (the B block of the slides is then exactly 0).
    """
    chain = model.chain
    if chain is None or model.n != 6 or any(t != REVOLUTE for t in model.joint_types[3:]):
        return None
    axes = chain.joint_axes(model.frames)
    wrist_axes = axes[3:]
    centre = None
    for _, candidate in wrist_axes:
        if all((z.cross(candidate - o)).applyfunc(simplify_product) == sp.zeros(3, 1) for z, o in wrist_axes):
            centre = candidate
            break
    if centre is None:
        return None
    arm_linear, arm_angular = [], []
    for joint_type, (z, o) in zip(model.joint_types[:3], axes[:3]):
        if joint_type == PRISMATIC:
            arm_linear.append(z)
            arm_angular.append(sp.zeros(3, 1))
        else:
            arm_linear.append(z.cross(centre - o))
            arm_angular.append(z)
    return WristBlocks(
        wrist_centre=centre, tool_offset=(model.fk[:3, 3] - centre).applyfunc(simplify_product),
        A=sp.Matrix.hstack(*arm_linear).applyfunc(simplify_product), C=sp.Matrix.hstack(*arm_angular),
        D=sp.Matrix.hstack(*[z for z, _ in wrist_axes]))


def wrist_partition(model, reference_length: sp.Expr) -> WristPartition | None:
    """Paul's partition of ``model`` with the closed-form block inverses (None: no spherical wrist)."""
    blocks = wrist_blocks(model)
    if blocks is None:
        return None
    A, D = blocks.A, blocks.D
    arm_columns = tuple(1 if t == PRISMATIC else 0 for t in model.joint_types[:3])
    arm_inverse, wrist_inverse = closed_form_inverse(A), closed_form_inverse(D)
    return WristPartition(
        wrist_centre=blocks.wrist_centre, tool_offset=blocks.tool_offset, A=A, C=blocks.C, D=D,
        arm_inverse=arm_inverse, wrist_inverse=wrist_inverse,
        arm_scaling=Scaling(reference_length, (1, 1, 1), arm_columns),
        wrist_scaling=Scaling(reference_length, (0, 0, 0), (0, 0, 0)),
        arm_minors=Minors.of_square(A, arm_inverse), wrist_minors=Minors.of_square(D, wrist_inverse),
    )

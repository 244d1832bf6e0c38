"""Inertial parameters of the links of a chain: what the equations of motion read.

Each moving link k (the body joint k moves) has a mass, the centre of mass ``com`` and the
inertia tensor about the centre of mass, both in the axes of the link's frame k (the frame
``frames[k]`` of the model: the DH frame k of a description, the child link of joint k of a URDF,
the tip link for the last joint of a URDF chain).  The tensor is stored as its six distinct
entries in URDF's order ``ixx, ixy, ixz, iyy, iyz, izz``.

:func:`check_physical` holds a link to what a rigid body can be: a mass that is finite and not
negative, a symmetric tensor that is positive definite (semi-definite for a massless link, whose
tensor must then be zero) and whose principal moments meet the triangle inequalities
``I1 + I2 >= I3`` (each moment is an integral of a sum of two squared coordinates, so no one
exceeds the sum of the other two).  :func:`combine` is the rigid union of bodies in one frame
(the parallel-axis theorem, Steiner): the fixed links a URDF hangs on a moving one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

__all__ = ["Inertial", "Actuator", "check_physical", "check_actuator", "combine", "transformed", "INERTIA_ORDER",
           "ACTUATOR_KEYS", "RELATIVE_TOLERANCE"]

INERTIA_ORDER = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
# Rounding in a file's decimals: a principal moment or a triangle inequality may miss by this much
# of the largest moment (a rod written with izz = 0 to 6 digits) without being refused.
RELATIVE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Inertial:
    """One link's inertial parameters (SI): ``mass`` (kg), ``com`` (m, link frame) and the
    tensor about the centre of mass (kg m^2, link frame axes; ``ixx, ixy, ixz, iyy, iyz, izz``).
    Each entry is a SymPy number, a parameter symbol or an expression of parameters."""

    mass: sp.Expr
    com: tuple[sp.Expr, sp.Expr, sp.Expr]
    inertia: tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr, sp.Expr, sp.Expr]

    def tensor(self) -> sp.Matrix:
        """The 3 x 3 tensor about the centre of mass."""
        xx, xy, xz, yy, yz, zz = self.inertia
        return sp.Matrix([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])

    def numbers(self, values: dict | None = None) -> tuple[float, np.ndarray, np.ndarray]:
        """(mass, com, tensor) as floats, with ``values`` ({symbol: number}) put in for parameters."""
        subs = {s: sp.Float(v, 30) for s, v in (values or {}).items()}

        def number(e):
            return float(sp.sympify(e).xreplace(subs).evalf(30))
        return (number(self.mass), np.array([number(c) for c in self.com]),
                np.array(self.tensor().applyfunc(lambda e: number(e)).tolist(), dtype=float))

    @classmethod
    def from_numbers(cls, mass: float, com, tensor) -> "Inertial":
        """Floats to SymPy: a zero stays exactly zero (so that the equations drop its terms)."""
        def exact(x: float):
            return sp.S.Zero if x == 0 else sp.Float(float(x))
        t = np.asarray(tensor, dtype=float)
        return cls(exact(mass), tuple(exact(c) for c in com),
                   tuple(exact(t[i, j]) for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))))


def check_physical(mass: float, com, tensor, fail) -> None:
    """Refuse (``fail(message)``) what no rigid body has: see the module's docstring."""
    com, tensor = np.asarray(com, dtype=float), np.asarray(tensor, dtype=float)
    if not (math.isfinite(mass) and np.all(np.isfinite(com)) and np.all(np.isfinite(tensor))):
        fail("mass, centre of mass and inertia must be finite numbers")
    if mass < 0:
        fail(f"mass {mass:g} kg is negative")
    scale = max(float(np.max(np.abs(tensor))), 1e-300)
    if np.max(np.abs(tensor - tensor.T)) > RELATIVE_TOLERANCE * scale:
        fail("the inertia tensor is not symmetric")
    if mass == 0:
        if np.any(tensor != 0):
            fail("mass 0 with a non-zero inertia tensor (a massless link has no rotational inertia)")
        return
    moments = np.linalg.eigvalsh((tensor + tensor.T) / 2)
    point_mass = not np.any(tensor)  # a point mass: the limit that URDF files write for small parts
    if moments[0] <= 0 and not point_mass:
        fail(f"the inertia tensor is not positive definite (principal moments "
             f"{', '.join(f'{m:.6g}' for m in moments)} kg m^2)")
    a, b, c = moments
    if a + b < c * (1 - RELATIVE_TOLERANCE) - RELATIVE_TOLERANCE * scale:
        fail(f"the principal moments {a:.6g}, {b:.6g}, {c:.6g} kg m^2 break the triangle inequality "
             f"({a:.6g} + {b:.6g} < {c:.6g}): no rigid body has them")


def transformed(mass: float, com, tensor, rotation, translation) -> tuple[float, np.ndarray, np.ndarray]:
    """A body given in frame B, expressed in frame A where ``x_A = rotation x_B + translation``."""
    rotation = np.asarray(rotation, dtype=float)
    return mass, rotation @ np.asarray(com, dtype=float) + np.asarray(translation, dtype=float), \
        rotation @ np.asarray(tensor, dtype=float) @ rotation.T


def combine(bodies) -> tuple[float, np.ndarray, np.ndarray]:
    """The rigid union of ``bodies`` [(mass, com, tensor about com)], all in one frame:
    total mass, centre of mass, and tensor about that centre (parallel-axis theorem)."""
    total = math.fsum(m for m, _, _ in bodies)
    if total == 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    centre = sum(m * np.asarray(c, dtype=float) for m, c, _ in bodies) / total
    tensor = np.zeros((3, 3))
    for m, c, inertia in bodies:
        d = np.asarray(c, dtype=float) - centre
        tensor += np.asarray(inertia, dtype=float) + m * (d @ d * np.eye(3) - np.outer(d, d))
    return total, centre, tensor


# An actuator's fields in a description, in this order: the rotor's inertia about its axis (kg m^2,
# at the motor), the gear ratio G (motor turns per joint turn), viscous friction Fv (N m s/rad, or N s/m
# for a prismatic joint) and Coulomb friction Fc (N m, or N).
ACTUATOR_KEYS = ("rotor_inertia", "gear_ratio", "viscous", "coulomb")


@dataclass(frozen=True)
class Actuator:
    """A joint's drive as the equations of motion see it: the rotor reflected through its gear,
    the armature ``Ia = Ir G^2`` (kg m^2; added to M's diagonal and to tau as ``Ia qdd``), and the
    friction torque ``Fv qd + Fc sign(qd)``.  The rotor inertia reflected through the gear, ``G^2 Jm``,
    is the actuator model of Spong, Hutchinson and Vidyasagar ("Robot Modeling and Control", the
    chapter on independent joint control), with the rotors' gyroscopic coupling with the links
    neglected (as Pinocchio's ``model.armature`` does).  Each entry is a SymPy number, a parameter or an
    expression of parameters."""

    rotor_inertia: sp.Expr = sp.S.Zero
    gear_ratio: sp.Expr = sp.S.One
    viscous: sp.Expr = sp.S.Zero
    coulomb: sp.Expr = sp.S.Zero

    @property
    def armature(self) -> sp.Expr:
        return sp.sympify(self.rotor_inertia) * sp.sympify(self.gear_ratio) ** 2

    def parameters(self) -> tuple:
        """(Ia, Fv, Fc): the three parameters the torques are linear in (the regressor's columns)."""
        return (self.armature, sp.sympify(self.viscous), sp.sympify(self.coulomb))


def check_actuator(values: dict, fail) -> None:
    """Refuse (``fail(message)``) a drive no motor has: a negative rotor inertia or friction, a
    gear ratio of zero, or a value that is not a finite number (``values``: field -> float)."""
    for key, value in values.items():
        if not math.isfinite(value):
            fail(f"{key} must be a finite number")
    for key in ("rotor_inertia", "viscous", "coulomb"):
        if values.get(key, 0.0) < 0:
            fail(f"{key} {values[key]:g} is negative (friction takes energy out, an inertia is not negative)")
    if values.get("gear_ratio", 1.0) == 0:
        fail("gear_ratio 0: the motor would not move the joint")

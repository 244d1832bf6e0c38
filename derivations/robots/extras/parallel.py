"""Direct kinematics of Kumar's planar parallel manipulator (Fig. 6): three RRR legs.

Kumar, section 5.3: for a chain with closed loops "the direct kinematics may
yield more than one solution or no solution"; for the planar parallel
manipulator "the number of (real) solutions for (x, y, phi) can be anywhere
from zero to six", and for the Stewart platform "anywhere from zero to forty".
This module reproduces the planar count; the Stewart platform's 40 is cited,
not computed (its direct kinematics is a degree-40 polynomial, Husty 1996).

The manipulator of Fig. 6: a floating triangle joined to the ground by three
legs, each a revolute at the base (actuated), a revolute at the elbow and a
revolute at the triangle.  With the base angles theta_i given, elbow i is at
the known point ``B_i = A_i + a_i (cos theta_i, sin theta_i)``, and the triangle's
vertex ``C_i = p + Rot(phi) c_i`` must lie at the distal link length ``b_i`` from
it: three equations ``|p + Rot(phi) c_i - B_i|^2 = b_i^2`` in (x, y, phi), the
same as a 3-RPR platform with leg lengths b_i (Kumar's telescoping links).

Subtracting the first equation from the other two leaves two equations linear
in p = (x, y); solving them (Cramer) and putting p back into the first gives one
equation in cos(phi), sin(phi); the tangent half-angle t = tan(phi / 2) turns it
into a polynomial in t of degree at most 6 once the factors (1 + t^2) are
divided out.  Its real roots (and phi = pi where the degree drops) are the
assembly modes.  Every coordinate is exact (rational), so the real roots are
counted exactly (Sturm sequences, ``Poly.count_roots``).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

__all__ = ["ThreeRRR", "forward_polynomial", "assembly_modes", "STEWART_BOUND", "PLANAR_BOUND"]

PLANAR_BOUND = 6     # Kumar: "anywhere from zero to six" (planar parallel manipulator)
STEWART_BOUND = 40   # Kumar: "anywhere from zero to forty" (Stewart platform), cited, not computed

t = sp.Symbol("t", real=True)  # tan(phi / 2)
x, y = sp.symbols("x y", real=True)


@dataclass(frozen=True)
class ThreeRRR:
    """A planar 3-RRR platform with its base angles given, in exact numbers.

    ``elbows`` B_i: the elbow points fixed by the actuated angles (A_i + a_i (cos, sin) theta_i);
    ``distal`` b_i: elbow-to-triangle link lengths; ``platform`` c_i: the triangle's vertices in its
    own frame (c_1 = (0, 0) puts the triangle's origin at vertex 1).
    """

    elbows: tuple[tuple[sp.Rational, sp.Rational], ...]
    distal: tuple[sp.Rational, ...]
    platform: tuple[tuple[sp.Rational, sp.Rational], ...]

    @classmethod
    def from_legs(cls, base, proximal, angles_cos_sin, distal, platform) -> "ThreeRRR":
        """From base points A_i, proximal lengths a_i and each base angle as its exact (cos, sin)."""
        elbows = tuple((sp.nsimplify(A[0]) + a * sp.nsimplify(cs[0]), sp.nsimplify(A[1]) + a * sp.nsimplify(cs[1]))
                       for A, a, cs in zip(base, proximal, angles_cos_sin))
        return cls(elbows, tuple(sp.nsimplify(b) for b in distal),
                   tuple(tuple(sp.nsimplify(v) for v in c) for c in platform))

    def loop_equations(self, cos_phi, sin_phi, px=x, py=y) -> list[sp.Expr]:
        """``|p + Rot(phi) c_i - B_i|^2 - b_i^2``, each zero where leg i closes."""
        out = []
        for (bx, by), b, (cx, cy) in zip(self.elbows, self.distal, self.platform):
            vx = px + cos_phi * cx - sin_phi * cy - bx
            vy = py + sin_phi * cx + cos_phi * cy - by
            out.append(vx**2 + vy**2 - b**2)
        return out


def _position(robot: ThreeRRR, cos_phi, sin_phi):
    """p = (x, y) from the differences of the loop equations (linear in p), by Cramer's rule."""
    first, *others = robot.loop_equations(cos_phi, sin_phi)
    rows = [sp.expand(e - first) for e in others]
    system = sp.Matrix([[r.coeff(x), r.coeff(y)] for r in rows])
    rhs = sp.Matrix([-(r - r.coeff(x) * x - r.coeff(y) * y) for r in rows])
    if any(sp.expand(r - (system[k, 0] * x + system[k, 1] * y - rhs[k])) != 0 for k, r in enumerate(rows)):
        raise ValueError("the differences of the loop equations are not linear in (x, y)")
    det = sp.expand(system.det())
    px = sp.expand(sp.Matrix([[rhs[0], system[0, 1]], [rhs[1], system[1, 1]]]).det())
    py = sp.expand(sp.Matrix([[system[0, 0], rhs[0]], [system[1, 0], rhs[1]]]).det())
    return px, py, det


def forward_polynomial(robot: ThreeRRR) -> sp.Poly:
    """The polynomial in t = tan(phi / 2) whose real roots are the assembly modes with phi != pi."""
    cos_phi, sin_phi = (1 - t**2) / (1 + t**2), 2 * t / (1 + t**2)
    px, py, det = _position(robot, cos_phi, sin_phi)
    first = robot.loop_equations(cos_phi, sin_phi, px / det, py / det)[0]
    numerator = sp.numer(sp.together(first))
    poly = sp.Poly(sp.expand(numerator), t)
    while True:  # divide out the half-angle substitution's (1 + t^2)
        quotient, remainder = sp.div(poly, sp.Poly(1 + t**2, t))
        if not remainder.is_zero:
            break
        poly = quotient
    return poly.monic() if not poly.is_zero else poly


def assembly_modes(robot: ThreeRRR, tolerance: float = 1e-9) -> list[tuple[float, float, float]]:
    """Every real pose (x, y, phi) of the platform, each checked to close all three legs within ``tolerance``."""
    import math
    poly = forward_polynomial(robot)
    if poly.degree() > PLANAR_BOUND:
        raise ValueError(f"forward polynomial of degree {poly.degree()} > {PLANAR_BOUND}")
    angles = [2 * math.atan(float(r)) for r in sp.Poly(poly, t).real_roots()]
    at_pi = _position(robot, sp.S.NegativeOne, sp.S.Zero)
    if at_pi[2] != 0 and sp.simplify(robot.loop_equations(-1, 0, at_pi[0] / at_pi[2], at_pi[1] / at_pi[2])[0]) == 0:
        angles.append(math.pi)
    poses = []
    for phi in angles:
        c_phi, s_phi = sp.Float(math.cos(phi), 30), sp.Float(math.sin(phi), 30)
        px, py, det = (sp.N(v.subs({t: sp.tan(sp.Float(phi, 30) / 2)}), 30) for v in
                       _position(robot, (1 - t**2) / (1 + t**2), 2 * t / (1 + t**2)))
        pose = (float(px / det), float(py / det), phi)
        residual = max(abs(float(e)) for e in robot.loop_equations(c_phi, s_phi, px / det, py / det))
        if residual > tolerance:
            raise ValueError(f"assembly mode phi = {phi} leaves a leg open by {residual:g}")
        poses.append(pose)
    return poses

"""Kumar's counts of direct-kinematics solutions of parallel mechanisms (section 5.3).

"It can be shown that depending on the value of (q1, q2, q3), the number of (real)
solutions for (x, y, phi) can be anywhere from zero to six.  For the Stewart
Platform in Figure 4, this number has been shown to be anywhere from zero to forty."
The planar count is reproduced on the three-RRR platform of Fig. 6; the Stewart
bound is cited.
"""
import math

import numpy as np
import pytest
import sympy as sp

from derivations import parallel
from derivations.parallel import ThreeRRR, assembly_modes, forward_polynomial, t

# A sample geometry (lengths in any unit): base joints A_i, proximal links a_i = 1 at base angles with exact
# cosines and sines (3-4-5 triangles), distal links b_i, and the triangle's vertices in its own frame.
SAMPLE = ThreeRRR.from_legs(
    base=[(-sp.Rational(13, 5), -sp.Rational(3, 10)), (sp.Rational(23, 10), -sp.Rational(13, 10)),
          (sp.Rational(9, 10), sp.Rational(17, 10))],
    proximal=[1, 1, 1],
    angles_cos_sin=[(sp.Rational(3, 5), sp.Rational(4, 5)), (-sp.Rational(3, 5), sp.Rational(4, 5)),
                    (-sp.Rational(4, 5), -sp.Rational(3, 5))],
    distal=[sp.Rational(19, 10), 2, sp.Rational(6, 5)],
    platform=[(0, 0), (sp.Rational(9, 5), 0), (0, sp.Rational(6, 5))])


def brute_force_modes(robot: ThreeRRR, grid: int = 720) -> list[tuple[float, float, float]]:
    """Assembly modes without the polynomial: vertex 1 on its circle about elbow 1 (angle psi), the triangle
    turned by phi; legs 2 and 3 must close.  Every grid cell where both residuals change sign is refined by
    Newton's method; solutions closer than 1e-6 are one."""
    (b1x, b1y), (b2x, b2y), (b3x, b3y) = [(float(u), float(v)) for u, v in robot.elbows]
    r1, r2, r3 = (float(b) for b in robot.distal)
    (c1x, c1y), (c2x, c2y), (c3x, c3y) = [(float(u), float(v)) for u, v in robot.platform]

    def residuals(phi, psi):
        px = b1x + r1 * np.cos(psi) - (np.cos(phi) * c1x - np.sin(phi) * c1y)
        py = b1y + r1 * np.sin(psi) - (np.sin(phi) * c1x + np.cos(phi) * c1y)
        out = []
        for (bx, by), r, (cx, cy) in (((b2x, b2y), r2, (c2x, c2y)), ((b3x, b3y), r3, (c3x, c3y))):
            vx = px + np.cos(phi) * cx - np.sin(phi) * cy - bx
            vy = py + np.sin(phi) * cx + np.cos(phi) * cy - by
            out.append(vx * vx + vy * vy - r * r)
        return np.array(out), px, py

    angles = np.linspace(-math.pi, math.pi, grid, endpoint=False)
    phi, psi = np.meshgrid(angles, angles, indexing="ij")
    (f, g), _, _ = residuals(phi, psi)
    candidates = []
    for di, dj in ((1, 0), (0, 1), (1, 1)):
        f2, g2 = np.roll(f, (-di, -dj), (0, 1)), np.roll(g, (-di, -dj), (0, 1))
        hits = np.argwhere((np.sign(f) != np.sign(f2)) & (np.sign(g) != np.sign(g2)))
        candidates += [(phi[i, j], psi[i, j]) for i, j in hits]
    found = []
    for a, b in candidates:
        x = np.array([a, b])
        for _ in range(50):
            r, _, _ = residuals(*x)
            h = 1e-7
            jac = np.column_stack([(residuals(x[0] + h, x[1])[0] - r) / h, (residuals(x[0], x[1] + h)[0] - r) / h])
            try:
                x = x - np.linalg.solve(jac, r)
            except np.linalg.LinAlgError:
                break
        r, px, py = residuals(*x)
        if np.max(np.abs(r)) < 1e-11:
            pose = (float(px), float(py), float(math.remainder(x[0], 2 * math.pi)))
            if all(np.hypot(pose[0] - q[0], pose[1] - q[1]) + abs(math.remainder(pose[2] - q[2], 2 * math.pi)) > 1e-6
                   for q in found):
                found.append(pose)
    return found


def test_planar_3rrr_forward_kinematics_has_six_real_assembly_modes():
    """Kumar section 5.3: "anywhere from zero to six" real solutions; the sample geometry reaches six."""
    poly = forward_polynomial(SAMPLE)
    assert poly.degree() == 6 == parallel.PLANAR_BOUND       # the bound, as the polynomial's degree
    assert poly.count_roots() == 6                            # every root real (Sturm, exact coefficients)
    modes = assembly_modes(SAMPLE)
    assert len(modes) == 6
    # Independently: a grid over (phi, psi) with Newton refinement finds the same six poses, and no others.
    brute = brute_force_modes(SAMPLE)
    assert len(brute) == 6
    for pose in modes:
        assert min(abs(pose[0] - q[0]) + abs(pose[1] - q[1]) + abs(math.remainder(pose[2] - q[2], 2 * math.pi))
                   for q in brute) < 1e-8


def test_planar_3rrr_counts_vary_with_the_inputs_and_never_pass_six():
    """Other inputs give fewer assembly modes (down to none: the legs cannot close), never more than six."""
    rng = np.random.default_rng(6)
    counts = set()
    for _ in range(12):
        distal = [sp.Rational(int(v), 10) for v in rng.integers(5, 30, 3)]
        robot = ThreeRRR(SAMPLE.elbows, tuple(distal), SAMPLE.platform)
        poly = forward_polynomial(robot)
        assert poly.degree() <= 6
        n = poly.count_roots()
        assert n <= 6 and n % 2 == 0  # real roots of a real sextic come with its complex pairs
        counts.add(n)
    assert {0, 2, 4} <= counts  # from no assembly at all to four modes


def test_stewart_platform_bound_is_cited():
    """The Stewart platform's forty is Kumar's statement (section 5.3), kept as a cited constant."""
    assert parallel.STEWART_BOUND == 40
    assert "forty" in parallel.__doc__ and "Stewart" in parallel.__doc__

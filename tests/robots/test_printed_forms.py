"""The papers' printed intermediate forms, each compared with ours (issue 18, item 6).

Round trips (FK(IK(x)) = x) show that a solution is *a* solution; these tests show
that it is the paper's: each printed form is typed here from the paper and
compared with the model's expression symbolically, or with the generated kernels
at many points (angles modulo 2 pi).
"""
import math

import numpy as np
import pytest
import sympy as sp

from conftest import kernels
from derivations.ik import p_cos_q_sin_r
from derivations.robots import planar_3r
from derivations.robots._common import parameters as params

c, s = sp.cos, sp.sin
BACKENDS = ["numpy", "c"]


def vanishes(expr) -> bool:
    return sp.simplify(sp.expand_trig(sp.expand(expr))) == 0


def same_angle(a, b, atol=1e-9):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))) <= atol


# --------------------------------------------------------------------------- Kumar (d)-(j)

def kumar_printed(x, y, phi, l1, l2, l3, sigma):
    """Kumar section 5.4, Eqs. (d)-(j), as printed (numbers in, angles out)."""
    xp, yp = x - l3 * math.cos(phi), y - l3 * math.sin(phi)                      # (d), (e): x', y'
    r = math.sqrt(xp**2 + yp**2)
    gamma = math.atan2(-yp / r, -xp / r)                                         # (h): gamma
    t1 = gamma + sigma * math.acos(-(xp**2 + yp**2 + l1**2 - l2**2) / (2 * l1 * r))  # (h)
    t2 = math.atan2((yp - l1 * math.sin(t1)) / l2, (xp - l1 * math.cos(t1)) / l2) - t1  # (i)
    t3 = phi - t1 - t2                                                           # (j)
    return t1, t2, t3


def test_kumar_steps_are_eqs_d_to_j_as_printed(models):
    """The model's steps, symbol by symbol, are Kumar's (d), (e), (h), (i), (j) typed from the paper."""
    m = models["planar_3r"]
    x, y, phi = m.task_symbols
    l1, l2, l3 = params(m, "l1", "l2", "l3")
    q1, q2, q3 = m.q
    xp, yp = planar_3r.WRIST
    r = sp.sqrt(xp**2 + yp**2)
    for branch, sigma in zip(m.ik, (-1, 1)):  # elbow_up is sigma = -1
        printed = [(xp, x - l3 * c(phi)), (yp, y - l3 * s(phi)),
                   (planar_3r.GAMMA, sp.atan2(-yp / r, -xp / r)),
                   (q1, planar_3r.GAMMA + sigma * sp.acos(-(xp**2 + yp**2 + l1**2 - l2**2) / (2 * l1 * r))),
                   (q2, sp.atan2((yp - l1 * s(q1)) / l2, (xp - l1 * c(q1)) / l2) - q1),
                   (q3, phi - q1 - q2)]
        ours = [(sym, e.replace(sp.Min, lambda *a: [v for v in a if v != 1][0])
                 .replace(sp.Max, lambda *a: [v for v in a if v != -1][0])) for sym, e in branch.steps]
        assert [sym for sym, _ in ours] == [sym for sym, _ in printed]
        for (sym, got), (_, want) in zip(ours, printed):
            assert sp.simplify(got - want) == 0, (branch.name, sym)


def test_kumar_eq_h_solves_eq_f_and_is_appendix_2(models):
    """Eq. (h) is Appendix 2's root of Eq. (f) (P = -2 l1 x', Q = -2 l1 y', R = x'^2 + y'^2 + l1^2 - l2^2),
    at many wrist points, both signs of sigma."""
    m = models["planar_3r"]
    l1, l2 = 0.5, 0.4
    rng = np.random.default_rng(18)
    xp_, yp_ = sp.symbols("xp yp", real=True)
    L1, L2 = params(m, "l1", "l2")
    roots = p_cos_q_sin_r(*planar_3r.kumar_eq_f(m, xp_, yp_))
    for _ in range(200):
        radius, angle = rng.uniform(0.12, 0.88), rng.uniform(-math.pi, math.pi)
        xp, yp = radius * math.cos(angle), radius * math.sin(angle)
        for sigma, root in ((1, roots[0]), (-1, roots[1])):
            gamma = math.atan2(-yp / radius, -xp / radius)
            t1 = gamma + sigma * math.acos(-(xp**2 + yp**2 + l1**2 - l2**2) / (2 * l1 * radius))
            P, Q, R = -2 * l1 * xp, -2 * l1 * yp, xp**2 + yp**2 + l1**2 - l2**2
            assert abs(P * math.cos(t1) + Q * math.sin(t1) + R) < 1e-12
            appendix = float(root.value.subs({xp_: xp, yp_: yp, L1: l1, L2: l2}))
            assert same_angle(t1, appendix, 1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kumar_eqs_h_to_j_against_the_kernel(backend):
    k = kernels("planar_3r", backend)
    rng = np.random.default_rng(3)
    q = np.column_stack([rng.uniform(-math.pi, math.pi, 400), rng.uniform(0.1, 3.0, 400) * rng.choice([-1, 1], 400),
                         rng.uniform(-math.pi, math.pi, 400)])
    targets = k.task(q)
    Q, valid = k.ik(targets)
    assert valid.all()
    for i, (x, y, phi) in enumerate(targets):
        for branch, sigma in ((0, -1), (1, 1)):
            assert same_angle(Q[i, branch], kumar_printed(x, y, phi, 0.5, 0.4, 0.2, sigma)).all()


# --------------------------------------------------------------------------- Kumar, R-P

@pytest.mark.parametrize("backend", BACKENDS)
def test_kumar_rp_sigma_form(backend):
    """Kumar section 5.4: d2 = sigma sqrt(x^2 + y^2), theta1 = atan2(y / d2, x / d2), sigma = +-1 (Eqs. 6-8)."""
    k = kernels("planar_rp", backend)
    rng = np.random.default_rng(4)
    xy = rng.uniform(-2, 2, (500, 2))
    Q, valid = k.ik(xy)
    assert valid.all() and k.BRANCHES == ("d2_positive", "d2_negative")
    for branch, sigma in ((0, 1), (1, -1)):
        d2 = sigma * np.sqrt(xy[:, 0]**2 + xy[:, 1]**2)
        theta1 = np.arctan2(xy[:, 1] / d2, xy[:, 0] / d2)
        np.testing.assert_allclose(Q[:, branch, 1], d2, rtol=1e-15, atol=0)
        assert same_angle(Q[:, branch, 0], theta1, 1e-14).all()


# --------------------------------------------------------------------------- Rehiara

def test_rehiara_eqs_15_16_17_and_22_to_28_and_31(models):
    """Rehiara section 3.2 on the AdeptThree's own x, y (Eq. 14): the geometric Eqs. 15-17 and the algebraic
    Eqs. 22-24, 26, 28 and 31, each as printed, hold identically."""
    m = models["adept_three"]
    q1, q2, _, _ = m.q
    l1, l2 = params(m, "l1", "l2")
    x, y = m.task[0], m.task[1]
    c1, s1, c2, s2, c12, s12 = c(q1), s(q1), c(q2), s(q2), c(q1 + q2), s(q1 + q2)
    r2 = x**2 + y**2
    assert vanishes(r2 - (l1**2 + l2**2 - 2 * l1 * l2 * c(sp.pi - q2)))                    # Eq. 15
    assert vanishes(r2 - (l1**2 + l2**2 + 2 * l1 * l2 * c2))                              # Eqs. 16 and 26
    assert vanishes(c2 - (r2 - l1**2 - l2**2) / (2 * l1 * l2))                            # Eq. 17
    assert vanishes(x - (l1 * c1 + l2 * c12)) and vanishes(y - (l1 * s1 + l2 * s12))      # Eq. 22
    eq23 = l1**2 * c1**2 + l2**2 * c12**2 + 2 * l1 * l2 * c1 * c12 + l1**2 * s1**2 + l2**2 * s12**2 \
        + 2 * l1 * l2 * s1 * s12
    assert vanishes(r2 - eq23)                                                            # Eq. 23
    assert vanishes(r2 - (l1**2 + l2**2 + 2 * l1 * l2 * (c1 * c12 + s1 * s12)))           # Eq. 24
    assert vanishes(x - (l1 * c1 + l2 * c1 * c2 - l2 * s1 * s2))                          # Eq. 28
    assert vanishes(y - (l1 * s1 + l2 * s1 * c2 + l2 * c1 * s2))
    den = l1 + l2 * c2
    eq31 = (x * l2 * s2 + l2**2 * s1 * s2**2) / den + (l1**2 * s1 + l1 * l2 * s1 * c2) / den \
        + (l1 * l2 * s1 * c2 + l2**2 * s1 * c2**2) / den
    assert vanishes(sp.together(y - eq31).as_numer_denom()[0])                            # Eq. 31


@pytest.mark.parametrize("backend", BACKENDS)
def test_rehiara_eqs_17_18_27_against_the_kernel(backend):
    """cos(theta2) of both branches is Eq. 17; the righty branch's theta2 is Eq. 18 (= Eq. 27), the
    principal arccosine, and lefty's its negative (the paper's elbow, and the other)."""
    k = kernels("adept_three", backend)
    l1, l2 = 0.559, 0.508
    rng = np.random.default_rng(15)
    q = np.column_stack([rng.uniform(-math.pi, math.pi, 400), rng.uniform(-3.0, 3.0, 400),
                         rng.uniform(0, 0.3, 400), rng.uniform(-math.pi, math.pi, 400)])
    target = k.task(q)
    Q, valid = k.ik(target)
    assert valid.all()
    x, y = target[:, 0], target[:, 1]
    eq18 = np.arccos((x**2 + y**2 - l1**2 - l2**2) / (2 * l1 * l2))
    np.testing.assert_allclose(Q[:, k.BRANCHES.index("righty"), 1], eq18, atol=2e-7)
    np.testing.assert_allclose(Q[:, k.BRANCHES.index("lefty"), 1], -eq18, atol=2e-7)


# --------------------------------------------------------------------------- the velocity slides

def test_slides_2r_example_origins_and_axes(models):
    """Velocity slides, "Example: 2-link planer robot": o_0 = 0, o_1 = (l1 c1, l1 s1, 0),
    o_2 = (l1 c1 + l2 c12, l1 s1 + l2 s12, 0), z_0 = z_1 = (0, 0, 1), from the model's frames."""
    m = models["planar_2r"]
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    o = [f[:3, 3] for f in m.frames]
    z = [f[:3, 2] for f in m.frames]
    assert o[0] == sp.zeros(3, 1)
    assert all(vanishes(e) for e in o[1] - sp.Matrix([l1 * c(q1), l1 * s(q1), 0]))
    assert all(vanishes(e) for e in o[2] - sp.Matrix([l1 * c(q1) + l2 * c(q1 + q2), l1 * s(q1) + l2 * s(q1 + q2), 0]))
    assert z[0] == z[1] == sp.Matrix([0, 0, 1])

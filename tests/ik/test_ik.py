"""Inverse kinematics: the primitives, the papers' numbers and errata, branch meanings, bad input.

The round trip over 10,000 configurations per robot is in test_ik_round_trip.py.
"""
import math
import warnings

import numpy as np
import pytest
import sympy as sp

from derivations.ik import (ACOS_TOLERANCE, atan2_of_sine_cosine, law_of_cosines, p_cos_q_sin_r, prismatic_along,
                            sine_cosine_pair, two_link, wrap_angle)
from derivations.robots import adept_three, planar_3r
from conftest import ROBOT_NAMES, kernels

BACKENDS = ["numpy", "c"]
deg = math.degrees


def numeric(expr, values):
    return float(sp.sympify(expr).xreplace({k: sp.Float(v, 30) for k, v in values.items()}).evalf(30))


# --- primitives ---------------------------------------------------------------------------------------------

def test_atan2_kumar_appendix1_example():
    """Kumar Appendix 1: s = 1/2, c = sqrt(3)/2; asin gives pi/6 and 5 pi/6, only pi/6 has that cosine."""
    s, c = sp.Rational(1, 2), sp.sqrt(3) / 2
    (root,) = atan2_of_sine_cosine(s, c)
    assert root.value == sp.pi / 6
    candidates = [sp.asin(s), sp.pi - sp.asin(s)]
    assert candidates == [sp.pi / 6, 5 * sp.pi / 6]
    assert [sp.cos(t) for t in candidates] == [c, -c]  # the second candidate is wrong


def scorbot_case_table(y, x):
    """Predescu and Stroe, section 3: atan2 printed as a case table of arctan(y/x)."""
    if x > 0:
        return math.atan(y / x)
    if y >= 0 and x < 0:
        return math.atan(y / x) + math.pi
    if y < 0 and x < 0:
        return math.atan(y / x) - math.pi
    if y > 0 and x == 0:
        return math.pi / 2
    if y < 0 and x == 0:
        return -math.pi / 2
    return None  # undefined at (0, 0)


def test_atan2_is_the_scorbot_case_table():
    a, b = sp.symbols("a b", real=True)
    (root,) = atan2_of_sine_cosine(a, b)
    rng = np.random.default_rng(3)
    points = [(y, x) for y in (-2.0, -0.5, 0.0, 0.7) for x in (-1.5, 0.0, 0.3)] + list(rng.normal(size=(50, 2)))
    for y, x in points:
        expected = scorbot_case_table(y, x)
        if expected is None:
            continue
        assert numeric(root.value, {a: y, b: x}) == pytest.approx(expected, abs=1e-15)


def test_p_cos_q_sin_r_gives_both_roots_where_p2_plus_q2_reaches_r2():
    """Kumar Appendix 2: theta = atan2(Q, P) +- acos(-R / sqrt(P^2 + Q^2))."""
    P, Q, R = sp.symbols("P Q R", real=True)
    roots = p_cos_q_sin_r(P, Q, R)
    assert [r.name for r in roots] == ["sigma_plus", "sigma_minus"]
    rng = np.random.default_rng(4)
    reachable = 0
    for p, q, r in rng.normal(size=(200, 3)):
        values = {P: p, Q: q, R: r}
        exists = p * p + q * q >= r * r
        for root in roots:
            assert bool(root.condition.xreplace({k: sp.Float(v, 30) for k, v in values.items()})) == exists
            if exists:
                theta = numeric(root.value, values)
                assert p * math.cos(theta) + q * math.sin(theta) + r == pytest.approx(0, abs=1e-12)
        if exists:
            reachable += 1
            assert not math.isclose(numeric(roots[0].value, values), numeric(roots[1].value, values)) or r * r == p * p + q * q
    assert 50 < reachable < 200


def test_law_of_cosines_both_elbows():
    r2, a, b = sp.symbols("r2 a b", positive=True)
    plus, minus = law_of_cosines(r2, a, b)
    for reach in (0.3, 0.7, 1.1):
        values = {r2: reach**2, a: 0.6, b: 0.5}
        for root, sign in ((plus, 1), (minus, -1)):
            theta = numeric(root.value, values)
            assert sign * theta >= 0
            assert 0.36 + 0.25 + 2 * 0.3 * math.cos(theta) == pytest.approx(reach**2, abs=1e-14)
    # Beyond the reach (1.1 m) by more than the tolerance: the root does not exist.
    assert not bool(plus.condition.xreplace({r2: sp.Float(1.1 + 1e-9, 30)**2, a: 0.6, b: 0.5}))
    assert bool(plus.condition.xreplace({r2: sp.Float(1.1, 30)**2 * (1 + sp.Float(1e-13)), a: 0.6, b: 0.5}))


def test_sine_cosine_pair_and_prismatic_along():
    A, B, t = 0.8, -0.3, 2.4
    u, v = A * math.cos(t) - B * math.sin(t), A * math.sin(t) + B * math.cos(t)
    (root,) = sine_cosine_pair(A, B, u, v)
    assert float(root.value) == pytest.approx(t, abs=1e-15)
    (slide,) = prismatic_along(sp.Matrix([3, 4, 5]), sp.Matrix([1, 1, 1]), sp.Matrix([0, 0, -2]))
    assert slide.value == -2  # 1 + (-2)(-2) = 5 along z


def test_wrap_angle_lands_in_the_half_open_turn():
    for value, expected in ((sp.pi, sp.pi), (-sp.pi, sp.pi), (3 * sp.pi / 2, -sp.pi / 2), (7, 7 - 2 * sp.pi)):
        assert sp.simplify(wrap_angle(sp.sympify(value)) - expected) == 0


def test_acos_tolerance_is_stated():
    assert ACOS_TOLERANCE == sp.Rational(1, 10**12)


# --- the papers ---------------------------------------------------------------------------------------------

def test_kumar_eq_f_is_the_sum_of_squares_of_eqs_d_e(models):
    """Kumar Eq. (f): squaring and adding (d), (e) gives P cos t1 + Q sin t1 + R = 0."""
    m = models["planar_3r"]
    q1 = m.q[0]
    l1, l2 = (p for p in m.params if str(p) in ("l1", "l2"))
    xw, yw = planar_3r.wrist_point(m)
    P, Q, R = planar_3r.kumar_eq_f(m)
    squares = (xw - l1 * sp.cos(q1))**2 + (yw - l1 * sp.sin(q1))**2 - l2**2
    assert sp.simplify(sp.expand(squares - (P * sp.cos(q1) + Q * sp.sin(q1) + R))) == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_kumar_sigma_plus_puts_the_elbow_right_of_the_wrist_line(models, backend):
    """Kumar Eq. (h): sigma = +1 gives theta2 in [0, pi] -- our elbow_down; Fig. 14's caption calls it elbow-up.

    For a wrist to the right of the base (x' > 0) the sigma = +1 elbow lies below
    the line from the base to the wrist (a naming choice, README "Choices the papers leave open").
    """
    k = kernels("planar_3r", backend)
    assert k.BRANCHES == ("elbow_up", "elbow_down")
    assert "sigma = -1" in models["planar_3r"].ik[0].doc and "sigma = +1" in models["planar_3r"].ik[1].doc
    rng = np.random.default_rng(11)
    q = rng.uniform(-np.pi, np.pi, (500, 3))
    x = k.task(q)
    Q, valid = k.ik(x)
    assert valid.all()
    assert np.all(Q[:, 0, 1] <= 0) and np.all(Q[:, 1, 1] >= 0)
    l1, l3 = k.PARAMS["l1"], k.PARAMS["l3"]
    wrist = x[:, :2] - l3 * np.stack([np.cos(x[:, 2]), np.sin(x[:, 2])], -1)
    right = wrist[:, 0] > 0.05
    for branch, below in ((1, True), (0, False)):
        elbow = l1 * np.stack([np.cos(Q[:, branch, 0]), np.sin(Q[:, branch, 0])], -1)
        line_height = wrist[:, 1] * elbow[:, 0] / np.where(right, wrist[:, 0], 1.0)
        assert np.all((elbow[right, 1] < line_height[right] + 1e-12) == below)


@pytest.mark.parametrize("backend", BACKENDS)
def test_scorbot_points_m_and_n_section_4(backend):
    """Predescu and Stroe, Eq. 4.1: theta2 = 13.4685 deg at M(0.750, 0, 0.300); 126.62 deg at N(0.300, 0, 0.750)."""
    k = kernels("scorbot_er7", backend)
    Q, valid = k.ik([[0.750, 0.0, 0.300], [0.300, 0.0, 0.750]])
    up = k.BRANCHES.index("elbow_up")
    assert valid[:, up].all()
    assert deg(Q[0, up, 1]) == pytest.approx(13.4685, abs=5e-5)
    assert deg(Q[1, up, 1]) == pytest.approx(126.62, abs=5e-3)
    # Eq. 4.1 at t = 10 s, with its printed (rounded) coefficients: 13.4685 + 3.3946 t^2 - 0.2263 t^3.
    assert deg(Q[1, up, 1]) == pytest.approx(13.4685 + 3.3946 * 100 - 0.2263 * 1000, abs=0.06)
    assert deg(Q[0, up, 2]) < 0  # the paper's numbers are on theta3 = -acos(...)
    np.testing.assert_allclose(k.task(Q[:, up]), [[0.75, 0, 0.3], [0.3, 0, 0.75]], atol=1e-15)
    # The gripper is horizontal (Eq. 3.10) and theta1 = 0 in the xOz plane (Eq. 3.1).
    np.testing.assert_allclose(Q[:, up, 1] + Q[:, up, 2] + Q[:, up, 3], 0, atol=1e-15)
    np.testing.assert_allclose(Q[:, up, 0], 0, atol=0)


def test_E11_scorbot_printed_eq_3_5_with_3_9_is_the_other_elbow(models):
    """Eq. 3.5 takes theta3 = +acos(...); with Eq. 3.9 that gives theta2 = -33.23 deg at M, not 13.4685."""
    a1, a2, a3, d1, d5 = 0.050, 0.300, 0.250, 0.385, 0.212
    xp, yp, zp = 0.750, 0.0, 0.300
    horizontal, vertical = math.hypot(xp, yp) - a1 - d5, zp - d1
    theta3 = math.acos((horizontal**2 + vertical**2 - a2**2 - a3**2) / (2 * a2 * a3))  # Eq. 3.5 as printed
    alpha = math.atan2(a3 * math.sin(theta3), a2 + a3 * math.cos(theta3))              # Eq. 3.6
    beta = math.atan2(vertical, horizontal)                                              # Eq. 3.7
    theta2 = beta - alpha                                                                # Eqs. 3.8-3.9
    assert deg(theta2) == pytest.approx(-33.2298, abs=1e-4)
    assert abs(deg(theta2) - 13.4685) > 40
    # The printed pair still reaches M: it is our elbow_down branch.
    k = kernels("scorbot_er7", "numpy")
    Q, valid = k.ik([xp, yp, zp])
    down = k.BRANCHES.index("elbow_down")
    assert valid[down] and Q[down, 1] == pytest.approx(theta2, abs=1e-14) and Q[down, 2] == pytest.approx(theta3)
    # With theta3 = -acos(...) the same Eqs. 3.6-3.9 give the paper's 13.4685 deg.
    alpha_up = math.atan2(a3 * math.sin(-theta3), a2 + a3 * math.cos(theta3))
    assert deg(beta - alpha_up) == pytest.approx(13.4685, abs=5e-5)


def rehiara_targets(k, rng, count):
    q = np.stack([rng.uniform(-np.pi, np.pi, count), rng.uniform(-np.pi, np.pi, count),
                  rng.uniform(0, 0.305, count), rng.uniform(-np.pi, np.pi, count)], -1)
    return q, k.task(q)


def test_E4_rehiara_eq21_as_printed_misses_the_target():
    """Eqs. 18 and 21: theta2 = +arccos(...), theta1 = arcsin(l2 s2 / r) + arctan(y/x) reaches only at s2 = 0.

    With theta2 >= 0 the first link must sit clockwise of the target: theta1 = alpha - beta.
    """
    k = kernels("adept_three", "numpy")
    l1, l2 = k.PARAMS["l1"], k.PARAMS["l2"]
    q, x = rehiara_targets(k, np.random.default_rng(5), 400)
    px, py = x[:, 0], x[:, 1]
    r = np.hypot(px, py)
    theta2 = np.arccos(np.clip((px**2 + py**2 - l1**2 - l2**2) / (2 * l1 * l2), -1, 1))  # Eq. 18
    beta = np.arcsin(l2 * np.sin(theta2) / r)                                              # Eq. 20
    front = px > 0  # where arctan(y/x) is the direction of the target
    printed = beta + np.arctan(py / px)                                                    # Eq. 21
    corrected = np.arctan(py / px) - beta

    def reach(theta1):
        return np.hypot(l1 * np.cos(theta1) + l2 * np.cos(theta1 + theta2) - px,
                        l1 * np.sin(theta1) + l2 * np.sin(theta1 + theta2) - py)

    assert np.all(reach(printed)[front & (theta2 > 0.01)] > 1e-3)
    assert np.all(reach(corrected)[front] < 1e-12)


def test_E5_rehiara_arcsin_and_arctan_lose_the_quadrant():
    """Eq. 34 (theta1 = arcsin(...)) and Eq. 19 (alpha = arctan(y/x)) fail where theta1 or the target
    leave (-pi/2, pi/2); the atan2 forms of the same equations, which the kernels use, do not."""
    k = kernels("adept_three", "numpy")
    l1, l2 = k.PARAMS["l1"], k.PARAMS["l2"]
    q, x = rehiara_targets(k, np.random.default_rng(6), 400)
    px, py = x[:, 0], x[:, 1]
    Q, valid = k.ik(x)
    righty = k.BRANCHES.index("righty")
    theta2 = Q[:, righty, 1]
    s2, c2 = np.sin(theta2), np.cos(theta2)
    eq34 = np.arcsin((py * (l1 + l2 * c2) - px * l2 * s2) / (px**2 + py**2))              # Eq. 34 as printed
    atan2_form = np.arctan2(py * (l1 + l2 * c2) - px * l2 * s2, px * (l1 + l2 * c2) + py * l2 * s2)
    np.testing.assert_allclose(atan2_form, Q[:, righty, 0], atol=1e-12)
    behind = np.abs(Q[:, righty, 0]) > np.pi / 2 + 0.01
    assert behind.sum() > 50
    assert np.all(np.abs(eq34 - Q[:, righty, 0])[behind] > 0.01)   # wrong quadrant
    np.testing.assert_allclose(eq34[~behind & (np.abs(Q[:, righty, 0]) < np.pi / 2 - 0.01)],
                               Q[:, righty, 0][~behind & (np.abs(Q[:, righty, 0]) < np.pi / 2 - 0.01)], atol=1e-9)
    left_half = px < 0
    assert np.all(np.abs(np.arctan(py / px) - np.arctan2(py, px))[left_half] > 3)  # off by pi


def test_rehiara_geometric_and_algebraic_methods_agree(models):
    """Both of Rehiara's routes (Eqs. 15-21 and 22-34), in atan2 form, give the same branches."""
    m = models["adept_three"]
    geometric, algebraic = adept_three.geometric_method(m), adept_three.algebraic_method(m)
    assert [b.name for b in geometric] == [b.name for b in algebraic] == ["lefty", "righty"]
    symbols = list(m.task_symbols) + list(m.params)
    rng = np.random.default_rng(8)
    k = kernels("adept_three", "numpy")
    _, x = rehiara_targets(k, rng, 50)
    values = np.concatenate([x, np.tile(list(m.params.values()), (50, 1))], axis=1)
    for g, a in zip(geometric, algebraic):
        for eg, ea in zip(g.solution, a.solution):
            fg, fa = sp.lambdify(symbols, eg, "numpy"), sp.lambdify(symbols, ea, "numpy")
            difference = np.array([fg(*v) - fa(*v) for v in values], dtype=float)
            assert np.all(np.abs((difference + np.pi) % (2 * np.pi) - np.pi) < 1e-12)


def test_two_link_method_must_be_named():
    with pytest.raises(ValueError, match="method must be 'geometric' or 'algebraic'"):
        two_link(1, 1, 1, 1, method="numeric")


# --- what the branch names mean ----------------------------------------------------------------------------

def above_line(origin, end, point, horizontal):
    """Whether ``point`` lies above the line from ``origin`` to ``end`` in their vertical plane."""
    h_end, z_end = ((end - origin) * horizontal).sum(-1), (end - origin)[..., 2]
    h_point, z_point = ((point - origin) * horizontal).sum(-1), (point - origin)[..., 2]
    return (h_end * z_point - z_end * h_point) / h_end > 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_planar_elbow_up_is_left_of_the_line_from_shoulder_to_target(backend):
    k = kernels("planar_2r", backend)
    q = np.random.default_rng(9).uniform(-np.pi, np.pi, (500, 2))
    Q, valid = k.ik(k.task(q))
    assert valid.all() and np.all(Q[:, 0, 1] <= 0) and np.all(Q[:, 1, 1] >= 0)
    x = k.task(q)
    elbow = k.frames(Q)[..., 1, :2, 3]
    cross = x[:, None, 0] * elbow[..., 1] - x[:, None, 1] * elbow[..., 0]
    assert np.all(cross[:, 0] >= -1e-12) and np.all(cross[:, 1] <= 1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_adept_righty_has_the_elbow_right_of_the_arm_line_seen_from_above(backend):
    k = kernels("adept_three", backend)
    q, x = rehiara_targets(k, np.random.default_rng(10), 500)
    Q, valid = k.ik(x)
    assert k.BRANCHES == ("lefty", "righty")
    elbow = k.frames(Q)[..., 1, :2, 3]
    cross = x[:, None, 0] * elbow[..., 1] - x[:, None, 1] * elbow[..., 0]
    assert np.all(cross[:, 1] <= 1e-12) and np.all(Q[:, 1, 1] >= 0)   # righty: clockwise side
    assert np.all(cross[:, 0] >= -1e-12) and np.all(Q[:, 0, 1] <= 0)  # lefty


@pytest.mark.parametrize("backend", BACKENDS)
def test_scorbot_elbow_up_means_above_the_shoulder_wrist_line(backend):
    k = kernels("scorbot_er7", backend)
    assert k.BRANCHES == ("elbow_up", "elbow_down", "shoulder_flip_elbow_up", "shoulder_flip_elbow_down")
    rng = np.random.default_rng(12)
    q = rng.uniform(-np.pi, np.pi, (2000, 5))
    q[:, 3], q[:, 4] = -(q[:, 1] + q[:, 2]), 0
    Q, valid = k.ik(k.task(q))
    assert valid[:, 2].sum() > 100
    frames = k.frames(Q)
    shoulder, elbow, wrist = frames[..., 1, :3, 3], frames[..., 2, :3, 3], frames[..., 3, :3, 3]
    gripper = np.stack([np.cos(Q[..., 0]), np.sin(Q[..., 0]), 0 * Q[..., 0]], -1)
    above = above_line(shoulder, wrist, elbow, gripper)
    clear = np.abs(np.sin(Q[..., 2])) > 1e-6
    wrist_ahead = ((wrist - shoulder) * gripper).sum(-1)  # along the gripper: the reach of the direct branches
    for branch, (up, flip) in enumerate(((True, False), (False, False), (True, True), (False, True))):
        # theta3's sign names the branch everywhere ...
        assert np.all((Q[valid[:, branch], branch, 2] <= 0) == (up != flip)), k.BRANCHES[branch]
        # ... and means "elbow above the shoulder-wrist line" wherever the wrist is ahead of the
        # shoulder in the direction the arm reaches (behind the shoulder, above and below swap).
        ahead = -wrist_ahead[:, branch] if flip else wrist_ahead[:, branch]
        use = valid[:, branch] & clear[:, branch] & (ahead > 1e-6)
        assert use.sum() > 100
        assert np.all(above[use, branch] == up), k.BRANCHES[branch]
    np.testing.assert_array_equal(Q[..., 4], 0.0)  # theta5 is free; the choice is 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_puma_branch_names_mean_shoulder_elbow_and_wrist(backend):
    k = kernels("puma560", backend)
    q = np.random.default_rng(13).uniform(-np.pi, np.pi, (2000, 6))
    Q, valid = k.ik(k.task(q))
    assert valid.all() and len(k.BRANCHES) == 8
    frames = k.frames(Q)
    x1 = frames[..., 1, :3, 0]
    wrist, shoulder, elbow = frames[..., 4, :3, 3], frames[..., 1, :3, 3], frames[..., 2, :3, 3]
    u = ((wrist - shoulder) * x1).sum(-1)
    above = above_line(shoulder, wrist, elbow, x1)
    for b, name in enumerate(k.BRANCHES):
        side, _, elbow_name, wrist_name = name.split("_")[0], None, name.split("_")[2], name.split("_")[3]
        assert np.all((u[:, b] >= 0) == (side == "right")), name
        clear = np.abs(u[:, b]) > 1e-6
        assert np.all(above[clear, b] == (elbow_name == "up")), name
        assert np.all((np.sin(Q[:, b, 4]) >= 0) == (wrist_name == "noflip")), name


@pytest.mark.parametrize("backend", BACKENDS)
def test_puma_wrist_singularity_takes_theta4_zero(backend):
    """At theta5 = 0 the pose fixes theta4 + theta6 only: theta4 := 0 (noflip) or pi (flip)."""
    k = kernels("puma560", backend)
    q = np.array([[0.3, -0.4, 0.5, 1.1, 0.0, -0.7], [-2.0, 0.9, -1.2, -0.4, np.pi, 0.5]])
    Q, valid = k.ik(k.task(q))
    assert valid.all()
    np.testing.assert_allclose(k.fk(Q), np.broadcast_to(k.fk(q)[:, None], (2, 8, 4, 4)), atol=1e-12)
    for item in range(2):
        # The arm branches that reproduce the generating theta1..theta3 are the singular ones.
        arm = np.abs((Q[item, :, :3] - q[item, :3] + np.pi) % (2 * np.pi) - np.pi).max(-1) < 1e-9
        assert arm.sum() == 2
        for b in np.flatnonzero(arm):
            wrist = k.BRANCHES[b].split("_")[-1]
            assert Q[item, b, 3] == (0.0 if wrist == "noflip" else pytest.approx(np.pi, abs=1e-15)), k.BRANCHES[b]
            assert abs(np.sin(Q[item, b, 4])) < 1e-12
            # theta6 carries what theta4 held: theta4 + theta6 at theta5 = 0, theta6 - theta4 at theta5 = pi
            sign = 1 if np.cos(q[item, 4]) > 0 else -1
            kept = (Q[item, b, 3] + sign * Q[item, b, 5]) - (q[item, 3] + sign * q[item, 5])
            assert abs(np.sin(kept / 2 if wrist == "noflip" else kept)) < 1e-12
    # manipulability flags exactly those branches: it is how a caller tells them from the others.
    _, singular = k.manipulability(Q)
    np.testing.assert_array_equal(singular, np.abs(np.sin(Q[..., 4])) < 1e-9)
    assert singular.sum(-1).tolist() == [2, 2]


# --- the contract -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_branches_constant_and_solutions_use_only_the_task_and_parameters(models, name):
    m = models[name]
    allowed = set(m.task_symbols) | set(m.params)
    for backend in BACKENDS:
        assert kernels(name, backend).BRANCHES == tuple(b.name for b in m.ik)
    for branch in m.ik:
        assert len(branch.solution) == m.n and branch.doc
        for expr in branch.solution:
            assert sp.sympify(expr).free_symbols <= allowed, (branch.name, expr)
        assert sp.sympify(branch.condition).free_symbols <= allowed


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_ik_shapes_broadcast(name, backend):
    k = kernels(name, backend)
    n, b = len(k.JOINTS), len(k.BRANCHES)
    rng = np.random.default_rng(14)
    x = k.task(rng.uniform(-1, 1, (2, 3, n)))
    Q, valid = k.ik(x)
    assert Q.shape == (2, 3, b, n) and valid.shape == (2, 3, b) and valid.dtype == bool
    Q1, valid1 = k.ik(x[1, 2])
    assert Q1.shape == (b, n)
    # The built C runs batches vectorised (libmvec) and one point in scalar C: equal to rounding.
    np.testing.assert_allclose(Q1, Q[1, 2], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(valid1, valid[1, 2])
    assert k.within_limits(Q).shape == (2, 3, b)


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_c_returns_the_number_of_valid_branches(name):
    k = kernels(name, "c")
    ffi, lib = k._ffi, k._lib
    n, b, m = len(k.JOINTS), len(k.BRANCHES), len(k.TASK)
    rng = np.random.default_rng(15)
    x = k.task(rng.uniform(-2, 2, (20, n)))
    x[::3, :3] *= 40.0  # far beyond reach for the arms with a bounded workspace
    _, valid = k.ik(x)
    total = 0
    for target, expected in zip(x, valid):
        Q = np.empty(b * n)
        flags = np.empty(b, dtype=np.intc)
        found = getattr(lib, f"{name}_ik")(ffi.from_buffer("double[]", np.ascontiguousarray(target)), ffi.NULL,
                                           ffi.from_buffer("double[]", Q, require_writable=True),
                                           ffi.from_buffer("int[]", flags, require_writable=True))
        assert found == expected.sum() == flags.astype(bool).sum()
        total += found
    Q = np.empty(20 * b * n)
    flags = np.empty(20 * b, dtype=np.intc)
    x = np.ascontiguousarray(x)
    assert getattr(lib, f"{name}_ik_batch")(20, ffi.from_buffer("double[]", x), ffi.NULL,
                                            ffi.from_buffer("double[]", Q, require_writable=True),
                                            ffi.from_buffer("int[]", flags, require_writable=True)) == total


# --- the edge of the workspace --------------------------------------------------------------------------------

def edge_targets(name, k, rng, count, margin):
    """Targets ``margin`` metres outside (margin > 0) or inside (< 0) the outer edge of the reach."""
    p = k.PARAMS
    q = rng.uniform(-np.pi, np.pi, (count, len(k.JOINTS)))
    for i, kind in enumerate(k.JOINT_TYPES):
        if kind == "P":
            q[:, i] = rng.uniform(0, 0.3, count)
    if name in ("planar_2r", "planar_3r", "adept_three"):
        q[:, 1] = 0.0  # stretched
        x = k.task(q)
        if name == "planar_3r":
            phi = x[:, 2:3]
            wrist = x[:, :2] - p["l3"] * np.concatenate([np.cos(phi), np.sin(phi)], -1)
            r = np.linalg.norm(wrist, axis=-1, keepdims=True)
            x[:, :2] += wrist / r * margin
        else:
            r = np.linalg.norm(x[:, :2], axis=-1, keepdims=True)
            x[:, :2] *= (r + margin) / r
        return x
    if name == "scorbot_er7":
        q[:, 2] = 0.0  # stretched
        q[:, 1] = rng.uniform(-1.2, 1.2, count)
        q[:, 3], q[:, 4] = -q[:, 1], 0
        x = k.task(q)
        forward = np.stack([np.cos(q[:, 0]), np.sin(q[:, 0])], -1)
        out = np.stack([np.cos(q[:, 1]), np.sin(q[:, 1])], -1)  # from the shoulder to the wrist
        x[:, :2] += forward * out[:, :1] * margin
        x[:, 2] += out[:, 1] * margin
        return x
    if name == "puma560":
        q[:, 2] = -math.atan2(p["d4"], p["a3"])  # a3 c3 - d4 s3 at its maximum: stretched
        T = k.fk(q)
        frames = k.frames(q)
        shoulder, wrist = frames[:, 1, :3, 3], T[:, :3, 3]
        x1, z1 = frames[:, 1, :3, 0], frames[:, 1, :3, 2]
        reach = wrist - shoulder - p["d3"] * z1
        in_plane = reach / np.linalg.norm(reach, axis=-1, keepdims=True)
        assert np.allclose((in_plane * z1).sum(-1), 0, atol=1e-12) and x1 is not None
        T[:, :3, 3] += in_plane * margin
        return T
    raise ValueError(name)


BOUNDED = ["planar_2r", "planar_3r", "adept_three", "scorbot_er7", "puma560"]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", BOUNDED)
def test_targets_just_inside_the_edge_solve_and_beyond_it_do_not(name, backend):
    k = kernels(name, backend)
    inside = edge_targets(name, k, np.random.default_rng(16), 300, -1e-12)
    Q, valid = k.ik(inside)
    assert valid.any(axis=-1).all()
    x = k.task(np.zeros(len(k.JOINTS))) if name != "puma560" else None
    target = inside if name != "puma560" else np.concatenate(
        [inside[:, :3, 3], inside[:, :3, :3].reshape(-1, 9)], -1)
    error = np.abs(k.task(Q) - target[:, None, :])
    if "phi" in k.TASK:
        i = k.TASK.index("phi")
        error[..., i] = np.abs((error[..., i] + np.pi) % (2 * np.pi) - np.pi)
    assert np.all(error.max(-1)[valid] < 1e-9), x
    for margin in (1e-9, 1e-6, 10.0):
        _, valid = k.ik(edge_targets(name, k, np.random.default_rng(17), 300, margin))
        assert not valid.any(), (name, margin)


# --- bad input ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_nan_and_inf_targets_give_valid_false_without_a_warning(name, backend):
    k = kernels(name, backend)
    q = np.full(len(k.JOINTS), 0.3)
    if name == "scorbot_er7":
        q[3], q[4] = -0.6, 0.0  # gripper horizontal
    good = k.task(q)
    bad = np.tile(good, (6, 1))
    bad[0, 0] = np.nan
    bad[1, -1] = np.inf
    bad[2, :] = -np.inf
    bad[3, 1] = np.nan
    far = 1 if name == "avr3000" else 0  # a length: the AVR 3000's first task coordinate is the angle T
    bad[4, far] = 1e100  # finite, and out of reach except for the unbounded planar R-P and P-P arms
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Q, valid = k.ik(bad)
    assert not valid[:4].any()
    assert valid[4].any() == (name in ("planar_rp", "planar_pp"))
    assert valid[5].any()
    assert np.isfinite(Q[5][valid[5]]).all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_joint_values_whose_sum_overflows_stay_valid(backend):
    """The C checks first add up every joint value (finite only where each is); a sum that overflows
    although each value is finite must not cost a branch its valid flag.  The Cartesian P-P arm's
    joints are its target's coordinates, so 1.5e308 and 1.6e308 are reachable, and their sum is inf."""
    k = kernels("planar_pp", backend)
    target = np.array([1.5e308, 1.6e308])
    Q, valid = k.ik(target)
    assert valid.all()
    assert sorted(Q[0]) == sorted(target)  # each prismatic joint moves along one axis, as far as the target
    assert np.array_equal(k.task(Q[0]), target)
    Q, valid = k.ik(np.array([1.5e308, np.nan]))
    assert not valid.any()


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pose_that_is_not_rigid_is_refused(backend):
    k = kernels("puma560", backend)
    T = k.fk([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    Q, valid = k.ik(T)  # a (4, 4) pose works like its 12-vector
    Q12, _ = k.ik(np.concatenate([T[:3, 3], T[:3, :3].ravel()]))
    np.testing.assert_array_equal(Q, Q12)
    assert valid.all()
    scaled = T.copy()
    scaled[:3, :3] *= 1.01
    with pytest.raises(ValueError, match=r"is not a rigid transform.*R R\^T - I.*expected an orthonormal R"):
        k.ik(scaled)
    mirrored = T.copy()
    mirrored[:3, 0] *= -1
    with pytest.raises(ValueError, match=r"det R = -1"):
        k.ik(mirrored)
    batch = np.stack([T, T, scaled])
    with pytest.raises(ValueError, match=r"x\[2\] is not a rigid transform"):
        k.ik(batch)
    projective = T.copy()
    projective[3, 0] = 0.5
    with pytest.raises(ValueError, match=r"not a homogeneous transform: last row"):
        k.ik(projective)
    with pytest.raises(ValueError, match=r"expected x of shape \(\.\.\., 12\) .* or a pose of shape \(\.\.\., 4, 4\)"):
        k.ik(np.zeros(6))
    nan_pose = T.copy()
    nan_pose[0, 0] = np.nan
    _, valid = k.ik(nan_pose)  # not a ValueError: reported through valid
    assert not valid.any()


def test_c_refuses_a_pose_that_is_not_rigid_with_minus_one():
    k = kernels("puma560", "c")
    ffi, lib = k._ffi, k._lib
    T = k.fk([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    x = np.concatenate([T[:3, 3], T[:3, :3].ravel()])

    def call(target):
        Q, flags = np.empty(48), np.full(8, 7, dtype=np.intc)
        found = lib.puma560_ik(ffi.from_buffer("double[]", np.ascontiguousarray(target)), ffi.NULL,
                               ffi.from_buffer("double[]", Q, require_writable=True),
                               ffi.from_buffer("int[]", flags, require_writable=True))
        return found, flags

    assert call(x) == (8, pytest.approx(np.ones(8)))
    sheared = x.copy()
    sheared[4] += 1e-6
    found, flags = call(sheared)
    assert found == -1 and not flags.any()
    found, flags = call(np.where(np.arange(12) == 5, np.nan, x))
    assert found == 0 and not flags.any()
    pair = np.ascontiguousarray(np.stack([x, sheared]))
    assert lib.puma560_ik_batch(2, ffi.from_buffer("double[]", pair), ffi.NULL,
                                ffi.from_buffer("double[]", np.empty(96), require_writable=True),
                                ffi.from_buffer("int[]", np.empty(16, dtype=np.intc), require_writable=True)) == -1


@pytest.mark.parametrize("backend", BACKENDS)
def test_ik_rejects_a_wrong_shape(backend):
    k = kernels("planar_3r", backend)
    with pytest.raises(ValueError, match=r"ik: expected x of shape \(\.\.\., 3\), got shape \(2,\)"):
        k.ik([0.1, 0.2])
    with pytest.raises(ValueError, match="real numeric array"):
        k.ik(["a", "b", "c"])


# --- joint limits -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_within_limits_counts_revolute_joints_modulo_a_turn(backend):
    k = kernels("puma560", backend)
    assert k.LIMITS[1] == pytest.approx((math.radians(-45), math.radians(225)))
    inside = [0.0, math.radians(200) - 2 * math.pi, 0.0, 0.0, 0.0, 0.0]  # theta2 = 200 deg, wrapped to -160
    outside = [0.0, math.radians(230) - 2 * math.pi, 0.0, 0.0, 0.0, 0.0]
    beyond_wrist = [0.0, 0.0, 0.0, 0.0, math.radians(120), 0.0]
    assert k.within_limits([inside, outside, beyond_wrist, [np.nan] * 6]).tolist() == [True, False, False, False]
    rng = np.random.default_rng(18)
    Q = rng.uniform(-np.pi, np.pi, (3000, 6))
    expected = np.ones(3000, dtype=bool)
    for i, (low, high) in enumerate(k.LIMITS):
        turns = Q[:, i, None] + 2 * np.pi * np.arange(-2, 3)
        expected &= ((turns >= low) & (turns <= high)).any(-1)
    np.testing.assert_array_equal(k.within_limits(Q), expected)


def test_within_limits_agrees_between_backends_and_on_unlimited_robots():
    rng = np.random.default_rng(19)
    for name in ("adept_three", "puma560", "planar_2r"):
        kn, kc = kernels(name, "numpy"), kernels(name, "c")
        Q = rng.uniform(-5, 5, (2000, len(kn.JOINTS)))
        np.testing.assert_array_equal(kn.within_limits(Q), kc.within_limits(Q))
    k = kernels("planar_2r", "numpy")
    assert k.within_limits([[10.0, -10.0], [np.inf, 0.0]]).tolist() == [True, False]


# --- the symbolic branches at a singular pose, and the README ------------------------------------------------

def test_puma_kernels_match_sympy_at_a_wrist_singular_pose(models):
    """The Piecewise choice theta4 := 0 holds in SymPy at 30 digits as in both kernels."""
    from codegen.verify import reference
    m = models["puma560"]
    function = m.ik_function()
    kn = kernels("puma560", "numpy")
    x = kn.task([0.3, -0.4, 0.5, 1.1, 0.0, -0.7])
    values = dict(zip(m.task_symbols, x))
    values.update(m.params)
    Q_ref, valid_ref = reference(function, values)
    for backend in BACKENDS:
        Q, valid = kernels("puma560", backend).ik(x)
        np.testing.assert_array_equal(valid, valid_ref)
        difference = np.abs(Q - Q_ref)
        assert np.all((difference < 1e-12) | (np.abs(difference - 2 * np.pi) < 1e-12))
    assert (Q_ref[:, 3] == 0).sum() >= 1


def test_readme_ik_example_runs():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    section = text[text.index("## Inverse kinematics"):]
    block = section[section.index("```python") + len("```python"):]
    block = block[:block.index("```")]
    namespace = {}
    exec(compile(block, "README.md", "exec"), namespace)
    assert namespace["valid"].all() and namespace["usable"].tolist() == [True, True, False, False]
    assert math.degrees(namespace["q"][1]) == pytest.approx(13.4685, abs=5e-5)


@pytest.mark.parametrize("name", ["planar_3r", "scorbot_er7", "puma560"])
def test_steps_define_each_symbol_from_earlier_ones_and_give_the_solution(models, name):
    """The printed form of a branch (``steps``) is well ordered and is the solution."""
    from derivations.ik import substitute_steps
    m = models[name]
    for branch in m.ik:
        assert branch.steps
        known = set(m.task_symbols) | set(m.params)
        for symbol, definition in branch.steps:
            assert sp.sympify(definition).free_symbols <= known, (branch.name, symbol)
            known.add(symbol)
        assert set(m.q) <= {s for s, _ in branch.steps}
        assert tuple(substitute_steps(q, branch.steps) for q in m.q) == branch.solution


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_inner_edge_of_the_two_link_workspace(backend):
    """Folded (q2 = pi) the 2R arm reaches |l1 - l2| = 51 mm: 1e-12 outside that ring solves, 1e-9 inside does not."""
    k = kernels("planar_2r", backend)
    l1, l2 = k.PARAMS["l1"], k.PARAMS["l2"]
    angles = np.random.default_rng(20).uniform(-np.pi, np.pi, 200)
    direction = np.stack([np.cos(angles), np.sin(angles)], -1)
    Q, valid = k.ik(direction * (l1 - l2 + 1e-12))
    assert valid.all()
    assert np.abs(k.task(Q) - direction[:, None] * (l1 - l2 + 1e-12)).max() < 1e-9
    np.testing.assert_allclose(np.abs(Q[..., 1]), np.pi, atol=1e-5)
    _, valid = k.ik(direction * (l1 - l2 - 1e-9))
    assert not valid.any()


@pytest.mark.parametrize("backend", BACKENDS)
def test_puma_near_the_wrist_singularity_every_branch_still_reaches_the_pose(backend):
    """Around theta5 = 0 and pi, on both sides of the 1e-12 switch to theta4 := 0, the pose error stays
    below 1e-12: theta5 and theta6 are taken from entries of size one given theta4."""
    k = kernels("puma560", backend)
    rng = np.random.default_rng(21)
    for theta5 in (1e-4, 1e-7, 1e-10, 1e-12, 3e-13, 1e-14, 0.0, np.pi - 1e-9, np.pi - 1e-12):
        q = rng.uniform(-np.pi, np.pi, (500, 6))
        q[:, 4] = theta5 * rng.choice([-1.0, 1.0], 500)
        T = k.fk(q)
        Q, valid = k.ik(T)
        assert valid.all()
        assert np.abs(k.fk(Q) - T[:, None]).max() < 2e-12, theta5

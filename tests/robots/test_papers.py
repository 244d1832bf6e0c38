"""The papers' equations, reproduced symbolically from the DH models.

Each test writes the printed equation out by hand, from the paper, and checks
that the derivation gives it (or, for a printed typo, that the print fails and
the derivation holds).
"""
import numpy as np
import pytest
import sympy as sp

import derivations
from derivations.chain import simplify_entry
from derivations.robots._common import parameters as params

c, s = sp.cos, sp.sin


def same(a, b):
    return sp.simplify(sp.expand_trig(sp.Matrix(a) - sp.Matrix(b))) == sp.zeros(*sp.Matrix(a).shape)


def test_kumar_eq4_planar_3r_position_and_orientation(models):
    m = models["planar_3r"]
    q1, q2, q3 = m.q
    l1, l2, l3 = params(m, "l1", "l2", "l3")
    # Kumar Eq. 4: x = l1 cos t1 + l2 cos(t1 + t2) + l3 cos(t1 + t2 + t3), y likewise, phi = t1 + t2 + t3
    eq4 = [l1 * c(q1) + l2 * c(q1 + q2) + l3 * c(q1 + q2 + q3),
           l1 * s(q1) + l2 * s(q1 + q2) + l3 * s(q1 + q2 + q3),
           q1 + q2 + q3]
    assert m.task_names == ("x", "y", "phi")
    assert same(m.task, eq4)


def test_kumar_eq11_planar_3r_jacobian_and_eq13_determinant(models):
    m = models["planar_3r"]
    q1, q2, q3 = m.q
    l1, l2, l3 = params(m, "l1", "l2", "l3")
    s1, s12, s123 = s(q1), s(q1 + q2), s(q1 + q2 + q3)
    c1, c12, c123 = c(q1), c(q1 + q2), c(q1 + q2 + q3)
    eq11 = [[-(l1 * s1 + l2 * s12 + l3 * s123), -(l2 * s12 + l3 * s123), -l3 * s123],
            [l1 * c1 + l2 * c12 + l3 * c123, l2 * c12 + l3 * c123, l3 * c123],
            [1, 1, 1]]
    assert m.task_jacobian == sp.Matrix(eq11).applyfunc(sp.expand)  # exactly, term by term
    # Kumar Eq. 13: |J| = l1 l2 sin(theta2)
    assert sp.simplify(m.task_jacobian.det() - l1 * l2 * s(q2)) == 0


def test_kumar_eqs5_to_10_rp_and_pp(models):
    rp = models["planar_rp"]
    q1, d2 = rp.q
    assert rp.joint_types == ("R", "P")
    assert same(rp.task, [d2 * c(q1), d2 * s(q1)])  # Kumar Eq. 5
    pp = models["planar_pp"]
    d1, d2 = pp.q
    assert pp.joint_types == ("P", "P")
    assert pp.task == sp.Matrix([d2, d1])  # Kumar Eq. 10: x = d2, y = d1


def test_slides_2r_geometric_jacobian(models):
    m = models["planar_2r"]
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    # Velocity-model slides, "Example: 2-link planer robot"
    slides = [[-l1 * s(q1) - l2 * s(q1 + q2), -l2 * s(q1 + q2)],
              [l1 * c(q1) + l2 * c(q1 + q2), l2 * c(q1 + q2)],
              [0, 0], [0, 0], [0, 0], [1, 1]]
    assert same(m.jacobian, slides)


def rehiara_printed_A(m):
    q1, q2, d3, q4 = m.q
    l1, l2, d1, d4 = params(m, "l1", "l2", "d1", "d4")
    A1 = [[c(q1), -s(q1), 0, l1 * c(q1)], [s(q1), c(q1), 0, l1 * s(q1)], [0, 0, 1, d1], [0, 0, 0, 1]]  # Eq. 9
    A2 = [[c(q2), s(q2), 0, l2 * c(q2)], [s(q2), -c(q2), 0, l2 * s(q2)], [0, 0, -1, 0], [0, 0, 0, 1]]  # Eq. 10
    A3 = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d3], [0, 0, 0, 1]]  # Eq. 11
    A4 = [[c(q4), -s(q4), 0, 0], [s(q4), c(q4), 0, 0], [0, 0, 1, d4], [0, 0, 0, 1]]  # Eq. 12
    return [sp.Matrix(a) for a in (A1, A2, A3, A4)]


def rehiara_printed_T(m):
    q1, q2, d3, q4 = m.q
    l1, l2, d1, d4 = params(m, "l1", "l2", "d1", "d4")
    s4, c4, s12, c12 = s(q4), c(q4), s(q1 + q2), c(q1 + q2)
    return sp.Matrix([  # Eq. 13 exactly as printed
        [s4 * s12 + c4 * c12, s4 * c12 + c4 * s12, 0, l2 * c12 + l1 * c(q1)],
        [s4 * c12 + c4 * s12, -s4 * s12 + c4 * c12, 0, l2 * s12 + l1 * s(q1)],
        [0, 0, -1, -d4 - d3 + d1],
        [0, 0, 0, 1]])


def test_rehiara_table1_gives_eqs9_to_12(models):
    m = models["adept_three"]
    for i, printed in enumerate(rehiara_printed_A(m)):
        derived = m.chain.link_transform(i, m.q[i]).applyfunc(simplify_entry)
        assert derived == printed.applyfunc(simplify_entry), f"A_{i + 1}"


def test_rehiara_eq14_position(models):
    m = models["adept_three"]
    q1, q2, d3, q4 = m.q
    l1, l2, d1, d4 = params(m, "l1", "l2", "d1", "d4")
    eq14 = [l2 * c(q1 + q2) + l1 * c(q1), l2 * s(q1 + q2) + l1 * s(q1), -d4 - d3 + d1]
    assert same(m.fk[:3, 3], eq14)
    assert m.params[l1] == 0.559 and m.params[l2] == 0.508 and m.params[d1] == 0.8763  # 559, 508, 876.3 mm


def test_E1_rehiara_eq13_rotation_block(models):
    """Eq. 13 as printed has sign errors in three rotation entries (erratum E1)."""
    m = models["adept_three"]
    q1, q2, d3, q4 = m.q
    product = sp.eye(4)
    for a in rehiara_printed_A(m):
        product = product * a
    assert same(m.fk, product)  # the derivation is the product of the printed Eqs. 9-12
    # The corrected rotation block: Rz(t1 + t2 - t4) with the tool z axis pointing down.
    a = q1 + q2 - q4
    corrected = sp.Matrix([[c(a), s(a), 0], [s(a), -c(a), 0], [0, 0, -1]])
    assert same(m.fk[:3, :3], corrected)
    printed = rehiara_printed_T(m)
    assert same(m.fk[:3, 3], printed[:3, 3])  # the position column of the print is right
    rng = np.random.default_rng(13)
    for _ in range(5):
        point = {sym: float(v) for sym, v in zip(m.q, rng.uniform(-2, 2, 4))}
        point.update({p: v for p, v in m.params.items()})
        P = np.array(printed.evalf(subs=point), dtype=float)
        T = np.array(m.fk.evalf(subs=point), dtype=float)
        wrong = np.abs(P[:3, :3] - T[:3, :3]) > 1e-9
        # entries (1,2), (2,1), (2,2) of the print are wrong; (1,1) and the third row/column hold
        assert wrong[0, 1] and wrong[1, 0] and wrong[1, 1] and not wrong[0, 0]
        assert not np.allclose(P[:3, :3] @ P[:3, :3].T, np.eye(3))  # the print is not even a rotation
        assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)


def test_scorbot_tool_point_with_gripper_horizontal(models):
    m = models["scorbot_er7"]
    q1, q2, q3, q4, q5 = m.q
    a1, a2, a3, d1, d5 = params(m, "a1", "a2", "a3", "d1", "d5")
    horizontal = {q4: -q2 - q3}  # theta2 + theta3 + theta4 = 0
    reach = a1 + a2 * c(q2) + a3 * c(q2 + q3) + d5
    expected = [c(q1) * reach, s(q1) * reach, d1 + a2 * s(q2) + a3 * s(q2 + q3)]
    assert same(m.fk[:3, 3].subs(horizontal), expected)
    assert sp.simplify(m.fk[2, 2].subs(horizontal)) == 0  # the gripper axis z_5 is horizontal
    assert [m.params[p] for p in (a1, a2, a3, d1, d5)] == [0.050, 0.300, 0.250, 0.385, 0.212]


def test_scorbot_theta2_is_measured_up_from_horizontal(models):
    m = models["scorbot_er7"]
    q1, q2, q3, q4, q5 = m.q
    at_rest = {q1: 0, q3: 0, q4: 0, q5: 0}
    z = m.fk[2, 3].subs(at_rest)
    a2, a3, d5 = params(m, "a2", "a3", "d5")
    # With the arm stretched out horizontally, raising theta2 lifts the tool at rate a2 + a3 + d5.
    assert sp.simplify(sp.diff(z, q2).subs(q2, 0) - (a2 + a3 + d5)) == 0


def test_puma560_home_pose_from_the_dh_table(models):
    m = models["puma560"]
    d1, a2, a3, d3, d4 = params(m, "d1", "a2", "a3", "d3", "d4")
    home = m.fk.subs({qi: 0 for qi in m.q})
    # At q = 0 the upper arm and forearm lie along x, the shoulder offset d3 along -y and d4 points up.
    assert home[:3, 3] == sp.Matrix([a2 + a3, -d3, d1 + d4])
    assert home[:3, :3] == sp.Matrix([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert [m.params[p] for p in (d1, a2, a3, d3, d4)] == [0.67183, 0.4318, 0.0203, 0.15005, 0.4318]


@pytest.mark.parametrize("name", list(derivations.ROBOTS))
def test_linear_part_of_geometric_jacobian_is_the_derivative_of_the_tool_point(models, name):
    m = models[name]
    derivative = m.fk[:3, 3].jacobian(sp.Matrix(m.q))
    assert (m.jacobian[:3, :] - derivative).applyfunc(simplify_entry) == sp.zeros(3, m.n)


@pytest.mark.parametrize("name", list(derivations.ROBOTS))
def test_frames_are_rigid_transforms(models, name):
    """R R^T = I and det R = 1 for every frame, at random points to 30 digits (fast where trigsimp is not)."""
    m = models[name]
    rng = np.random.default_rng(3)
    for frame in m.frames:
        assert frame[3, :] == sp.Matrix([[0, 0, 0, 1]])
        for _ in range(3):
            point = {qi: sp.Rational(float(v)) for qi, v in zip(m.q, rng.uniform(-3, 3, m.n))}
            point.update({p: sp.Rational(v) for p, v in m.params.items()})
            R = frame[:3, :3].evalf(30, subs=point)
            assert max(abs(e) for e in (R * R.T - sp.eye(3))) < 1e-25
            assert abs(R.det() - 1) < 1e-25


# --------------------------------------------------------------------------- Kumar's R-P orientation

@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_kumar_rp_pose_has_phi_equal_theta1(models, backend):
    """Kumar section 5.3, the R-P arm: x = d2 cos(theta1), y = d2 sin(theta1), phi = theta1 (Eq. 5 and the
    line after it). ``kumar_pose`` gives (x, y, phi) with that phi; the task stays (x, y). The tool frame's
    x axis is at theta1 - pi/2 and its z axis along the slide (the direction phi names)."""
    import generated
    k = generated.load("planar_rp", backend=backend)
    assert k.TASK == ("x", "y")
    rng = np.random.default_rng(5)
    q = np.column_stack([rng.uniform(-np.pi, np.pi, 500), rng.uniform(-2, 2, 500)])
    pose = k.kumar_pose(q)
    assert pose.shape == (500, 3)
    np.testing.assert_allclose(pose[:, 2], q[:, 0], rtol=0, atol=1e-15)                 # phi = theta1
    np.testing.assert_allclose(pose[:, 0], q[:, 1] * np.cos(q[:, 0]), rtol=0, atol=1e-14)  # x = d2 cos(theta1)
    np.testing.assert_allclose(pose[:, 1], q[:, 1] * np.sin(q[:, 0]), rtol=0, atol=1e-14)  # y = d2 sin(theta1)
    np.testing.assert_allclose(pose[:, :2], k.task(q), rtol=0, atol=1e-15)
    T = k.fk(q)
    np.testing.assert_allclose(np.arctan2(T[:, 1, 0], T[:, 0, 0]), np.angle(np.exp(1j * (q[:, 0] - np.pi / 2))),
                               atol=1e-12)
    np.testing.assert_allclose(T[:, :2, 2], np.column_stack([np.cos(q[:, 0]), np.sin(q[:, 0])]), atol=1e-15)
    from derivations.robots.planar_rp import kumar_phi
    assert kumar_phi(models["planar_rp"]) == models["planar_rp"].q[0]

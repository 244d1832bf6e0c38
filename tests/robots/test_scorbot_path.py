"""The SCORBOT ER-VII pick-and-place path: Predescu and Stroe, section 4.

The joint angles at M and N are checked against the paper's Eqs. 3.1-3.9
written out below with the math module (independent of derivations); Eq. 4.1
and Eq. 4.8 against their printed digits; the tool-point motion against its
geometry (on the line, elbow circle of radius a3) and finite differences; the
Cartesian version against the generated forward kinematics and Jacobian.
"""
import dataclasses
import math

import numpy as np
import pytest
import sympy as sp

import derivations
from codegen import build, generate
from codegen.verify import verify_model
from conftest import kernels
from derivations import scorbot_path as sc
from derivations import trajectory as tr
from derivations.trajectory import t

BACKENDS = ["numpy", "c"]
A1, A2, A3, D1, D5 = 0.050, 0.300, 0.250, 0.385, 0.212  # section 4, from the robot's manual [9]
M, N = (0.750, 0.0, 0.300), (0.300, 0.0, 0.750)


def paper_ik(x, y, z, theta3_sign):
    """Eqs. 3.1, 3.5, 3.9, 3.11 exactly as printed, with the sign of theta3 chosen by the caller."""
    theta1 = math.atan2(y, x)                                                        # (3.1)
    horizontal, vertical = math.sqrt(x**2 + y**2) - A1 - D5, z - D1                  # O2B, O4B
    theta3 = theta3_sign * math.acos((horizontal**2 + vertical**2 - A2**2 - A3**2) / (2 * A2 * A3))  # (3.5)
    theta2 = (math.atan2(vertical, horizontal)
              - math.atan2(A3 * math.sin(theta3), A2 + A3 * math.cos(theta3)))       # (3.9)
    return theta1, theta2, theta3, -theta2 - theta3                                   # (3.11)


@pytest.fixture(scope="module")
def scorbot():
    return derivations.load("scorbot_er7")


@pytest.fixture(scope="module")
def cubic_theta2(scorbot):
    return sc.theta2_cubic(scorbot)


def values(exprs):
    return [float(e) for e in exprs]


# -- joint angles at M and N, Eq. 4.1 ------------------------------------------------------

def test_joint_angles_at_m_and_n_are_the_papers_elbow_up_solution(scorbot):
    for point in (M, N):
        expected = paper_ik(*point, theta3_sign=-1)
        got = values(sc.joint_angles(scorbot, point))
        np.testing.assert_allclose(got[:4], expected, rtol=0, atol=1e-14)
        assert got[4] == 0
    assert sc.paper_branch(scorbot).name == "elbow_up"


def test_eq_4_1_cubic_for_theta2(scorbot):
    """Eq. 4.1: theta2(t) = 13.4685 + 3.3946 t^2 - 0.2263 t^3 [deg], from the IK at M and N over 10 s."""
    coefficients = sp.Poly(sc.eq_4_1_degrees(scorbot), t).all_coeffs()  # t^3, t^2, t, 1
    assert [round(float(c), 4) for c in coefficients] == [-0.2263, 3.3946, 0.0, 13.4685]
    assert float(coefficients[3]) == pytest.approx(math.degrees(paper_ik(*M, -1)[1]), abs=1e-12)
    at_n = float(sc.eq_4_1_degrees(scorbot).subs(t, 10))
    assert at_n == pytest.approx(math.degrees(paper_ik(*N, -1)[1]), abs=1e-12)


def test_E11_principal_arccosine_of_eq_3_5_gives_the_other_elbow():
    """Eqs. 3.5 and 3.9 as printed (acos in [0, pi]) give theta2(M) = -33.23 deg, not Eq. 4.1's 13.4685 deg."""
    printed = math.degrees(paper_ik(*M, theta3_sign=+1)[1])
    assert round(printed, 2) == -33.23
    assert round(math.degrees(paper_ik(*M, theta3_sign=-1)[1]), 4) == 13.4685


def test_eq_4_8_parameters_are_the_ik_values_rounded(scorbot):
    """Eq. 4.8: theta_i = 0.235 rad = theta2(M), A0 = 1.975 rad = theta2(N) - theta2(M), omega0 = pi/5 = 2 pi / 10 s."""
    theta_m, theta_n = paper_ik(*M, -1)[1], paper_ik(*N, -1)[1]
    theta_i, amplitude, omega = sc.CYCLOIDAL_PARAMETERS
    assert round(theta_m, 3) == float(theta_i) and round(theta_n - theta_m, 3) == float(amplitude)
    assert 2 * sp.pi / omega == sc.DURATION
    law = sc.theta2_cycloidal()
    assert float(law.subs(t, 0)) == pytest.approx(theta_m, abs=1e-3)
    assert float(law.subs(t, 10)) == pytest.approx(theta_n, abs=1e-3)


def test_paper_branch_is_chosen_by_geometry_from_the_models_own_ik(scorbot):
    """Once the model carries IK branches, the path takes the one with theta1 = 0 and theta3 < 0 at M."""
    branches = list(reversed(sc.paper_ik_branches(scorbot)))
    renamed = [dataclasses.replace(b, name=f"branch_{i}") for i, b in enumerate(branches)]
    model = dataclasses.replace(scorbot, ik=renamed)
    assert sc.paper_branch(model).name == "branch_1"
    with pytest.raises(sc.PathError, match="expected exactly one IK branch"):
        sc.paper_branch(dataclasses.replace(scorbot, ik=renamed[:1]))


def test_out_of_reach_point_is_reported(scorbot):
    with pytest.raises(sc.PathError, match=r"out of reach on branch elbow_up"):
        sc.joint_angles(scorbot, (2.0, 0.0, 0.3))


# -- P5 driven by the theta2 law (Eqs. 4.2-4.7) ------------------------------------------------

@pytest.mark.parametrize("law_name", ["cubic", "cycloidal"])
def test_tool_point_runs_on_mn_with_the_elbow_circle(scorbot, cubic_theta2, law_name):
    law = cubic_theta2 if law_name == "cubic" else sc.theta2_cycloidal()
    position, velocity, _ = sc.tool_motion(scorbot, law)
    for time in np.linspace(0, 10, 11):
        x, z = values(position.subs(t, sp.Rational(time)))
        theta2 = float(law.subs(t, sp.Rational(time)))
        assert x + z == pytest.approx(1.05, abs=1e-12)  # the line MN: x + z = 0.75 + 0.300
        o3 = (A1 + A2 * math.cos(theta2), D1 + A2 * math.sin(theta2))
        assert math.hypot(x - D5 - o3[0], z - o3[1]) == pytest.approx(A3, abs=1e-12)  # |O3 O4| = a3
        # and the elbow-up IK of that P5 gives back theta2: the construction stays on the paper's branch
        assert paper_ik(x, 0.0, z, -1)[1] == pytest.approx(theta2, abs=1e-9)
    if law_name == "cubic":  # exactly M at t = 0 and N at t = 10 (the law joins the IK angles)
        np.testing.assert_allclose(values(position.subs(t, 0)), [M[0], M[2]], atol=1e-14)
        np.testing.assert_allclose(values(position.subs(t, 10)), [N[0], N[2]], atol=1e-14)
    assert values(velocity.subs(t, 0)) == [0.0, 0.0] and values(velocity.subs(t, 10)) == [0.0, 0.0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_tool_point_kernel_matches_the_symbolic_motion_and_finite_differences(scorbot, cubic_theta2, backend):
    k = kernels("scorbot_path", backend)
    trapezoidal = kernels("trajectory", backend)
    times = np.linspace(0.5, 9.5, 7)
    q0, qf = float(cubic_theta2.subs(t, 0)), float(cubic_theta2.subs(t, 10))
    theta_state, _ = trapezoidal.cubic(times[:, None], [q0, qf, 10.0, 0.0, 0.0])
    p, valid = k.tool_point_from_theta2(theta_state)
    assert p.shape == (7, 3, 2) and valid.all()
    position, velocity, acceleration = sc.tool_motion(scorbot, cubic_theta2.evalf(30))
    for i, time in enumerate(times):
        expected = [values(m.subs(t, sp.Rational(time))) for m in (position, velocity, acceleration)]
        np.testing.assert_allclose(p[i], expected, rtol=0, atol=1e-13)
    h = 1e-5
    ahead, _ = k.tool_point_from_theta2(trapezoidal.cubic(times[:, None] + h, [q0, qf, 10.0, 0, 0])[0])
    behind, _ = k.tool_point_from_theta2(trapezoidal.cubic(times[:, None] - h, [q0, qf, 10.0, 0, 0])[0])
    np.testing.assert_allclose(p[:, 1], (ahead[:, 0] - behind[:, 0]) / (2 * h), atol=1e-9)
    np.testing.assert_allclose(p[:, 2], (ahead[:, 1] - behind[:, 1]) / (2 * h), atol=1e-9)


# -- the Cartesian straight line -------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_joints_along_the_line_reach_the_line_with_the_right_velocity(backend):
    k = kernels("scorbot_path", backend)
    robot = kernels("scorbot_er7", backend)
    laws = kernels("trajectory", backend)
    times = np.linspace(0.0, 10.0, 41)[:, None]
    s_state, _ = laws.cubic(times, [0.0, 1.0, 10.0, 0.0, 0.0])
    q, valid = k.joints_along_line(s_state)
    assert q.shape == (41, 3, 5) and valid.all()
    angles, rates, accelerations = q[:, 0], q[:, 1], q[:, 2]
    direction = np.subtract(N, M)
    # forward kinematics (generated from the DH table, not from the IK) puts P5 on the line ...
    np.testing.assert_allclose(robot.task(angles), M + s_state[:, :1] * direction, atol=1e-14)
    # ... with the gripper horizontal (Eq. 3.10) ...
    np.testing.assert_allclose(angles[:, 1] + angles[:, 2] + angles[:, 3], 0, atol=1e-14)
    # ... and the joint rates give the tool velocity through the Jacobian: J qdot = sdot (N - M)
    tool_velocity = np.einsum("...ij,...j->...i", robot.task_jacobian(angles), rates)
    np.testing.assert_allclose(tool_velocity, s_state[:, 1:2] * direction, atol=1e-14)
    # accelerations: the derivative of the rates (central differences along the same law)
    h = 1e-5
    ahead = k.joints_along_line(laws.cubic(times + h, [0.0, 1.0, 10.0, 0.0, 0.0])[0])[0][:, 1]
    behind = k.joints_along_line(laws.cubic(times - h, [0.0, 1.0, 10.0, 0.0, 0.0])[0])[0][:, 1]
    np.testing.assert_allclose(accelerations, (ahead - behind) / (2 * h), atol=1e-8)
    # the ends: the IK angles at M and N, at rest
    np.testing.assert_allclose(angles[0, :4], paper_ik(*M, -1), atol=1e-14)
    np.testing.assert_allclose(angles[-1, :4], paper_ik(*N, -1), atol=1e-14)
    np.testing.assert_allclose(rates[[0, -1]], 0, atol=1e-15)


def test_joints_along_line_symbolic_agrees_with_the_kernel(scorbot):
    law = tr.cubic(0, 1, 10)
    angles, rates, accelerations = sc.joints_along_line(scorbot, law)
    k = kernels("scorbot_path", "numpy")
    for time in (1, 4, 7.5):
        s_state = [float(e.subs(t, time)) for e in tr.position_velocity_acceleration(law)]
        q, valid = k.joints_along_line(s_state)
        assert valid
        expected = [values(m.subs(t, sp.Rational(time))) for m in (angles, rates, accelerations)]
        np.testing.assert_allclose(q, expected, rtol=0, atol=1e-14)


def test_joints_along_line_flags_unreachable_points():
    k = kernels("scorbot_path", "numpy")
    with np.errstate(invalid="ignore"):
        q, valid = k.joints_along_line([[0.5, 0, 0], [0.5, 0, 0]], xN=[2.0, 0.3][0])
    assert not valid.any()


@pytest.fixture(scope="module")
def path_kernels():
    return derivations.load_kernel_set("scorbot_path")


def test_every_path_kernel_matches_sympy_at_30_digits(path_kernels):
    # three points each: the 30-digit reference of the second derivatives is slow (about 4 s a point)
    checks = verify_model(path_kernels, {b: kernels("scorbot_path", b) for b in BACKENDS}, samples=3, seed=5)
    assert len(checks) == 2 * 2
    assert not [c for c in checks if not c.ok], checks


def test_path_c_compiles_strictly_and_runs_clean_under_sanitizers(path_kernels):
    package = generate.GENERATED / "scorbot_path"
    build.compile_strict(package, "scorbot_path")
    # the driver needs the entry points only, not the CSE of a render (generate.entry_points)
    assert build.sanitizer_run(package, "scorbot_path", generate.entry_points(path_kernels), 0).count("\n") >= 4

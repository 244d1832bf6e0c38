"""Sotirov, "Kinematics of AVR 3000 Vacuum Robot": every printed equation against the derived model.

Each test writes the paper's equation out by hand and checks that the model's
derivation gives it; where the print is wrong the test shows the printed form
failing and the derived one holding (README, "Errata": E8-E10, AVR3, AVR4, AVR6).
"""
import math

import numpy as np
import pytest
import sympy as sp

import derivations
from derivations.spaces import SpacesModel

c, s, pi = sp.cos, sp.sin, sp.pi
IN = 0.0254


@pytest.fixture(scope="module")
def avr():
    return derivations.load("avr3000")


def syms(model):
    p = {str(k): k for k in model.params}
    return p["a"], p["e"], p["J11"], p["J21"], p["J22"], p["J33"]


def vanishes(expr):
    return sp.simplify(sp.expand_trig(sp.Matrix(expr))) == sp.zeros(*sp.Matrix(expr).shape)


def test_registry_holds_the_python_built_robot(avr):
    assert derivations.ROBOTS["avr3000"].name == "avr3000.py"
    assert isinstance(avr, SpacesModel)
    assert avr.joint_types == ("R", "R", "P") and avr.task_names == ("T", "R", "Z")
    names = {f.name for f in avr.functions()}
    for source in ("motor", "joint", "tool", "cartesian"):
        for target in ("motor", "joint", "tool", "cartesian"):
            if source != target:
                assert {f"{source}_to_{target}", f"{source}_to_{target}_velocity",
                        f"{source}_to_{target}_acceleration"} <= names
    assert {"fk", "frames", "jacobian", "task", "task_jacobian", "ik"} <= names


def test_section5_and_eq1_defaults_in_si(avr):
    a, e, J11, J21, J22, J33 = syms(avr)
    assert avr.params[a] == pytest.approx(10.5 * IN, abs=0)  # link length 10.5 in
    assert avr.params[J11] == -4.0175691732e-5 and avr.params[J21] == 2.6036376953e-5  # Eq. 1 values, rad/count
    assert avr.params[J22] == -2.6036376953e-5
    assert avr.params[J33] == pytest.approx(6.5616798e-6 * IN, rel=1e-15)  # printed in in/count


def test_eqs_2_and_3_motor_to_joint_velocity_and_acceleration(avr):
    a, e, J11, J21, J22, J33 = syms(avr)
    td, tdd = avr.spaces["motor"].velocity, avr.spaces["motor"].acceleration
    eq2 = [J11 * td[0], J21 * td[0] + J22 * td[1], J33 * td[2]]
    eq3 = [J11 * tdd[0], J21 * tdd[0] + J22 * tdd[1], J33 * tdd[2]]
    assert avr.maps["motor_to_joint_velocity"].values == sp.Matrix(eq2)
    assert avr.maps["motor_to_joint_acceleration"].values == sp.Matrix(eq3)


def test_eqs_5_and_6_joint_to_tool_velocity_and_acceleration(avr):
    a = syms(avr)[0]
    q1, q2, q3 = avr.spaces["joint"].position
    qd, qdd = avr.spaces["joint"].velocity, avr.spaces["joint"].acceleration
    eq5 = [-qd[0] - qd[1] / 2, -a * s(q2 / 2) * qd[1], qd[2]]
    eq6 = [-qdd[0] - qdd[1] / 2, -a * c(q2 / 2) * qd[1]**2 / 2 - a * s(q2 / 2) * qdd[1], qdd[2]]
    assert vanishes(avr.maps["joint_to_tool_velocity"].values - sp.Matrix(eq5))
    assert vanishes(avr.maps["joint_to_tool_acceleration"].values - sp.Matrix(eq6))


def test_eq4_is_the_wrist_of_eq7_in_polar_form(avr):
    # Eq. 4 (R = 2a cos(q2/2) along the bisector, T from the y axis) and Eq. 7 with e = 0 place the wrist alike.
    a, e = syms(avr)[:2]
    T, R, _ = avr.maps["joint_to_tool"].values
    wrist = avr.maps["joint_to_cartesian"].values.subs(e, 0)
    assert vanishes(wrist[:2, 0] - sp.Matrix([R * s(T), R * c(T)]))


def test_eq7_position_from_the_link_frames(avr):
    a, e = syms(avr)[:2]
    q1, q2, q3 = avr.q
    eq7 = [a * (c(q1) + c(q1 + q2)) - e * c(q1 + q2 / 2), a * (s(q1) + s(q1 + q2)) - e * s(q1 + q2 / 2), q3]
    assert vanishes(avr.maps["joint_to_cartesian"].values - sp.Matrix(eq7))
    assert avr.fk[:3, 3] == avr.maps["joint_to_cartesian"].values
    # The hand lies on the bisector of the links: the tool frame is turned by q1 + q2/2 = pi/2 - T.
    assert vanishes(avr.fk[:2, 0] - sp.Matrix([c(q1 + q2 / 2), s(q1 + q2 / 2)]))


def test_E8_eq7_velocity_expanded_lines_and_the_jx(avr):
    """E8: the collected J12^x, J22^x drop the factor 0.5 on the e term that the expanded line above them has."""
    a, e = syms(avr)[:2]
    q1, q2, _ = avr.q
    qd1, qd2, _ = avr.spaces["joint"].velocity
    derived = avr.maps["joint_to_cartesian_velocity"].values
    xdot = a * (-s(q1) * qd1 - s(q1 + q2) * (qd1 + qd2)) + e * s(q1 + q2 / 2) * (qd1 + qd2 / 2)  # first line
    ydot = a * (c(q1) * qd1 + c(q1 + q2) * (qd1 + qd2)) - e * c(q1 + q2 / 2) * (qd1 + qd2 / 2)
    assert vanishes(derived[:2, 0] - sp.Matrix([xdot, ydot]))
    Jx = derived[:2, 0].jacobian(sp.Matrix([qd1, qd2]))
    J11x = -a * (s(q1) + s(q1 + q2)) + e * s(q1 + q2 / 2)
    J21x = a * (c(q1) + c(q1 + q2)) - e * c(q1 + q2 / 2)
    printed_J12x = -a * s(q1 + q2) + e * s(q1 + q2 / 2)
    printed_J22x = a * c(q1 + q2) - e * c(q1 + q2 / 2)
    assert vanishes(Jx[:, 0] - sp.Matrix([J11x, J21x]))
    assert not vanishes(Jx[:, 1] - sp.Matrix([printed_J12x, printed_J22x]))
    assert vanishes(Jx[:, 1] - sp.Matrix([-a * s(q1 + q2) + e * s(q1 + q2 / 2) / 2,
                                          a * c(q1 + q2) - e * c(q1 + q2 / 2) / 2]))
    assert Jx == avr.jacobian[:2, :2]  # the geometric Jacobian's linear rows


def test_eq8_tool_to_joint(avr):
    a = syms(avr)[0]
    T, R, Z = avr.spaces["tool"].position
    q2 = 2 * sp.acos(R / (2 * a))
    eq8 = [pi / 2 - q2 / 2 - T, q2, Z]
    assert avr.maps["tool_to_joint"].values == sp.Matrix(eq8)
    from derivations.ik import WrapAngle
    assert avr.ik[0].solution == (WrapAngle(eq8[0]), eq8[1], eq8[2])  # the ik branch wraps q1 to (-pi, pi]


def _in_tool_coordinates(expr, avr):
    """The paper writes Eqs. 9-10 in q2; on q2 in [0, 2 pi], cos(q2/2) = R/2a and sin(q2/2) = sqrt(1 - (R/2a)^2)."""
    a = syms(avr)[0]
    R = avr.spaces["tool"].position[1]
    half = sp.Symbol("h")
    q2 = avr.q[1]
    return expr.subs(q2, 2 * half).subs({c(half): R / (2 * a), s(half): sp.sqrt(1 - (R / (2 * a))**2)})


def test_eqs_9_and_10_tool_to_joint_velocity_and_acceleration(avr):
    a = syms(avr)[0]
    q2 = avr.q[1]
    Td, Rd, Zd = avr.spaces["tool"].velocity
    Tdd, Rdd, Zdd = avr.spaces["tool"].acceleration
    qd2_eq9 = -Rd / (a * s(q2 / 2))
    eq9 = [-qd2_eq9 / 2 - Td, qd2_eq9, Zd]
    qdd2_eq10 = (-a * c(q2 / 2) * qd2_eq9**2 / 2 - Rdd) / (a * s(q2 / 2))
    eq10 = [-qdd2_eq10 / 2 - Tdd, qdd2_eq10, Zdd]
    for printed, name in ((eq9, "tool_to_joint_velocity"), (eq10, "tool_to_joint_acceleration")):
        printed = sp.Matrix(printed).applyfunc(lambda v: _in_tool_coordinates(v, avr))
        assert vanishes(avr.maps[name].values - printed), name


def test_eqs_11_to_13_joint_to_motor(avr):
    a, e, J11, J21, J22, J33 = syms(avr)
    q, qd, qdd = (avr.spaces["joint"].at(level) for level in ("position", "velocity", "acceleration"))
    eq11 = [q[0] / J11, (q[1] - pi - J21 / J11 * q[0]) / J22, q[2] / J33]
    eq12 = [qd[0] / J11, (qd[1] - J21 / J11 * qd[0]) / J22, qd[2] / J33]
    eq13 = [qdd[0] / J11, (qdd[1] - J21 / J11 * qdd[0]) / J22, qdd[2] / J33]
    for printed, name in ((eq11, "joint_to_motor"), (eq12, "joint_to_motor_velocity"),
                          (eq13, "joint_to_motor_acceleration")):
        assert vanishes(avr.maps[name].values - sp.Matrix(printed)), name


def test_eq14_motor_to_tool_velocity(avr):
    a, e, J11, J21, J22, J33 = syms(avr)
    th = avr.spaces["motor"].position
    td = avr.spaces["motor"].velocity
    q2 = pi + J21 * th[0] + J22 * th[1]  # Eq. 1
    eq14 = [(-J11 - J21 / 2) * td[0] - J22 / 2 * td[1], -a * s(q2 / 2) * (J21 * td[0] + J22 * td[1]), J33 * td[2]]
    assert vanishes(avr.maps["motor_to_tool_velocity"].values - sp.Matrix(eq14))


def _eq1_values(avr):
    return {k: sp.Rational(v) for k, v in avr.params.items()}


def test_section4_gear_ratios(avr):
    """Sotirov section 4: GearT = -J22/J21 = 1, GearR = 0.5 J22 / (-J11 - 0.5 J21) = -0.47935881."""
    a, e, J11, J21, J22, J33 = syms(avr)
    assert sp.simplify(avr.constants["GEAR_T"] - (-J22 / J21)) == 0
    assert sp.simplify(avr.constants["GEAR_R"] - (J22 / 2) / (-J11 - J21 / 2)) == 0
    values = _eq1_values(avr)
    assert avr.constants["GEAR_T"].xreplace(values) == 1
    gear_r = float(avr.constants["GEAR_R"].xreplace(values))
    assert gear_r == pytest.approx(-0.47935881, abs=5e-9)  # the print's 8 digits, with the derived sign
    # The Matlab script's 0.479358811234781 (15 digits) agrees to the 11 digits of Eq. 1's values.
    assert abs(gear_r) == pytest.approx(0.479358811234781, rel=2e-11)


def test_E9_section4_gear_r_sign(avr):
    """E9: GearR is printed positive; only the negative ratio keeps T still (Eq. 14, first row)."""
    Tdot = avr.maps["motor_to_tool_velocity"].values[0]
    td = avr.spaces["motor"].velocity
    values = _eq1_values(avr)
    for ratio, still in ((sp.Rational("-0.479358811229"), True), (sp.Rational("0.47935881"), False)):
        rate = float(Tdot.subs({td[0]: ratio, td[1]: 1, td[2]: 0}).xreplace(values))
        scale = float(values[syms(avr)[2]])  # |J11|: the size of each term
        assert (abs(rate) < 1e-11 * abs(scale)) == still


def test_AVR3_section4_numbers_differ_from_eq1_but_keep_the_ratio(avr):
    """AVR3: section 4 substitutes J21 = 1.1634e-5, J11 = -1.795196e-5, not Eq. 1's values; the ratio J11/J21 agrees."""
    a, e, J11, J21, J22, J33 = syms(avr)
    eq1 = {k: float(v) for k, v in _eq1_values(avr).items()}
    assert eq1[J21] != pytest.approx(1.1634e-5, rel=0.1)
    assert eq1[J11] / eq1[J21] == pytest.approx(-1.795196 / 1.1634, rel=1e-10)
    printed_gear_r = (-0.5 * 1.1634e-5) / (1.795196e-5 - 0.5 * 1.1634e-5)  # section 4.2 as printed, before "="
    assert printed_gear_r == pytest.approx(-0.47935881, abs=5e-9)  # negative: the "= 0.47935881" dropped the sign


# The Matlab script of section 6, transcribed (its own units: inches, motor radians).
ECPR_TR = 2048 * 4 / (2 * math.pi)
ECPR_Z = 2500 * 4 / (2 * math.pi)
GEAR_T_SCRIPT, GEAR_R_SCRIPT, GEAR_Z_SCRIPT = -4.0175691732E-5, -2.6036376953E-5, 6.5616798E-06
ARM = 21.0 / 2.0


def matlab_jmj():
    return np.array([[-GEAR_T_SCRIPT * ECPR_TR, 0, 0],
                     [GEAR_R_SCRIPT * ECPR_TR, -GEAR_R_SCRIPT * ECPR_TR, 0],
                     [0, 0, GEAR_Z_SCRIPT * ECPR_Z]])


def matlab_jjt(q2):
    return np.array([[-1.0, -0.5, 0], [0, -ARM * math.sin(0.5 * q2), 0], [0, 0, 1.0]])


def test_matlab_script_position_numbers():
    R = 18.3
    q2 = 2.0 * math.acos(R / (ARM * 2.0))
    q1 = (math.pi - q2) / 2.0
    assert q2 == pytest.approx(1.025378, abs=5e-7)
    assert ARM * (math.cos(q1) + math.cos(q1 + q2)) == pytest.approx(0, abs=1e-12)
    assert ARM * (math.sin(q1) + math.sin(q1 + q2)) == pytest.approx(18.3, abs=1e-12)


def test_AVR4_matlab_jmj_sign(avr):
    """AVR4: the script's JMJ is -ECPR times Eq. 1's Jacobian in its T and R rows (same magnitudes)."""
    values = {k: float(v) for k, v in avr.params.items()}
    J = np.array(avr.maps["motor_to_joint_velocity"].values.jacobian(
        sp.Matrix(avr.spaces["motor"].velocity)).subs(values), dtype=float)
    per_motor_radian = J * np.array([ECPR_TR, ECPR_TR, ECPR_Z])  # d joint / d motor angle
    jmj = matlab_jmj()
    assert not np.allclose(jmj, per_motor_radian, rtol=1e-9)
    np.testing.assert_allclose(jmj[:2], -per_motor_radian[:2], rtol=1e-9)
    np.testing.assert_allclose(jmj[2] * IN, per_motor_radian[2], rtol=1e-9)  # Z: inches there, metres here


def test_matlab_jjt_and_jx_are_the_derived_jacobians(avr):
    a, e = syms(avr)[:2]
    q2 = avr.q[1]
    jjt = avr.maps["joint_to_tool_velocity"].values.jacobian(sp.Matrix(avr.spaces["joint"].velocity))
    assert vanishes(jjt - sp.Matrix([[-1, -sp.Rational(1, 2), 0], [0, -a * s(q2 / 2), 0], [0, 0, 1]]))
    T, R, _ = avr.spaces["tool"].position
    jx = avr.maps["tool_to_cartesian_velocity"].values.jacobian(sp.Matrix(avr.spaces["tool"].velocity)).subs(e, 0)
    assert vanishes(jx - sp.Matrix([[R * c(T), s(T), 0], [-R * s(T), c(T), 0], [0, 0, 1]]))  # the script's JX


def test_E10_matlab_jjc_misses_the_link_length(avr):
    """E10: the script's JJC (joint -> Cartesian) lacks the factor a = ArmLength in its x and y rows."""
    a, e = syms(avr)[:2]
    q1, q2, _ = avr.q
    derived = avr.maps["joint_to_cartesian_velocity"].values.jacobian(
        sp.Matrix(avr.spaces["joint"].velocity)).subs(e, 0)
    jjc = sp.Matrix([[-s(q1) - s(q1 + q2), -s(q1 + q2), 0], [c(q1) + c(q1 + q2), c(q1 + q2), 0], [0, 0, 1]])
    assert not vanishes(derived - jjc)
    assert vanishes(derived - sp.diag(a, a, 1) * jjc)


def test_matlab_jmt_is_the_chain_rule_of_the_derived_maps(avr):
    """JMT = JJT JMJ: the composed motor -> tool velocity map equals the product of its two Jacobians."""
    J = avr.maps["motor_to_joint_velocity"].values.jacobian(sp.Matrix(avr.spaces["motor"].velocity))
    jjt = avr.maps["joint_to_tool_velocity"].values.jacobian(sp.Matrix(avr.spaces["joint"].velocity))
    jjt_of_motor = jjt.xreplace(dict(zip(avr.q, avr.maps["motor_to_joint"].values)))
    jmt = avr.maps["motor_to_tool_velocity"].values.jacobian(sp.Matrix(avr.spaces["motor"].velocity))
    assert vanishes(jmt - jjt_of_motor * J)
    assert jmt == avr.maps["motor_to_tool"].jacobian  # the same matrix, as the model exposes it
    jjc = avr.maps["joint_to_cartesian_velocity"].values.jacobian(sp.Matrix(avr.spaces["joint"].velocity))
    jmc = avr.maps["motor_to_cartesian_velocity"].values.jacobian(sp.Matrix(avr.spaces["motor"].velocity))
    assert vanishes(jmc - jjc.xreplace(dict(zip(avr.q, avr.maps["motor_to_joint"].values))) * J)


def test_AVR4_matlab_pure_r_motion_magnitude_matches_the_model(avr):
    """At R = 18.3 in, [0.479.. x, -1 x] 4500 rpm: the script gives Rdot = +121.886 in/s, the model -121.886 in/s."""
    omega = 4500 * 2 * math.pi / 60
    motors = np.array([0.479358811234781 * omega, -omega, 0])
    q2 = 2.0 * math.acos(18.3 / (ARM * 2.0))
    script_tool = matlab_jjt(q2) @ matlab_jmj() @ motors
    assert script_tool[0] == pytest.approx(0, abs=1e-9)
    assert script_tool[1] == pytest.approx(121.886, abs=5e-4)

    values = {k: sp.Rational(v) for k, v in avr.params.items()}
    T, R, Z = avr.spaces["tool"].position
    motor_position = avr.maps["tool_to_motor"].values.subs({T: 0, R: sp.Rational("18.3") * sp.Rational("0.0254"),
                                                            Z: 0}).xreplace(values)
    counts = motors * np.array([ECPR_TR, ECPR_TR, ECPR_Z])  # motor rad/s -> counts/s
    rates = avr.maps["motor_to_tool_velocity"].values.subs(dict(zip(avr.spaces["motor"].position, motor_position)))
    rates = rates.subs(dict(zip(avr.spaces["motor"].velocity, [sp.Rational(v) for v in counts]))).xreplace(values)
    tool_rate = [float(v.evalf(30)) for v in rates]
    assert tool_rate[0] == pytest.approx(0, abs=1e-9)
    assert tool_rate[1] / IN == pytest.approx(-script_tool[1], rel=1e-9)  # AVR4: opposite sign, same magnitude


def test_AVR6_matlab_script_keeps_only_the_last_motor_vector():
    """AVR6: MaxMotorVel is assigned for R, T and Z motion in turn; as printed only Z survives, so the
    script's R-axis block computes VelMaxR = 0, AccMaxR = 0 and TimeAccR = 0/0."""
    omega_z = 5500 * 2 * math.pi / 60
    max_motor_vel = np.array([0, 0, omega_z])  # the last assignment wins
    q2 = 2.0 * math.acos(18.3 / (ARM * 2.0))
    vel_max_r = (matlab_jjt(q2) @ matlab_jmj() @ max_motor_vel)[1]
    acc_max_r = 1.5 * vel_max_r * vel_max_r / abs(20.0 - (-10.0))
    assert vel_max_r == 0 and acc_max_r == 0
    with np.errstate(invalid="ignore"):
        assert np.isnan(np.float64(1.5 * vel_max_r) / np.float64(acc_max_r))

"""Errata E2-E12: printed equations that fail, beside the derived forms that hold.

Each test writes the printed form out by hand from the paper, shows numerically
that it fails, and shows that the derived form holds (against the DH model, a
SymPy derivative, finite differences or the paper's own numbers).  E1 (Rehiara
Eq. 13) is in test_papers.py.  The report (report/chapters/) and the README
errata table cite these tests by name.
"""
import math

import numpy as np
import pytest
import sympy as sp

import derivations
from derivations.chain import dh_standard
from derivations.robots._common import parameters as params

c, s = sp.cos, sp.sin
RNG = np.random.default_rng(2011)


def numeric(expr, values):
    return np.array(sp.N(sp.sympify(expr).subs(values), 30), dtype=float)


# --------------------------------------------------------------------------- Rehiara


def rehiara_eq6_printed(theta, d, a, alpha):
    """Rehiara Eq. 6 exactly as printed (Eq. 2 is its rotation block; the Maple DH script builds the same)."""
    return sp.Matrix([
        [c(theta), -c(alpha) * s(theta), s(alpha) * s(theta), a * c(theta)],
        [s(theta), c(alpha) * c(theta), -s(alpha) * s(theta), a * s(theta)],
        [0, s(alpha), c(alpha), d],
        [0, 0, 0, 1]])


def test_E2_rehiara_eq2_eq6_entry_23_is_minus_sin_alpha_cos_theta():
    """E2: entry (2,3) of Eqs. 2 and 6 reads -sin(alpha) sin(theta); Eq. 5's product gives -sin(alpha) cos(theta)."""
    theta, d, a, alpha = sp.symbols("theta d a alpha", real=True)
    rot_z = sp.Matrix([[c(theta), -s(theta), 0, 0], [s(theta), c(theta), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    trans_z = sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d], [0, 0, 0, 1]])
    trans_x = sp.Matrix([[1, 0, 0, a], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    rot_x = sp.Matrix([[1, 0, 0, 0], [0, c(alpha), -s(alpha), 0], [0, s(alpha), c(alpha), 0], [0, 0, 0, 1]])
    eq5 = rot_z * trans_z * trans_x * rot_x  # Rehiara Eq. 4/5: the product the paper simplifies
    printed = rehiara_eq6_printed(theta, d, a, alpha)
    derived = dh_standard(theta, d, a, alpha)
    assert sp.simplify(eq5 - derived) == sp.zeros(4, 4)
    assert derived[1, 2] == -s(alpha) * c(theta)
    for _ in range(5):
        values = {theta: RNG.uniform(-3, 3), alpha: RNG.uniform(0.2, 1.3), d: 0.3, a: 0.4}
        P, D = numeric(printed, values), numeric(derived, values)
        assert abs(P[1, 2] - D[1, 2]) > 1e-3  # the print is wrong at a generic twist ...
        assert not np.allclose(P[:3, :3] @ P[:3, :3].T, np.eye(3), atol=1e-6)  # ... and not a rotation
        assert np.allclose(D[:3, :3] @ D[:3, :3].T, np.eye(3), atol=1e-12)
    # It does not touch the AdeptThree: every twist of Table 1 is 0 or pi, where sin(alpha) = 0.
    m = derivations.load("adept_three")
    for i, qi in enumerate(m.q):
        j = m.chain.joints[i]
        th, dd = (qi + j.offset, j.d) if j.type == "R" else (j.theta, qi + j.offset)
        assert sp.simplify(rehiara_eq6_printed(th, dd, j.a, j.alpha) - m.chain.link_transform(i, qi)) == sp.zeros(4, 4)


def test_E3_rehiara_eq40_eq42_tool_configuration_sign():
    """E3: Eq. 39 with the approach vector a = (0, 0, -1) of Eq. 13 gives w6 = -e^(theta4/pi); Eqs. 40, 42 print +."""
    m = derivations.load("adept_three")
    q1, q2, d3, q4 = m.q
    approach, position = m.fk[:3, 2], m.fk[:3, 3]
    assert approach == sp.Matrix([0, 0, -1])
    w = sp.Matrix.vstack(position, approach * sp.exp(q4 / sp.pi))  # Eq. 39: w = [p; a e^(q4/pi)]
    J = w.jacobian(sp.Matrix(m.q))  # Eq. 41
    l1, l2, d1, d4 = params(m, "l1", "l2", "d1", "d4")
    printed_w6 = sp.exp(q4 / sp.pi)  # Eq. 40, sixth entry
    printed_J64 = sp.exp(q4 / sp.pi) / sp.pi  # Eq. 42, entry (6, 4)
    for _ in range(5):
        values = {q1: RNG.uniform(-2, 2), q2: RNG.uniform(-2, 2), d3: RNG.uniform(0, 0.3), q4: RNG.uniform(-4, 4)}
        values.update(m.params)
        assert numeric(w[5], values) == pytest.approx(-numeric(printed_w6, values), rel=1e-14)
        assert numeric(J[5, 3], values) == pytest.approx(-numeric(printed_J64, values), rel=1e-14)
        assert abs(numeric(w[5] - printed_w6, values)) > 0.1
    # The other rows of Eq. 42 hold: the position rows are the task Jacobian's first three rows.
    assert J[:3, :] == m.task_jacobian[:3, :]
    assert J[3:5, :] == sp.zeros(2, 4)


def two_link_fk(l1, l2, t1, t2):
    return (l1 * math.cos(t1) + l2 * math.cos(t1 + t2), l1 * math.sin(t1) + l2 * math.sin(t1 + t2))


TWO_LINK_CASES = [(0.3, 0.8), (1.2, 1.9), (-0.7, 0.5), (2.6, 0.9), (-2.4, 2.2)]


@pytest.mark.parametrize("t1, t2", TWO_LINK_CASES)
def test_E4_rehiara_eq21_theta1_subtracts_beta_with_atan2(t1, t2):
    """E4: with theta2 from Eq. 18 (arccos, >= 0), Eq. 21 adds beta and uses arctan(y/x); theta1 = atan2(y, x) - beta."""
    l1, l2 = 0.559, 0.508  # Rehiara Eq. 14
    x, y = two_link_fk(l1, l2, t1, t2)
    r = math.hypot(x, y)
    theta2 = math.acos((x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2))  # Eq. 18
    assert theta2 == pytest.approx(t2, abs=1e-9)
    printed = math.asin(l2 * math.sin(theta2) / r) + math.atan(y / x)  # Eq. 21 as printed
    derived = math.atan2(y, x) - math.atan2(l2 * math.sin(theta2), l1 + l2 * math.cos(theta2))
    assert np.hypot(*np.subtract(two_link_fk(l1, l2, printed, theta2), (x, y))) > 0.4  # metres off
    assert np.hypot(*np.subtract(two_link_fk(l1, l2, derived, theta2), (x, y))) < 1e-12


@pytest.mark.parametrize("t1, t2", [(2.5, 0.7), (-2.2, 1.1), (1.9, 2.0)])
def test_E5_rehiara_eq34_arcsin_loses_the_quadrant(t1, t2):
    """E5: Eq. 34 gives sin(theta1) right but arcsin returns |theta1| <= pi/2; atan2(s1, c1) gives theta1."""
    l1, l2 = 0.559, 0.508
    x, y = two_link_fk(l1, l2, t1, t2)
    c2 = (x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2)  # Eq. 27
    s2 = math.sqrt(1 - c2 * c2)
    s1 = (y * (l1 + l2 * c2) - x * l2 * s2) / (x * x + y * y)  # Eq. 34, the argument of arcsin
    assert s1 == pytest.approx(math.sin(t1), abs=1e-12)  # the algebra of Eqs. 29-33 is right
    printed = math.asin(s1)
    c1 = (x * (l1 + l2 * c2) + y * l2 * s2) / (x * x + y * y)  # the same elimination for cos(theta1)
    derived = math.atan2(s1, c1)
    assert abs(printed - t1) > 0.1
    assert derived == pytest.approx(t1, abs=1e-12)


def test_rehiara_eqs29_to_33_hold():
    """Checked, not an erratum: Eq. 30 substitutes Eq. 29's c1 into y = c1 (l2 s2) + l1 s1 + l2 s1 c2."""
    l1, l2, t1, t2 = sp.symbols("l1 l2 theta1 theta2", positive=True)
    x = l1 * c(t1) + l2 * c(t1 + t2)  # Eq. 22
    y = l1 * s(t1) + l2 * s(t1 + t2)
    s1, c1, s2, c2 = s(t1), c(t1), s(t2), c(t2)
    eq29 = (x + l2 * s1 * s2) / (l1 + l2 * c2)
    eq30 = eq29 * (l2 * s2) + l1 * s1 + l2 * s1 * c2
    eq32 = (x * l2 * s2 + s1 * (l1**2 + l2**2 + 2 * l1 * l2 * c2)) / (l1 + l2 * c2)
    eq33 = (x * l2 * s2 + s1 * (x**2 + y**2)) / (l1 + l2 * c2)
    for _ in range(5):
        values = {l1: 0.559, l2: 0.508, t1: RNG.uniform(-3, 3), t2: RNG.uniform(-3, 3)}
        Y = numeric(y, values)
        assert numeric(eq29, values) == pytest.approx(numeric(c1, values), abs=1e-12)
        for printed in (eq30, eq32, eq33):
            assert numeric(printed, values) == pytest.approx(Y, abs=1e-12)


# --------------------------------------------------------------------------- velocity slides


def test_E6_slides_ivm_step_has_a_spurious_inverse():
    """E6: the slides write (-1/det) [-d b; c -a]^(-1); the adjugate step needs no inverse: (-1/det) [-d b; c -a]."""
    m = derivations.load("planar_2r")
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    J = m.task_jacobian
    M = sp.Matrix([[-l2 * c(q1 + q2), -l2 * s(q1 + q2)],
                   [l1 * c(q1) + l2 * c(q1 + q2), l1 * s(q1) + l2 * s(q1 + q2)]])  # the printed [-d b; c -a]
    factor = -1 / (l1 * l2 * s(q2))
    for _ in range(5):
        values = {q1: RNG.uniform(-3, 3), q2: RNG.uniform(0.2, 2.9), **m.params}
        inverse = np.linalg.inv(numeric(J, values))
        printed = numeric(factor, values) * np.linalg.inv(numeric(M, values))
        derived = numeric(factor * M, values)
        assert not np.allclose(printed, inverse, atol=1e-3)
        assert np.allclose(derived, inverse, rtol=1e-12, atol=1e-12)
    # The slides' final closed form is right (it uses the step without the inverse).
    xd, yd = sp.symbols("xdot ydot")
    theta1_rate = (l2 * c(q1 + q2) * xd + l2 * s(q1 + q2) * yd) / (l1 * l2 * s(q2))
    theta2_rate = -((l1 * c(q1) + l2 * c(q1 + q2)) * xd + (l1 * s(q1) + l2 * s(q1 + q2)) * yd) / (l1 * l2 * s(q2))
    assert sp.simplify(J.inv() * sp.Matrix([xd, yd]) - sp.Matrix([theta1_rate, theta2_rate])) == sp.zeros(2, 1)


def test_E7_slides_dvm_jacobian_lacks_a_row():
    """E7: the DVM slide prints J as 5 x 2; [v; w] needs 6 rows (the 2-link example slide has them)."""
    m = derivations.load("planar_2r")
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    printed = sp.Matrix([[-l1 * s(q1) - l2 * s(q1 + q2), -l2 * s(q1 + q2)],
                         [l1 * c(q1) + l2 * c(q1 + q2), l2 * c(q1 + q2)],
                         [0, 0], [0, 0], [1, 1]])
    assert printed.shape != m.jacobian.shape == (6, 2)
    assert m.jacobian.extract([0, 1, 2, 4, 5], [0, 1]) == printed  # one zero row of J_w is missing


# --------------------------------------------------------------------------- Sotirov (AVR 3000)


def test_E8_sotirov_eq7_velocity_drops_half_on_the_end_effector_terms():
    """E8: differentiating Eq. 7 gives J12 = -a s12 + e/2 sin(q1 + q2/2); the print drops the 1/2 (J22 too)."""
    a, e, q1, q2 = sp.symbols("a e q1 q2", real=True)
    half = sp.Rational(1, 2)
    x = a * (c(q1) + c(q1 + q2)) - e * c(q1 + half * q2)  # Sotirov Eq. 7
    y = a * (s(q1) + s(q1 + q2)) - e * s(q1 + half * q2)
    derived = sp.Matrix([x, y]).jacobian([q1, q2])
    printed = sp.Matrix([
        [-a * (s(q1) + s(q1 + q2)) + e * s(q1 + half * q2), -a * s(q1 + q2) + e * s(q1 + half * q2)],
        [a * (c(q1) + c(q1 + q2)) - e * c(q1 + half * q2), a * c(q1 + q2) - e * c(q1 + half * q2)]])
    difference = (derived - printed).applyfunc(sp.simplify)
    assert difference[:, 0] == sp.zeros(2, 1)  # the q1 column holds
    assert sp.simplify(difference[0, 1] + half * e * s(q1 + half * q2)) == 0
    assert sp.simplify(difference[1, 1] - half * e * c(q1 + half * q2)) == 0
    # Finite differences of Eq. 7 at a = 10.5 in and an end effector e = 8 in side with the derivative.
    values = {a: 10.5, e: 8.0, q1: 0.4, q2: 2.1}
    step = 1e-6
    fd = (numeric(x, {**values, q2: 2.1 + step}) - numeric(x, {**values, q2: 2.1 - step})) / (2 * step)
    assert fd == pytest.approx(numeric(derived[0, 1], values), rel=1e-8)
    assert abs(fd - numeric(printed[0, 1], values)) > 1.0


def test_E9_sotirov_gear_r_is_negative():
    """E9: GearR = 0.5 J22 / (-J11 - 0.5 J21) = -0.47935881 with the paper's J values; it prints +0.47935881."""
    J11, J21, J22 = -4.0175691732e-5, 2.6036376953e-5, -2.6036376953e-5  # Sotirov section 2.1.1
    gear_r = 0.5 * J22 / (-J11 - 0.5 * J21)
    assert gear_r == pytest.approx(-0.47935881, abs=1e-8)
    assert 0.5 * -1.1634e-5 / (1.795196e-5 - 0.5 * 1.1634e-5) == pytest.approx(-0.47935881, abs=1e-4)  # its own numbers

    def t_rate(theta1_rate, theta2_rate):  # Sotirov Eq. 14
        return (-J11 - 0.5 * J21) * theta1_rate - 0.5 * J22 * theta2_rate

    assert t_rate(-0.47935881, 1.0) == pytest.approx(0.0, abs=1e-13)  # derived ratio: pure R motion
    assert abs(t_rate(+0.47935881, 1.0)) > 1e-5  # printed ratio turns T as well
    # The Matlab script's R-only move [0.4794 vT, -vR] has the derived (negative) ratio.
    assert -0.479358811234781 == pytest.approx(gear_r, abs=1e-10)
    # GearT = -J22 / J21 = 1 holds.
    assert -J22 / J21 == pytest.approx(1.0, abs=1e-15)


def test_E10_sotirov_matlab_cartesian_jacobian_omits_the_link_length():
    """E10: the Matlab JJC is Eq. 7's Jacobian divided by a (and with e = 0); the velocities it gives are a times too small."""
    a, q1, q2 = 10.5, 0.3, 2.0  # ArmLength = 21.0 / 2.0 inches
    jjc = np.array([[-math.sin(q1) - math.sin(q1 + q2), -math.sin(q1 + q2)],
                    [math.cos(q1) + math.cos(q1 + q2), math.cos(q1 + q2)]])  # as printed in the script

    def xy(t1, t2):  # Sotirov Eq. 7 with e = 0, the script's own x, y
        return np.array([a * (math.cos(t1) + math.cos(t1 + t2)), a * (math.sin(t1) + math.sin(t1 + t2))])

    step = 1e-6
    fd = np.column_stack([(xy(q1 + step, q2) - xy(q1 - step, q2)) / (2 * step),
                          (xy(q1, q2 + step) - xy(q1, q2 - step)) / (2 * step)])
    assert not np.allclose(jjc, fd, rtol=1e-3)
    assert np.allclose(a * jjc, fd, rtol=1e-8)


# --------------------------------------------------------------------------- Predescu and Stroe (SCORBOT)


def scorbot_angles(x, y, z, elbow):
    """Predescu and Stroe Eqs. 3.1-3.9 with theta3 = elbow * acos(...) and theta2 = beta - alpha."""
    a1, a2, a3, d1, d5 = 0.050, 0.300, 0.250, 0.385, 0.212
    horizontal = math.hypot(x, y) - a1 - d5  # O2B
    vertical = z - d1  # O4B
    theta3 = elbow * math.acos((horizontal**2 + vertical**2 - a2**2 - a3**2) / (2 * a2 * a3))  # Eq. 3.5
    alpha = math.atan2(a3 * math.sin(theta3), a2 + a3 * math.cos(theta3))  # Eq. 3.6
    beta = math.atan2(vertical, horizontal)  # Eq. 3.7
    theta2 = beta - alpha  # Eq. 3.8
    return math.atan2(y, x), theta2, theta3, -theta2 - theta3  # Eqs. 3.1, 3.9, 3.11


def test_E11_predescu_eq41_starts_on_the_other_elbow_branch():
    """E11: Eqs. 3.5 + 3.8 give theta2(M) = -33.23 deg; Eq. 4.1's 13.4685 deg is theta3 = -acos, theta2 = beta + alpha."""
    m = derivations.load("scorbot_er7")
    tool_point = m.fk[:3, 3].subs(m.params)
    M, N = (0.750, 0.0, 0.300), (0.300, 0.0, 0.750)  # section 4
    printed_start = math.radians(13.4685)  # Eq. 4.1 at t = 0
    printed_end = math.radians(13.4685 + 3.3946 * 10**2 - 0.2263 * 10**3)  # Eq. 4.1 at t = 10 s
    as_printed = scorbot_angles(*M, elbow=+1)
    other = scorbot_angles(*M, elbow=-1)
    assert math.degrees(as_printed[1]) == pytest.approx(-33.2298, abs=1e-3)
    assert other[1] == pytest.approx(printed_start, abs=1e-6)  # 13.4685 deg to the paper's 4 decimals
    assert abs(as_printed[1] - printed_start) > 0.5
    for target in (M, N):  # both branches reach M and N on the DH model, gripper horizontal
        for elbow in (+1, -1):
            angles = scorbot_angles(*target, elbow=elbow)
            point = numeric(tool_point, dict(zip(m.q, (*angles, 0.0)))).ravel()
            assert np.allclose(point, target, atol=1e-12)
    end = scorbot_angles(*N, elbow=-1)
    assert end[1] == pytest.approx(printed_end, abs=math.radians(0.02))
    # Eq. 4.1 is the rest-to-rest cubic between these ends: 3 D / T^2 and 2 D / T^3 with T = 10 s.
    delta = math.degrees(end[1] - other[1])
    assert 3 * delta / 100 == pytest.approx(3.3946, abs=5e-4)
    assert 2 * delta / 1000 == pytest.approx(0.2263, abs=5e-5)
    # The sinusoidal law (Eq. 4.8) spans the same ends: theta_i = 0.235 rad, theta_i + A0 = 2.210 rad.
    assert 0.235 == pytest.approx(other[1], abs=5e-4)
    assert 0.235 + 1.975 == pytest.approx(end[1], abs=5e-4)


# --------------------------------------------------------------------------- Kumar (mobility)


def grubler_spatial(n, connectivities):  # Kumar Eq. 2
    return 6 * (n - len(connectivities)) + sum(connectivities)


def grubler_planar(n, connectivities):  # Kumar Eq. 3
    return 3 * (n - len(connectivities)) + sum(connectivities)


def test_E12_kumar_mobility_examples_cite_the_wrong_equation():
    """E12: the slider crank (M = 1) needs the planar Eq. 3, not Eq. 2; the Stewart platform (M = 6) Eq. 2, not Eq. 3."""
    slider_crank = (3, [1, 1, 1, 1])  # Example 2: n = 3, g = 4
    assert grubler_spatial(*slider_crank) == -2  # "we use Equation (2)": a negative mobility
    assert grubler_planar(*slider_crank) == 1  # the stated M = 1
    stewart = (19, [1] * 12 + [1] * 6 + [3] * 6)  # n = 6 x 3 + 1, g = 24, sum f = 36
    assert grubler_planar(*stewart) == 3 * (19 - 24) + 36 == 21  # "According to Equation (3)"
    assert grubler_spatial(*stewart) == 6  # the printed arithmetic 6(19 - 24) + 36 is Eq. 2
    assert grubler_planar(7, [1] * 9) == 3  # Example 3 cites Eq. 3 rightly: M = 3


# --------------------------------------------------------------------------- the documents agree

REPO = __import__("pathlib").Path(__file__).resolve().parents[2]


def readme_errata() -> dict[str, list[tuple[str, str]]]:
    """{erratum id: [(test file, test name), ...]} from the README's "Errata found in the papers" table."""
    text = (REPO / "README.md").read_text()
    table = text.split("## Errata found in the papers", 1)[1].split("\n## ", 1)[0]
    errata = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 5 or cells[0] in ("id", "") or set(cells[0]) <= set("-"):
            continue
        tests, current = [], None
        for ref in __import__("re").findall(r"`((?:tests/[\w./]+)?::\w+)`", cells[-1]):
            path, name = ref.split("::")
            current = path or current
            tests.append((current, name))
        errata[cells[0]] = tests
    return errata


def report_errata_ids() -> dict[str, set[str]]:
    """{chapter or table: ids of its errata rows}: the chapters' errata environments and the introduction's table."""
    import re
    out = {}
    for chapter in sorted((REPO / "report" / "chapters").glob("*.tex")):
        text = chapter.read_text()
        blocks = re.findall(r"\\begin\{(errata|tabularx)\}(.*?)\\end\{\1\}", text, flags=re.S)
        ids = {m for _, block in blocks for m in re.findall(r"^([A-Z]+\d+) &", block, flags=re.M)}
        if ids:
            out[chapter.stem] = ids
    return out


def test_every_readme_erratum_has_a_test_of_its_name_and_a_report_row():
    """Issue 18, item 8: every erratum id of the README is the prefix of each test the README cites for it
    (``test_<id>_...``, which exists in that file), and has a row in its chapter's errata table and in the
    introduction's list; the report holds no erratum the README lacks."""
    import ast
    errata = readme_errata()
    assert {"E1", "E12", "AVR3", "AVR4", "AVR6"} <= set(errata) and "IK2" not in errata
    for erratum, tests in errata.items():
        assert tests, f"README erratum {erratum} cites no test"
        for path, name in tests:
            assert name.startswith(f"test_{erratum}_"), f"{erratum}: the README cites {name}"
            tree = ast.parse((REPO / path).read_text())
            defined = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
            assert name in defined, f"{erratum}: {path} has no test {name}"
    report = report_errata_ids()
    introduction = report.pop("introduction")
    in_chapters = set().union(*report.values())
    assert set(errata) == introduction, "the introduction's errata list and the README differ"
    assert set(errata) == in_chapters, "the chapters' errata tables and the README differ"

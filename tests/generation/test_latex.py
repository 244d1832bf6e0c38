"""The LaTeX backend: notation, line breaking, sections, citations, the CLI, and the
determinants and rate maps it prints (checked against the papers and numerically)."""
import copy
import math
import dataclasses
import re

import numpy as np
import pytest
import sympy as sp

import derivations
from codegen import cli, generate
from codegen.backends import latex_backend
from codegen.backends.latex_backend import (CITATIONS, KinematicsLatexPrinter, MathLayout, escape_text, latex_for,
                                            math_width, robot_sections)
from derivations.model import IKBranch
from derivations.singular import inverse_rate_map, jacobian_determinant
from derivations.robots._common import parameters as params
from conftest import ROBOT_NAMES

c, s = sp.cos, sp.sin


def printer_for(model):
    return KinematicsLatexPrinter(model.q, model.joint_types, tuple(model.params))


# --------------------------------------------------------------------------- notation

def test_joint_variables_print_by_joint_type(models):
    rp = printer_for(models["planar_rp"])
    q1, q2 = models["planar_rp"].q
    assert rp.doprint(q1) == r"\theta_{1}" and rp.doprint(q2) == "d_{2}"  # Kumar Fig. 11: theta1, d2
    adept = models["adept_three"]
    p = printer_for(adept)
    assert [p.doprint(q) for q in adept.q] == [r"\theta_{1}", r"\theta_{2}", "d_{3}", r"\theta_{4}"]
    d1, d4 = params(adept, "d1", "d4")
    assert p.doprint(d1 - d4 - adept.q[2]) == "d_{1} - d_{4} - d_{3}"  # Rehiara Eq. 14: -d4 - d3 + d1


def test_trig_abbreviations_for_plain_sums_only(models):
    m = models["adept_three"]
    q1, q2, d3, q4 = m.q
    p = printer_for(m)
    assert p.doprint(c(q1)) == "c_{1}"
    assert p.doprint(s(q1 + q2)) == "s_{12}"
    assert p.doprint(c(q1) ** 2) == "c_{1}^{2}"
    assert p.doprint(c(q1 + q2 - q4)) == r"\cos(\theta_{1} + \theta_{2} - \theta_{4})"
    assert p.doprint(s(q2 / 2)) == r"\sin(\frac{\theta_{2}}{2})"
    assert p.doprint(c(d3)) == r"\cos(d_{3})"  # a prismatic variable is no angle
    assert p.doprint(sp.atan2(q1, q2)) == r"\operatorname{atan2}\left(\theta_{1},\, \theta_{2}\right)"


def test_clashing_names_fall_back_to_plain_symbols():
    q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
    d3, c1 = sp.symbols("d3 c1", real=True)
    p = KinematicsLatexPrinter((q1, q2, q3), ("R", "R", "P"), (d3,))
    assert p.doprint(q3) == "q_{3}"  # a parameter d3 beside a prismatic joint 3
    assert p.doprint(q1) == r"\theta_{1}"
    p = KinematicsLatexPrinter((q1, q2), ("R", "R"), (c1,))
    assert p.doprint(c(q1)) == r"\cos(\theta_{1})"  # a parameter c1 would read like the abbreviation
    assert p.legend() == ""


def test_text_is_escaped_for_pdflatex():
    assert escape_text("d4 = 5% of l_1 & more {x}") == r"d4 = 5\% of l\_1 \& more \{x\}"
    assert escape_text("θ ± 150°") == r"$\theta$ $\pm$ 150$^\circ$"
    assert escape_text("naïve") == "na?ve"


# --------------------------------------------------------------------------- layout

def unbroken(lines):
    return re.sub(r"\s+", "", "".join(lines).replace("{}", "").replace(r"\bigl(", r"\left(").replace(r"\bigr)", r"\right)"))


@pytest.mark.parametrize("width", [30.0, 45.0, 66.0])
def test_long_sums_break_into_lines_that_fit_and_lose_nothing(models, width):
    m = models["puma560"]
    layout = MathLayout(printer_for(m), width)
    for expr in (m.fk[0, 0], m.fk[1, 1], m.jacobian[0, 0], m.fk[0, 3]):
        lines = layout.lines(expr, width - 5)
        assert all(math_width(line) <= width for line in lines[1:]), lines
        assert math_width(lines[0]) <= width - 5
        assert unbroken(lines) == re.sub(r"\s+", "", layout.tex(expr))


def test_a_product_with_a_long_sum_is_opened_across_lines(models):
    m = models["scorbot_er7"]
    layout = MathLayout(printer_for(m), 24.0)
    expr = m.fk[0, 3]  # (a1 + a2 c2 + a3 c23 + d5 c234) c1
    lines = layout.lines(expr, 18.0)
    assert len(lines) > 1
    assert lines[0].startswith(r"c_{1} \bigl(") and lines[-1].endswith(r"\bigr)")
    assert all(math_width(line) <= 24.0 for line in lines)
    assert unbroken(lines) == re.sub(r"\s+", "", r"c_{1}\left(a_{1} + a_{2} c_{2} + a_{3} c_{23} + d_{5} c_{234}\right)")


def test_line_breaking_prints_each_subexpression_once(models, monkeypatch):
    """Breaking a nested product over lines prints a sum, its terms, the factors of a wide term
    and so on down; each distinct subexpression goes through SymPy's printer once (a UR5 whose
    twists were written 1.5708 spent 35 s of its LaTeX reprinting them), and the text is the
    same as printed fresh."""
    m = models["puma560"]
    expr = sp.expand(m.fk[0, 3] * m.fk[1, 3] + m.jacobian[0, 1] * m.fk[2, 3])
    fresh = [MathLayout(printer_for(m), 40.0).lines(expr, 35.0)]
    calls = []
    original = latex_backend.LatexPrinter._print_Add
    monkeypatch.setattr(latex_backend.LatexPrinter, "_print_Add",
                        lambda self, e, *a, **k: calls.append(e) or original(self, e, *a, **k))
    layout = MathLayout(printer_for(m), 40.0)
    again = [layout.lines(expr, 35.0), layout.lines(expr, 35.0)]
    assert again == fresh * 2
    assert calls and len(calls) == len(set(calls)), f"{len(calls)} prints of {len(set(calls))} sums"


def test_math_width_grows_with_content():
    assert math_width("x") < math_width("x + y") < math_width(r"x + y + \theta_{1}")
    assert math_width(r"\frac{a + b}{c}") == pytest.approx(math_width("a + b") + 0.4)
    assert math_width(r"\left(x\right)") < math_width("x") + 2


def test_wide_matrices_print_entry_by_entry(models):
    sections = {sec.key: sec.body for sec in robot_sections(models["puma560"])}
    assert r"T_{11} &= " in sections["fk"] and r"\begin{bmatrix}" not in sections["fk"]
    assert "the last row is $(0\\ 0\\ 0\\ 1)$" in sections["fk"]
    assert "J_{14} = J_{15} = J_{16}" in sections["jacobian"]  # the zero entries, named once
    narrow = {sec.key: sec.body for sec in robot_sections(models["planar_2r"])}
    assert r"\begin{bmatrix}" in narrow["fk"]


# --------------------------------------------------------------------------- sections

def with_ik(model):
    m = copy.copy(model)
    q1, q2 = m.q
    x, y = m.task_symbols
    l1, l2 = params(m, "l1", "l2")
    cos2 = (x**2 + y**2 - l1**2 - l2**2) / (2 * l1 * l2)
    theta2 = sp.acos(cos2)
    theta1 = sp.atan2(y, x) - sp.atan2(l2 * sp.sin(theta2), l1 + l2 * sp.cos(theta2))
    m.ik = [IKBranch("elbow_up", (theta1, theta2), sp.And(cos2 >= -1, cos2 <= 1), "theta2 >= 0 (Rehiara Eq. 18)"),
            IKBranch("elbow_down", (sp.atan2(y, x) + sp.atan2(l2 * sp.sin(theta2), l1 + l2 * sp.cos(theta2)),
                                    -theta2))]
    return m


def test_ik_branches_print_with_their_conditions(models):
    m = with_ik(models["planar_2r"])
    sections = {sec.key: sec for sec in robot_sections(m)}
    body = sections["ik"].body
    assert r"\paragraph{Branch \texttt{elbow\_up}} theta2 \textgreater{}= 0 (Rehiara Eq. 18)" in body
    assert r"\paragraph{Branch \texttt{elbow\_down}}" in body
    assert r"\theta_{1} &= " in body and r"\theta_{2} &= \arccos" in body
    assert r"\operatorname{atan2}" in body
    assert body.count(r"\tag{Rehiara Eqs.~18, 21, 27, 34}") == 2
    assert "It exists when" in body and r"\geq -1" in body  # the elbow_up condition; elbow_down has none
    assert body.count("It exists when") == 1
    assert latex_for(m, ["ik"]).startswith("% Inverse kinematics")


@dataclasses.dataclass
class SingularFamily:  # the shape a later module may give model.singularities
    name: str
    condition: sp.Basic
    doc: str = ""


def test_whatever_else_a_model_carries_is_printed(models):
    m = copy.copy(models["planar_2r"])
    q1, q2 = m.q
    # (model.singularities itself is a property of the rate module; a plain attribute stands in)
    m.singular_families = [SingularFamily("elbow_stretched", sp.Eq(s(q2), 0), "theta2 = 0 or pi (slides)")]
    m.hessian_x = sp.Matrix([[c(q1), 0], [0, s(q1 + q2)]])
    m.comment = "not symbolic: no section"
    sections = {sec.key: sec for sec in robot_sections(m)}
    assert r"\paragraph{elbow\_stretched}" in sections["singular_families"].body
    assert "s_{2} = 0" in sections["singular_families"].body
    assert "c_{1}" in sections["hessian_x"].body and "s_{12}" in sections["hessian_x"].body
    assert "comment" not in sections
    assert latex_for(m, ["singular_families"]).startswith("% Singular families")


def test_citation_keys_name_real_sections():
    for robot, table in CITATIONS.items():
        assert robot in derivations.ROBOTS
        n = derivations.load(robot).n
        valid = set(latex_backend.SECTION_KEYS) | {"singular", "inverse_rates"} | {f"link{i}" for i in range(1, n + 1)}
        for key in table:
            assert key in valid or key.startswith("ik:"), (robot, key)


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_fragments_carry_the_papers_equation_numbers(name):
    text = (generate.GENERATED / name / f"{name}.tex").read_text()
    assert "Do not edit by hand" in text and "\\kinegenrobot{" in text
    model = derivations.load(name)
    for key, cite in CITATIONS.get(name, {}).items():
        if key.startswith("ik") and not model.ik:
            continue  # printed once the model carries IK branches
        assert cite in text, (name, key)


def test_the_papers_landmark_equations_are_tagged():
    frag = {n: (generate.GENERATED / n / f"{n}.tex").read_text() for n in ROBOT_NAMES}
    assert r"\det J_x &= l_{1} l_{2} s_{2} \tag{Kumar Eq.~13}" in frag["planar_3r"]
    assert r"\tag{Kumar Eq.~11}" in frag["planar_3r"]
    assert r"\tag{Rehiara Eq.~13, corrected (E1)}" in frag["adept_three"]
    for eq in (9, 10, 11, 12):
        assert rf"\tag{{Rehiara Eq.~{eq}}}" in frag["adept_three"]


# --------------------------------------------------------------------------- what it prints is right

def test_determinants_reproduce_the_papers(models):
    m = models["planar_3r"]
    l1, l2 = params(m, "l1", "l2")
    det = jacobian_determinant(m)
    assert det.which == "task_jacobian"
    assert sp.simplify(det.value - l1 * l2 * s(m.q[1])) == 0  # Kumar Eq. 13
    assert det.singular == ((s(m.q[1]), (sp.Eq(m.q[1], 0), sp.Eq(m.q[1], sp.pi))),)  # "0 or 180 degrees"
    m2 = models["planar_2r"]
    assert sp.simplify(jacobian_determinant(m2).value - l1 * l2 * s(m2.q[1])) == 0  # slides: |J| = l1 l2 s2
    rp = jacobian_determinant(models["planar_rp"])
    assert rp.value == -models["planar_rp"].q[1]  # det [[-d2 s1, c1], [d2 c1, s1]] = -d2
    assert rp.singular[0][1] == (sp.Eq(models["planar_rp"].q[1], 0),)
    assert jacobian_determinant(models["planar_pp"]).singular == ()
    assert jacobian_determinant(models["scorbot_er7"]) is None  # 3 x 5: no determinant


@pytest.mark.parametrize("name", ["puma560", "adept_three", "planar_3r", "planar_rp"])
def test_factored_determinant_matches_numpy(models, name):
    m = models[name]
    det = jacobian_determinant(m)
    J = m.task_jacobian if det.which == "task_jacobian" else m.jacobian
    rng = np.random.default_rng(13)
    for _ in range(5):
        point = {qi: float(v) for qi, v in zip(m.q, rng.uniform(-2.5, 2.5, m.n))}
        point.update(m.params)
        expected = np.linalg.det(np.array(J.evalf(subs=point), dtype=float))
        assert float(det.value.evalf(subs=point)) == pytest.approx(expected, rel=1e-10, abs=1e-14)
        for factor, zeros in det.singular:
            for zero in zeros:  # each printed singular configuration zeroes its factor
                assert abs(float(factor.subs(zero.lhs, zero.rhs).evalf(subs=point))) < 1e-12


def test_puma_singular_set_is_shoulder_elbow_wrist(models):
    m = models["puma560"]
    a2, a3, d4 = params(m, "a2", "a3", "d4")
    q1, q2, q3, q4, q5, q6 = m.q
    det = jacobian_determinant(m)
    # a2 (a3 s3 + d4 c3)(a2 c2 + a3 c23 - d4 s23) s5: elbow, wrist centre on the shoulder axis, wrist
    expected = a2 * (a3 * s(q3) + d4 * c(q3)) * (a2 * c(q2) + a3 * c(q2 + q3) - d4 * s(q2 + q3)) * s(q5)
    assert sp.expand(sp.expand_trig(det.value - expected)) == 0
    assert [zeros for _, zeros in det.singular][-1] == (sp.Eq(q5, 0), sp.Eq(q5, sp.pi))


@pytest.mark.parametrize("name", ["planar_2r", "planar_3r", "planar_rp", "planar_pp", "adept_three"])
def test_inverse_rate_maps_invert_the_task_jacobian(models, name):
    m = models[name]
    adjugate, det = inverse_rate_map(m)
    rng = np.random.default_rng(7)
    for _ in range(5):
        point = {qi: float(v) for qi, v in zip(m.q, rng.uniform(0.2, 2.8, m.n))}
        point.update(m.params)
        J = np.array(m.task_jacobian.evalf(subs=point), dtype=float)
        inverse = np.array(adjugate.evalf(subs=point), dtype=float) / float(det.evalf(subs=point))
        assert np.allclose(inverse @ J, np.eye(m.n), atol=1e-12)
    assert inverse_rate_map(models["puma560"]) is None  # 12 x 6 task: no inverse printed


def test_slides_ivm_is_what_the_fragment_prints(models):
    m = models["planar_2r"]
    body = latex_for(m, ["rates"])
    # slides: theta1' = (l2 c12 X' + l2 s12 Y') / (l1 l2 s2), printed with l2 cancelled
    assert r"\dot{\theta}_{1} &= \frac{c_{12} \dot{x} + s_{12} \dot{y}}{l_{1} s_{2}}" in body
    assert r"\dot{x} &= - l_{1} s_{1} \dot{\theta}_{1} - l_{2} s_{12} \left(\dot{\theta}_{1} + \dot{\theta}_{2}\right)" in body


# --------------------------------------------------------------------------- command line

def test_cli_prints_one_section(capsys):
    assert cli.main(["latex", "planar_3r", "--what", "det"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("% Singularities")
    assert r"\det J_x &= l_{1} l_{2} s_{2} \tag{Kumar Eq.~13}" in out
    assert "Task coordinates" not in out
    assert cli.main(["latex", "adept_three", "--what", "fk,position"]) == 0
    out = capsys.readouterr().out
    assert "Rehiara Eq.~13" in out and "Rehiara Eq.~14" in out and "Link transforms" not in out


def test_cli_rejects_unknown_sections_and_robots(capsys):
    assert cli.main(["latex", "planar_3r", "--what", "torque"]) == 2
    err = capsys.readouterr().err
    assert "no section 'torque'" in err and "expected one of" in err and "jacobian" in err
    assert cli.main(["latex", "no_such_robot"]) == 2
    assert "unknown robot 'no_such_robot'" in capsys.readouterr().err


def test_cli_prints_a_users_description(tmp_path, capsys):
    path = tmp_path / "cyl.toml"
    path.write_text('name = "cyl"\ntask = ["x", "y", "z"]\n[params]\nd1 = 0.5\n'
                    '[[joint]]\ntype = "R"\nd = "d1"\n[[joint]]\ntype = "P"\nalpha = "-pi/2"\n'
                    '[[joint]]\ntype = "P"\n')
    assert cli.main(["latex", str(path), "--what", "dh"]) == 0
    out = capsys.readouterr().out
    assert r"$\theta_{1}$ & $d_{1}$" in out and "$d_{2}$" in out and "$d_{3}$" in out


# --------------------------------------------------------------------------- issue 18: notation and order

def multi_space_robots():
    return [n for n in ROBOT_NAMES if len(getattr(derivations.load(n), "spaces", {})) > 1]


def printed_across_spaces(model, printer) -> dict[str, set[str]]:
    """{printed text: the spaces whose symbols print as it} (the joints and their rates in the joint space)."""
    spaces = latex_backend.space_symbols(model)
    printed: dict[str, set[str]] = {}
    for space, symbols in spaces.items():
        for symbol in symbols:
            printed.setdefault(printer.doprint(symbol), set()).add(space)
    joint_space = next(s for s, symbols in spaces.items() if set(model.q) <= set(symbols))
    for qi in model.q:
        printed.setdefault(printer.doprint(qi), set()).add(joint_space)
        printed.setdefault(printer.doprint(latex_backend.rate_symbol(qi)), set()).add(joint_space)
    return printed


def test_the_space_check_catches_the_old_avr3000_notation():
    """Printed as before issue 18 (joints as theta_i, blind to the motor space), q1 and the motor angle theta1
    print alike, and the check below says so."""
    model = derivations.load("avr3000")
    printed = printed_across_spaces(model, printer_for(model))
    assert printed[r"\theta_{1}"] == {"motor", "joint"}


@pytest.mark.parametrize("name", multi_space_robots())
def test_no_two_spaces_print_a_symbol_alike(name):
    """Issue 18, item 1: in a robot with several coordinate spaces (the AVR 3000: motor, joint, tool,
    Cartesian), every symbol of every space, at position, velocity and acceleration level, prints
    differently from every symbol of another space, in the fragment's own printer; the joints (and their
    rates, as the rate maps print them) belong to the joint space, and the tool pose's name is no
    coordinate."""
    model = derivations.load(name)
    printed = printed_across_spaces(model, latex_backend.printer_for(model))
    shared = {text: owners for text, owners in printed.items() if len(owners) > 1}
    assert not shared, f"{name}: printed alike across spaces: {shared}"
    assert latex_backend.pose_name(model) not in printed


def test_the_avr3000_fragment_writes_sotirov_eq4_in_joint_symbols():
    """Sotirov Eq. 4, T = pi/2 - q1 - q2/2, R = 2a cos(q2/2), Z = q3, as the fragment prints it: joints q_i,
    the motors theta_i only where motor coordinates are meant (Eq. 1: q1 = J11 theta1)."""
    text = (generate.GENERATED / "avr3000" / "avr3000.tex").read_text()
    assert r"T &= - q_{1} - \frac{q_{2}}{2} + \frac{\pi}{2}" in text
    assert r"R &= 2 a \cos(\frac{q_{2}}{2})" in text and r"Z &= q_{3}" in text
    assert r"{}^{0}H_{\mathrm{tip}} = " in text and "\nT = " not in text
    assert "Joint variables: $q_{1}$ (revolute), $q_{2}$ (revolute), $q_{3}$ (prismatic)" in text
    assert r"\dot{T} &= - \dot{q}_{1} - \frac{\dot{q}_{2}}{2}" in text
    assert r"J_{11} \theta_{1}" in text  # Eq. 1, motor -> joint
    ik = text.split(r"\kinegenpart{Inverse kinematics}")[1].split(r"\kinegenpart{")[0]
    assert r"\theta" not in ik  # Eq. 8 is in tool and joint coordinates only
    assert r"$-\pi < q_i \le \pi$" in text


def ik_rows(body: str) -> list[tuple[str, str, str]]:
    """(lhs, rhs, tag) of each equation of an IK branch's align block (continuation lines joined)."""
    rows = []
    for line in body.split("\\\\\n"):
        line = line.strip()
        if "&=" in line:
            lhs, rhs = line.split("&=", 1)
            tag = re.search(r"\\tag\{([^}]*)\}", rhs)
            rows.append((lhs.strip(), re.sub(r"\\tag\{[^}]*\}", "", rhs), tag.group(1) if tag else ""))
        elif line.startswith(r"&\quad") and rows:
            lhs, rhs, tag = rows[-1]
            rows[-1] = (lhs, rhs + line, tag)
    return rows


@pytest.mark.parametrize("name", [n for n in ROBOT_NAMES if any(b.steps for b in derivations.load(n).ik)])
def test_ik_steps_print_in_their_order_each_defined_before_use(name):
    """Issue 18, item 2: the steps of a branch print in the order the paper gives them, one equation each,
    each left side defined before any right side uses it, with no common-subexpression temporaries."""
    model = derivations.load(name)
    printer = latex_backend.printer_for(model)
    body = {s.key: s.body for s in robot_sections(model)}["ik"]
    known = {printer.doprint(p) for p in model.params} | {printer.doprint(s) for s in model.task_symbols}
    for branch, block in zip(model.ik, body.split(r"\paragraph{Branch")[1:]):
        align = block.split(r"\begin{align*}")[1].split(r"\end{align*}")[0]
        rows = ik_rows(align)
        names = [printer.joint_latex.get(sym, printer.doprint(sym)) for sym, _ in branch.steps]
        assert [lhs for lhs, _, _ in rows] == names, branch.name
        defined = set()
        for lhs, rhs, _ in rows:
            later = set(names) - defined - {lhs}
            used = [n for n in later if re.search(re.escape(n) + r"(?![\w'{])", rhs)]
            assert not used, f"{name}.{branch.name}: {lhs} uses {used} before their definition"
            defined.add(lhs)
        if branch.step_cites:
            assert [tag for _, _, tag in rows] == list(branch.step_cites)
    assert r"\kappa" not in body


def test_kumar_3r_inverse_prints_eqs_d_to_j_in_order():
    """Kumar section 5.4: x', y' (d, e), gamma and theta1 (h), theta2 (i), theta3 (j), tagged so."""
    text = (generate.GENERATED / "planar_3r" / "planar_3r.tex").read_text()
    ik = text.split(r"\kinegenpart{Inverse kinematics}")[1]
    for branch in ik.split(r"\paragraph{Branch")[1:]:
        rows = ik_rows(branch.split(r"\begin{align*}")[1].split(r"\end{align*}")[0])
        assert [(lhs, tag) for lhs, _, tag in rows] == [
            ("x'", "Kumar Eq.~(d)"), ("y'", "Kumar Eq.~(e)"), (r"\gamma", "Kumar Eq.~(h)"),
            (r"\theta_{1}", "Kumar Eq.~(h)"), (r"\theta_{2}", "Kumar Eq.~(i)"), (r"\theta_{3}", "Kumar Eq.~(j)")]
        gamma, theta1 = rows[2][1], rows[3][1]
        assert r"\operatorname{atan2}\left(- \frac{y'}{\sqrt{x'^{2} + y'^{2}}},\, - \frac{x'}{\sqrt{x'^{2} + y'^{2}}}\right)" in gamma
        assert r"{2 l_{1} \sqrt{x'^{2} + y'^{2}}}" in theta1 and theta1.strip().startswith(r"\gamma")


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_code_names_stay_out_of_the_latex(name):
    """Issue 18, item 2: no helper of the generated code in print: no WrapAngle, no clamp of an arccos
    argument, no CSE temporary, no tolerance spelt out in digits; the wrap is stated once in words."""
    text = (generate.GENERATED / name / f"{name}.tex").read_text()
    assert "WrapAngle" not in text and "wrap_angle" not in text
    assert r"\min\left(1" not in text and r"\max\left(-1" not in text
    assert r"\kappa" not in text and "1000000000001" not in text
    if derivations.load(name).ik:
        assert r"taken in $(-\pi, \pi]$" in text


def test_the_wrap_prints_as_mathematics_inside_a_map():
    """Where the wrap sits inside a longer expression (the AVR 3000's reversed Cartesian inverse), it prints
    as theta + 2 pi floor((pi - theta) / (2 pi)), which the test evaluates against the wrap's definition."""
    from derivations.ik import WrapAngle
    model = derivations.load("avr3000")
    printer = latex_backend.printer_for(model)
    x_, y_ = sp.symbols("x y", real=True)
    text = printer.doprint(WrapAngle(sp.atan2(x_, y_) + sp.pi))
    assert "WrapAngle" not in text and r"\left\lfloor" in text
    for theta in np.linspace(-7, 7, 29):
        wrapped = float(WrapAngle.formula(sp.Float(theta)))
        assert -math.pi < wrapped <= math.pi and math.isclose(math.remainder(wrapped - theta, 2 * math.pi), 0,
                                                               abs_tol=1e-12)


def test_a_descriptions_cite_notes_are_text_not_tex(tmp_path):
    """A cite_* note lands in \\tag{...}: written by whoever wrote the description, it is escaped,
    so that \\input{/etc/passwd} prints as text and pulls in no file."""
    path = tmp_path / "hostile.toml"
    path.write_text('name = "hostile_2r"\n[params]\nl1 = 1\n[notes]\ncite_fk = "\\\\input{/etc/passwd} 100% & #1"\n'
                    '[[joint]]\ntype = "R"\na = "l1"\n[[joint]]\ntype = "R"\na = "l1"\n')
    model = derivations.load(path)
    assert model.notes["cite_fk"] == "\\input{/etc/passwd} 100% & #1"
    text = latex_backend.latex_for(model, ["fk"])
    assert "\\tag{\\textbackslash{}input\\{/etc/passwd\\} 100\\% \\& \\#1}" in text
    assert "\\input{" not in text


def test_an_ik_step_past_the_limit_is_named_not_typeset(monkeypatch):
    """IK steps longer than latex_backend.IK_STEP_TEX_LIMIT characters (the Romeo arm's 13 kB each)
    get one row saying how long they are and where they are computed; shorter ones are typeset.
    With the limit at 300 characters, the UR5's longer steps go and its short ones stay."""
    model = derivations.load(generate.REPO / "tests" / "data" / "arms" / "ur5.toml")
    full = latex_for(model, ["ik"])
    assert "characters of \\LaTeX" not in full
    monkeypatch.setattr(latex_backend, "IK_STEP_TEX_LIMIT", 300)
    short = latex_for(model, ["ik"])
    named = re.findall(r"\\text\{\(a closed form of ([\d,]+) characters of \\LaTeX: in the package's", short)
    assert named and all(int(n.replace(",", "")) > 300 for n in named)
    assert len(short) < len(full) and short.count(r"\paragraph{Branch") == full.count(r"\paragraph{Branch")

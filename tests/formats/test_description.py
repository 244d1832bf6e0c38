"""Robot descriptions: the parser accepts what it should and names what is wrong."""
import pytest
import sympy as sp

import derivations
from derivations.description import DescriptionError, parse_description
from derivations.expressions import ExpressionError, parse_expression

GOOD = """
name = "cylindrical_rpp"
task = ["x", "y", "z"]
[params]
d1 = 0.5
[[joint]]
type = "R"
d = "d1"
limits = ["deg(-170)", "deg(170)"]
[[joint]]
type = "P"
alpha = "-pi/2"
[[joint]]
type = "P"
theta = "pi/2"
alpha = "pi/2"
[tool]
xyz = [0, 0, 0.1]
"""


def test_a_good_description_parses_exactly():
    d = parse_description(GOOD, "robot.toml")
    assert d.name == "cylindrical_rpp"
    assert [j.type for j in d.joints] == ["R", "P", "P"]
    assert d.joints[1].alpha == -sp.pi / 2
    assert d.joints[0].limits == (-sp.Rational(17, 18) * sp.pi, sp.Rational(17, 18) * sp.pi)
    assert d.tool[2, 3] == sp.Rational(1, 10)
    assert list(d.params.values()) == [0.5]


@pytest.mark.parametrize("mutation, message", [
    (("name = \"cylindrical_rpp\"", "name = \"1robot\""), r"robot.toml: field 'name': '1robot' is not a valid identifier"),
    (("name = \"cylindrical_rpp\"", "name = \"sin\""), "not a valid identifier"),
    (("type = \"R\"", "type = \"H\""), r"robot.toml: joint 1: field 'type': unknown joint type 'H'"),
    (("d = \"d1\"", "d = \"d2\""), r"joint 1: field 'd': in 'd2': unknown name 'd2' \(parameters: d1; also pi\)"),
    (("d = \"d1\"", "d = \"__import__('os')\""), r"joint 1: field 'd': .*only the functions"),
    (("d = \"d1\"", "d = \"d1.real\""), r"joint 1: field 'd': .*Attribute is not allowed"),
    (("d = \"d1\"", "d = \"(lambda: 1)()\""), "joint 1: field 'd'"),
    (("d = \"d1\"", "d = \"d1 +\""), "cannot parse"),
    (("theta = \"pi/2\"", "d = 0.3"), r"joint 3: field 'd': d is the joint variable of a prismatic joint"),
    (("alpha = \"-pi/2\"", "alfa = 1"), r"joint 2: unknown field 'alfa'"),
    (("d1 = 0.5", "if = 0.5"), r"params: 'if': not a valid parameter name"),
    (("d1 = 0.5", "d1 = \"far\""), r"params: 'd1'"),
    (("task = [\"x\", \"y\", \"z\"]", "task = [\"w\"]"), r"field 'task': unknown task coordinate 'w'"),
    (("limits = [\"deg(-170)\", \"deg(170)\"]", "limits = [1, -1]"), r"joint 1: field 'limits': low 1.0 must be below high -1.0"),
    (("[[joint]]\ntype = \"R\"", "[[joint]]\nkind = \"R\""), r"joint 1: unknown field 'kind'"),
])
def test_bad_descriptions_name_file_joint_and_field(mutation, message):
    old, new = mutation
    assert old in GOOD
    with pytest.raises(DescriptionError, match=message):
        parse_description(GOOD.replace(old, new, 1), "robot.toml")


def test_malformed_toml_and_missing_fields():
    with pytest.raises(DescriptionError, match="robot.toml: malformed TOML"):
        parse_description("name = ", "robot.toml")
    with pytest.raises(DescriptionError, match="missing field 'name'"):
        parse_description("[[joint]]\ntype = 'R'\n", "robot.toml")
    with pytest.raises(DescriptionError, match="missing \\[\\[joint\\]\\] tables"):
        parse_description("name = 'arm'\n", "robot.toml")
    with pytest.raises(DescriptionError, match="joint 1: missing field 'type'"):
        parse_description("name = 'arm'\n[[joint]]\na = 1\n", "robot.toml")


def test_expressions_are_parsed_never_evaluated():
    a = sp.Symbol("a", real=True)
    assert parse_expression("2*a + pi/2", {"a": a}) == 2 * a + sp.pi / 2
    assert parse_expression("deg(90)", {}) == sp.pi / 2
    assert parse_expression(0.4318, {}) == sp.Rational(2159, 5000)
    for text in ("open('x')", "a.__class__", "[1]", "1 if a else 2", "a @ a", "'text'", "a < 1"):
        with pytest.raises(ExpressionError):
            parse_expression(text, {"a": a})
    with pytest.raises(ExpressionError, match="division by zero"):
        parse_expression("1/0", {})


def test_unknown_robot_lists_the_known_ones():
    with pytest.raises(derivations.UnknownRobotError, match="unknown robot 'puma561'; known robots: .*puma560"):
        derivations.load("puma561")
    with pytest.raises(ValueError):  # it is a ValueError as well as a KeyError
        derivations.load("nothing")


def test_a_user_description_file_loads_like_a_registered_robot(tmp_path):
    path = tmp_path / "cyl.toml"
    path.write_text(GOOD)
    model = derivations.load(path)
    q1, q2, q3 = model.q
    (d1,) = model.params
    # By hand: the lift q2 raises the arm to d1 + q2; the slide q3 runs along (-s1, c1, 0);
    # the tool's 0.1 m along z_3 = (c1, s1, 0).
    c1, s1 = sp.cos(q1), sp.sin(q1)
    expected = sp.Matrix([-q3 * s1 + c1 / 10, q3 * c1 + s1 / 10, d1 + q2])
    assert model.task_names == ("x", "y", "z")
    assert sp.simplify(model.task - expected) == sp.zeros(3, 1)
    assert model.jacobian.shape == (6, 3)


@pytest.mark.parametrize("name", [n for n, p in derivations.ROBOTS.items() if p.suffix == ".toml"])
def test_every_name_the_generated_c_declares_is_reserved_or_the_robots_own(name):
    """A description's parameter may not take a name the generated C declares for itself.

    A parameter named J would be redeclared beside jacobian's output J (a compile
    error, not a DescriptionError), and one named k shadowed by an ik loop's k
    inside a block (wrong numbers, silently).  So every identifier declared in the
    robot's C (variables, function parameters) is a parameter, an argument's entry
    (q1, qd1, xd_x, ...), a name of the generated code (_*, kinegen_*, <name>_*), or
    reserved.
    """
    import re

    from codegen.generate import GENERATED
    from derivations.expressions import RESERVED

    model = derivations.load(name)
    source = (GENERATED / name / f"{name}.c").read_text()
    # File-scope helpers that take no parameter struct (kinegen_min(a, b), the pose check)
    # have scopes of their own, apart from the parameters.
    source = re.sub(r"^static [^\n(]*\((?:(?!params)[^)])*\)\n\{.*?^\}", "", source, flags=re.M | re.S)
    types = r"\b(?:size_t|int|long|double|float|char|unsigned)"
    declared = set()
    for statement in re.findall(rf"^\s*(?:static\s+)?(?:const\s+)?{types}\s+([^;]*);", source, re.M):
        while re.search(r"\([^()]*\)", statement):  # calls and casts in initialisers, prototypes' lists
            statement = re.sub(r"\([^()]*\)", "", statement)
        statement = re.sub(r"=\s*\{[^}]*\}|=[^,]*", "", statement)  # initialisers
        for item in statement.split(","):
            declared.add(re.sub(r"[*\s]|restrict|\[.*", "", item))
    declared |= set(re.findall(rf"{types}\s*\*?\s*(?:restrict\s+)?(\w+)\s*[,)]", source))
    own = {str(p) for p in model.params}
    own |= {str(s) for f in model.functions() for a in f.arguments for s in a.symbols}
    strangers = {d for d in declared if d and not d.startswith(("_", "kinegen_", f"{name}_")) and d not in own}
    assert strangers <= RESERVED, sorted(strangers - RESERVED)


@pytest.mark.parametrize("param", ["J", "T", "Jx", "frames", "i", "k", "start", "stream"])
def test_a_parameter_named_like_generated_code_is_refused(param):
    text = f'name = "arm"\n[params]\n{param} = 1.0\n[[joint]]\ntype = "R"\na = "{param}"\n'
    with pytest.raises(DescriptionError, match=f"params: '{param}'.*reserved"):
        parse_description(text, "arm.toml")


# Names issue #17 found breaking the numpy backend at call time (Python builtins and the
# generated module's own upper-case names) or the C compile (C library names and macros).
LANGUAGE_NAMES = ["range", "type", "ValueError", "len", "CHUNK", "PARAMS", "NULL", "fabs", "NAN", "size_t",
                  "errno", "KINEGEN_BLOCK", "kinegen_solve", "isfinite"]


@pytest.mark.parametrize("param", LANGUAGE_NAMES)
def test_a_parameter_named_like_the_languages_or_the_templates_is_refused(param):
    text = f'name = "arm"\n[params]\n{param} = 1.0\n[[joint]]\ntype = "R"\na = "{param}"\n'
    with pytest.raises(DescriptionError, match=f"params: '{param}'.*reserved"):
        parse_description(text, "arm.toml")


@pytest.mark.parametrize("robot", ["typing", "json", "os", "math", "codegen", "derivations"])
def test_a_robot_named_like_a_python_module_is_refused(robot, tmp_path, capsys):
    """Its package would shadow the module for any Python started beside it."""
    from codegen.cli import main
    path = tmp_path / "arm.toml"
    path.write_text(f'name = "{robot}"\n[[joint]]\ntype = "R"\na = 1\n')
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg")]) == 2
    err = capsys.readouterr().err
    assert f"field 'name': {robot!r}" in err and ("would shadow the Python module" in err or "reserved word" in err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.toml"]


@pytest.mark.parametrize("param", ["M_PI", "INT_MAX", "Py_None", "NPY_MAXDIMS", "isnan", "errno", "EOF", "NAN",
                                   "HUGE_VAL", "stdout", "assert"])
def test_hostile_d3_a_parameter_named_like_a_c_macro_is_refused(param):
    """A parameter named like a macro of the headers the generated C includes would be replaced by
    the preprocessor: refused when the description is read, never a compile error (issue #28, D3)."""
    text = f'name = "arm"\n[params]\n{param} = 1.0\n[[joint]]\ntype = "R"\na = "{param}"\n'
    with pytest.raises(DescriptionError, match=f"params: '{param}'.*reserved"):
        parse_description(text, "arm.toml")


def test_hostile_d3_the_reserved_macros_cover_this_machines_headers():
    """Every macro that the C headers of a generated package define on this machine (read off the
    compiler's preprocessor, not from our list) is a reserved name."""
    import shutil

    from codegen.build import header_macros
    from derivations.expressions import is_identifier
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    macros = header_macros("cc")
    assert {"M_PI", "INT_MAX", "Py_None", "NPY_MAXDIMS"} <= macros and len(macros) > 1000
    assert sorted(m for m in macros if is_identifier(m)) == []


@pytest.mark.parametrize("name", ["stddef", "stdint", "emmintrin", "Python", "limits"])
def test_hostile_d3_a_robot_named_like_a_c_header_is_refused(name):
    """The package folder is on its C's include path: a robot named stddef would be included in
    place of <stddef.h>."""
    text = f'name = "{name}"\n[[joint]]\ntype = "R"\na = 1\n'
    with pytest.raises(DescriptionError, match="field 'name'"):
        parse_description(text, "arm.toml")


@pytest.mark.parametrize("text, message", [
    ('name = "arm"\na = ' + "1" * 5000 + "\n", "a number too long to read"),
    ('name = "arm"\nx = ' + "[" * 100000 + "]" * 100000 + "\n", "nested too deep to read"),
    ('name = "arm"\ntask = ["x", "x"]\n[[joint]]\ntype = "R"\na = 1\n', "field 'task': 'x' is asked for twice"),
    ('name = "arm"\ntask = ["pose", "z"]\n[[joint]]\ntype = "R"\na = 1\n', "field 'task': 'z' is asked for twice"),
])
def test_hostile_d2_malformed_toml_is_a_description_error(text, message):
    """Python's own limits (4,300-digit integers, recursion) and a repeated task coordinate were
    internal errors (exit 1); they are the input's fault (issue #28, D2)."""
    with pytest.raises(DescriptionError, match=message):
        parse_description(text, "arm.toml")


def test_hostile_d4_a_field_that_expands_past_the_bound_is_refused_before_any_work():
    """A sum of six lengths to the 64th power passes every size check of its text and then runs
    the derivation to its time budget: its expanded size (C(69, 5) terms) is refused at parse time."""
    import math
    import time
    params = "".join(f"l{i} = 0.1\n" for i in range(1, 7))
    text = f'name = "arm"\n[params]\n{params}[[joint]]\ntype = "R"\na = "(l1+l2+l3+l4+l5+l6)**64"\n'
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    with pytest.raises(DescriptionError, match=f"{math.comb(69, 5)} terms once expanded, more than 100"):
        parse_description(text, "arm.toml")
    assert time.process_time() - start < 1.0
    fine = f'name = "arm"\n[params]\n{params}[[joint]]\ntype = "R"\na = "(l1 + l2)**2 * sin((l3 + l4)**3)"\n'
    assert parse_description(fine, "arm.toml").joints[0].a != 0

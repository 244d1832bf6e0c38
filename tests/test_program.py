"""Straight-line programs (derivations/program.py, derivations/chain_program.py): a general arm's
kinematics kept as steps, with derivatives taken in forward mode through them.

The machinery is held to SymPy's own ``diff`` of the inlined expressions; a general 6R (every
twist, offset and length an arbitrary decimal) is held to a DH product written here in numpy,
its Jacobian to central differences of that product, and its Jacobian's rate to central
differences of the Jacobian along a joint path.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import mpmath
import numpy as np
import pytest
import sympy as sp

import derivations
from derivations.program import Program, evaluate, evaluator, inline, needed

GENERAL = Path(__file__).resolve().parent / "data" / "synthetic" / "general_6r.toml"


def test_a_step_is_made_once_and_only_where_it_pays():
    x, y = sp.symbols("x y", real=True)
    program = Program(taken={"x", "y"})
    a = program.define("_a", sp.cos(x) * y + 1)
    assert program.define("_b", sp.cos(x) * y + 1) is a  # the same expression: the same step
    assert program.define("_c", y) is y and program.define("_d", -y) == -y and program.define("_e", 3) == 3
    assert [s.name for s, _ in program.steps] == ["_a"]
    with pytest.raises(ValueError, match="also the name of a parameter"):
        program.define("x", x * y)


def test_derivatives_through_steps_equal_sympys_of_the_inlined_expression():
    x, y, z = sp.symbols("x y z", real=True)
    program = Program(taken={"x", "y", "z"})
    a = program.define("_a", sp.sin(x) * y)
    b = program.define("_b", a * sp.cos(x) + a**2)
    c = program.define("_c", b * z - sp.sin(a))
    for expr in (c, b + a * z, c * sp.cos(y)):
        explicit = inline(program.steps, expr)
        for variable in (x, y, z):
            got = inline(program.steps, program.derivative(expr, variable))
            assert sp.simplify(got - sp.diff(explicit, variable)) == 0
    xd, yd = sp.symbols("xd yd", real=True)
    got = inline(program.steps, program.time_derivative(c, {x: xd, y: yd}))
    explicit = inline(program.steps, c)
    assert sp.simplify(got - sp.diff(explicit, x) * xd - sp.diff(explicit, y) * yd) == 0
    assert program.derivative(a, z) == 0  # a does not read z: no step for it
    assert needed(program.steps, [a + x]) == ((a, program.value[a]),)
    point = {x: sp.Rational(1, 3), y: 2, z: -1}
    assert abs(evaluate(program.steps, [c], point)[0] - explicit.xreplace(point).evalf(30)) < 1e-28
    # the mpmath walk of the same steps, with a square root, a reciprocal and pi besides
    d = program.define("_d", sp.sqrt(c**2 + 1) / (2 + sp.cos(b)) + sp.pi * x)
    run = evaluator(program.steps, [c, d, b * y], [x, y, z])
    with mpmath.workdps(30):
        got = run(mpmath.mpf(1) / 3, mpmath.mpf(2), mpmath.mpf(-1))
    expected = [e.xreplace(point).evalf(40) for e in (explicit, inline(program.steps, d), inline(program.steps, b * y))]
    assert all(abs(g - sp.Float(str(e), 40)) < 1e-27 for g, e in zip(got, expected))


def dh_product(table, q):
    """The standard DH product of ``table`` (theta offset, d, a, alpha per joint) at q: the frames."""
    frames = [np.eye(4)]
    for (offset, d, a, alpha), qi in zip(table, q):
        t = qi + offset
        ct, st, ca, sa = math.cos(t), math.sin(t), math.cos(alpha), math.sin(alpha)
        frames.append(frames[-1] @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                                             [0, sa, ca, d], [0, 0, 0, 1]]))
    return frames


def geometric_jacobian(frames):
    p = frames[-1][:3, 3]
    return np.array([np.concatenate([np.cross(F[:3, 2], p - F[:3, 3]), F[:3, 2]]) for F in frames[:-1]]).T


@pytest.fixture(scope="module")
def general():
    data = tomllib.loads(GENERAL.read_text())
    table = [(j["offset"], j["d"], j["a"], j["alpha"]) for j in data["joint"]]
    model = derivations.load(GENERAL)
    rates = model.rates
    args = [model.q, rates.qd]

    def program(exprs):
        entries = [e for matrix in exprs for row in matrix for e in row]
        return list(needed(rates.program, entries)), exprs

    function = sp.lambdify(args, [model.fk.tolist(), model.jacobian.tolist(), rates.jacobian_dot.tolist()],
                           modules="math", cse=program)
    return model, table, lambda q, qd: [np.array(m, dtype=float) for m in function(q, qd)]


def test_a_general_arm_is_a_program_and_its_fk_and_jacobian_are_the_dh_product(general):
    model, table, kernels = general
    # the twist 1.3127 stays exact as written; its cosine is a number (not cos(13127/10000) in every product)
    assert model.program and model.chain.link_transform(0, model.q[0])[1, 1].has(sp.Float)
    rng = np.random.default_rng(3)
    for q in rng.uniform(-math.pi, math.pi, (50, 6)):
        T, J, _ = kernels(q, np.zeros(6))
        frames = dh_product(table, q)
        assert np.max(np.abs(T - frames[-1])) < 1e-13
        assert np.max(np.abs(J - geometric_jacobian(frames))) < 1e-13


def test_the_general_arms_jacobian_and_its_rate_are_derivatives(general):
    model, table, kernels = general
    rng = np.random.default_rng(4)
    h = 1e-6
    for q, qd in zip(rng.uniform(-math.pi, math.pi, (10, 6)), rng.uniform(-1, 1, (10, 6))):
        T, J, J_dot = kernels(q, qd)
        for j in range(6):
            step = np.zeros(6)
            step[j] = h
            plus, minus = dh_product(table, q + step)[-1], dh_product(table, q - step)[-1]
            assert np.allclose((plus[:3, 3] - minus[:3, 3]) / (2 * h), J[:3, j], atol=1e-8)
        along = (geometric_jacobian(dh_product(table, q + h * qd)) - geometric_jacobian(dh_product(table, q - h * qd)))
        assert np.allclose(along / (2 * h), J_dot, atol=1e-8)

"""codegen.operations.operation_count: the number sympy.count_ops gives, on kernels and on random
expressions (count_ops itself is the independent reference)."""
from pathlib import Path

import pytest
import sympy as sp
from hypothesis import given, settings, strategies as st

import derivations
from codegen.kernels import prepare
from codegen.operations import operation_count
from conftest import ROBOT_NAMES

DATA = Path(__file__).resolve().parents[1] / "data"

x, y, z = sp.symbols("x y z", real=True)


def _expressions(prepared):
    yield from (e for _, e in prepared.temporaries)
    yield from (e for out in prepared.outputs for e in out.entries)
    for check in prepared.checks:
        yield from (e for _, e in check.temporaries)
        yield check.condition


@pytest.mark.parametrize("name", ["avr3000", "scorbot_er7", "rrp_arm"])
def test_every_expression_of_a_robots_kernels_counts_as_count_ops_does(models, name):
    """Two of the papers' robots, and an arm with its dynamics (tests/data/dynamics/rrp_arm.toml)."""
    model = models[name] if name in ROBOT_NAMES else derivations.load(DATA / "dynamics" / f"{name}.toml")
    params = tuple(str(s) for s in model.params)
    seen = 0
    for function in model.functions():
        if function.solve is None:
            for expr in _expressions(prepare(function, params)):
                assert operation_count(expr) == int(sp.count_ops(expr)), (function.name, expr)
                seen += 1
    assert seen > 300


SPECIAL_CASES = [
    -x, -x - y, -x + y, x - y, -2 * x, -x / 2, x / y, -x / y, 1 / x, -1 / x, 3 / x, x ** -2, -3 / x ** 2,
    sp.Rational(3, 4) * x * y, -sp.Rational(3, 4) / (x * y), sp.sqrt(x), 1 / sp.sqrt(x + 1), x ** sp.Rational(-3, 2),
    -1.5 * x, x - 0.5, -0.5 - x, 1.0 * x, -1.0 * x * y, (x + y) * z / 3, -(x + y) * z, 2 * (x + y) ** -1 * z,
    sp.sin(x) * sp.cos(y) - sp.sin(y), sp.atan2(-x, y - 1), sp.Max(x, y, z), sp.Min(x, -y),
    sp.Piecewise((x, x > 0), (-y, sp.And(y > 0, z < 1)), (0, True)), sp.Abs(-x + y), sp.exp(-x), sp.E * x,
    sp.sqrt(2) * x / 2, x / sp.sqrt(3), sp.Integer(-7), sp.Rational(-2, 3), sp.Float(-2.5), x > y,
    sp.Integer(2) ** x, x ** y, (x * y) ** sp.Rational(1, 2) / z,
]


@pytest.mark.parametrize("expr", SPECIAL_CASES, ids=str)
def test_the_cases_count_ops_treats_apart(expr):
    assert operation_count(expr) == int(sp.count_ops(expr))


_atoms = st.sampled_from([x, y, z, sp.Integer(2), sp.Integer(-1), sp.Integer(-3), sp.Rational(1, 2),
                          sp.Rational(-5, 7), sp.Float(0.25), sp.Float(-1.5), sp.pi])


def _combine(children):
    unary = st.builds(lambda f, a: f(a), st.sampled_from([sp.sin, sp.cos, sp.sqrt, lambda a: -a,
                                                          lambda a: 1 / a, lambda a: a ** 2,
                                                          lambda a: a ** -3, lambda a: a ** sp.Rational(-1, 2)]),
                      children)
    binary = st.builds(lambda f, a, b: f(a, b), st.sampled_from([sp.Add, sp.Mul, lambda a, b: a - b,
                                                                 lambda a, b: a / b, sp.atan2]), children, children)
    return unary | binary | st.lists(children, min_size=3, max_size=5).map(lambda args: sp.Add(*args))


@settings(max_examples=300, deadline=None)
@given(st.recursive(_atoms, _combine, max_leaves=12))
def test_random_expressions_count_as_count_ops_does(expr):
    assert operation_count(expr) == int(sp.count_ops(expr))


@settings(max_examples=200, deadline=None)
@given(st.recursive(st.sampled_from([x, y, sp.Integer(3), sp.Rational(2**60 + 1, 7), sp.Rational(1, 2**54 + 3),
                                     sp.Integer(-(2**53) - 1), sp.Integer(2**53), sp.pi]),
                    lambda children: st.one_of(st.tuples(children, children).map(lambda a: a[0] + a[1]),
                                               st.tuples(children, children).map(lambda a: a[0] * a[1]),
                                               children.map(sp.sqrt), children.map(sp.cos)),
                    max_leaves=10))
def test_a_rational_beyond_a_double_is_found_as_atoms_finds_it(expr):
    """codegen.kernels._holds_beyond_double (each distinct node once) against SymPy's atoms."""
    from codegen.kernels import EXACT_INTEGER_LIMIT, _holds_beyond_double
    expected = any(abs(r.p) > EXACT_INTEGER_LIMIT or r.q > EXACT_INTEGER_LIMIT for r in expr.atoms(sp.Rational))
    assert _holds_beyond_double(expr) == expected

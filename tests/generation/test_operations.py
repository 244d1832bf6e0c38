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


_BEYOND_DOUBLE = st.recursive(
    st.sampled_from([x, y, sp.Integer(3), sp.Rational(2**60 + 1, 7), sp.Rational(1, 2**54 + 3),
                     sp.Integer(-(2**53) - 1), sp.Integer(2**53), sp.pi]),
    lambda children: st.one_of(st.tuples(children, children).map(lambda a: a[0] + a[1]),
                               st.tuples(children, children).map(lambda a: a[0] * a[1]),
                               children.map(sp.sqrt), children.map(sp.cos)),
    max_leaves=10)


def _beyond(expr):
    from codegen.kernels import EXACT_INTEGER_LIMIT
    return any(abs(r.p) > EXACT_INTEGER_LIMIT or r.q > EXACT_INTEGER_LIMIT for r in expr.atoms(sp.Rational))


@settings(max_examples=200, deadline=None)
@given(_BEYOND_DOUBLE)
def test_a_rational_beyond_a_double_is_found_as_atoms_finds_it(expr):
    """codegen.kernels._holds_beyond_double (each distinct node once) against SymPy's atoms."""
    from codegen.kernels import _holds_beyond_double
    assert _holds_beyond_double(expr) == _beyond(expr)


def _folded(e):
    """bounded_numbers' fold as its docstring states it, with SymPy's own free_symbols and atoms on
    every node: the largest constant subexpression holding a rational beyond 2**53, evaluated at 30
    digits (a rational alone left as it is)."""
    if e.is_Rational and not e.is_Integer:
        return e
    if isinstance(e, sp.Expr) and not e.free_symbols and _beyond(e):
        value = e.evalf(30)
        return sp.Float(value, 30) if value.is_real and value.is_finite else e
    return e.func(*map(_folded, e.args)) if e.args else e


# Positive numbers only, for the fold's evaluation: cos(sqrt(-2**53 - 1)) is a cosh of 9.5e7, whose
# cosine evalf would take for ever to find a digit of.
_POSITIVE_BEYOND_DOUBLE = st.recursive(
    st.sampled_from([x, y, sp.Integer(3), sp.Rational(2**60 + 1, 7), sp.Rational(1, 2**54 + 3), sp.Integer(2**53 + 1),
                     sp.pi]),
    lambda children: st.one_of(st.tuples(children, children).map(lambda a: a[0] + a[1]),
                               st.tuples(children, children).map(lambda a: a[0] * a[1]),
                               children.map(sp.sqrt), children.map(sp.cos)),
    max_leaves=10)


@settings(max_examples=200, deadline=None)
@given(_POSITIVE_BEYOND_DOUBLE, st.sampled_from([lambda e: e, lambda e: sp.Subs(e * x, x, 2),
                                                 lambda e: sp.Derivative(e * x, x, evaluate=False)]))
def test_the_numbers_beyond_a_double_fold_as_free_symbols_and_atoms_say(expr, wrap):
    """codegen.kernels.bounded_numbers (what each node holds found once, from its arguments, but for
    a node that binds a symbol of its own: Subs(e x, x, 2) is a constant where e is) folds what the
    docstring's reference does."""
    from codegen.kernels import bounded_numbers
    expr = wrap(expr)
    bounded_numbers.cache_clear()
    assert bounded_numbers(expr) == (_folded(expr) if _beyond(expr) else expr)


@settings(max_examples=200, deadline=None)
@given(_BEYOND_DOUBLE, st.sampled_from([lambda e: e, lambda e: sp.Subs(e * x, x, 2),
                                        lambda e: sp.Derivative(e * x, x, evaluate=False),
                                        lambda e: sp.Tuple(e, sp.Lambda(x, e * x + y))]))
def test_free_symbols_and_the_fold_of_pi_are_sympys(expr, wrap):
    """codegen.kernels.free_symbols and exact_floats (each distinct node once) against SymPy's own
    free_symbols and xreplace, on random trees that share subtrees (e + y e**2), and where
    a node binds a symbol of its own (Subs, Derivative, Lambda: its free symbols are not its arguments')."""
    from codegen.kernels import exact_floats, free_symbols
    expr = wrap(expr + y * expr ** 2)
    assert free_symbols(expr) == expr.free_symbols
    exact_floats.cache_clear()
    folded = exact_floats(expr)
    assert folded == expr.xreplace({sp.pi: sp.Float(sp.pi.evalf(40), 40)})
    assert not folded.has(sp.pi) and (folded == expr) == (not expr.has(sp.pi))

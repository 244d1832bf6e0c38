"""derivations.support.pickling.dumps: pickles that load as the very objects pickled (the same
classes with the same arguments, compared through sympy.srepr, which prints the tree as built),
without SymPy evaluating them again."""
import pickle
from pathlib import Path

import sympy as sp
from hypothesis import given, settings, strategies as st

import derivations
from derivations.ik import WrapAngle
from derivations.ik.primitives import ClampUnit
from derivations.support.pickling import dumps

DATA = Path(__file__).resolve().parents[1] / "data"

x, y, z = sp.symbols("x y z", real=True)
f = sp.Function("f")


def _same(value):
    loaded = pickle.loads(dumps(value))
    assert type(loaded) is type(value)
    return loaded


def test_unevaluated_forms_stay_as_they_were_built():
    """SymPy's own pickles evaluate on loading (x + x comes back as 2*x); these do not."""
    forms = [sp.Add(x, x, evaluate=False), sp.Mul(x, x, 2, evaluate=False), sp.Pow(x, 1, evaluate=False),
             sp.sin(sp.pi, evaluate=False), sp.atan2(0, 1, evaluate=False), sp.Max(x, x, evaluate=False)]
    assert sp.srepr(pickle.loads(pickle.dumps(forms[0]))) == sp.srepr(2 * x)  # what this module avoids
    for form in forms:
        assert sp.srepr(_same(form)) == sp.srepr(form)


def test_special_classes_round_trip():
    """An undefined function (pickled as SymPy pickles it), a Piecewise, our own functions, a matrix,
    numbers and relations."""
    values = [f(x) + 1, sp.Piecewise((x, x > 0), (-x, True)), WrapAngle(x + y), ClampUnit(x / 3),
              sp.Matrix([[x * y, sp.sqrt(x)], [sp.Rational(1, 3), sp.Float("0.1", 30)]]), sp.Eq(x, y + 1),
              sp.And(x > 0, y < 1), sp.I * x, sp.exp(-x) * sp.cos(z) ** 2, sp.Tuple(x, 1.5, sp.oo)]
    for value in values:
        loaded = _same(value)
        assert loaded == value and sp.srepr(loaded) == sp.srepr(value)
        if not isinstance(value, sp.MutableDenseMatrix):
            assert hash(loaded) == hash(value)


_leaves = st.sampled_from([x, y, z, sp.Integer(2), sp.Rational(-1, 3), sp.pi, sp.Float("1.25")])


def _combine(children):
    return st.one_of(
        st.tuples(children, children).map(lambda a: a[0] + a[1]),
        st.tuples(children, children).map(lambda a: a[0] * a[1]),
        st.tuples(children, st.sampled_from([-1, 2, sp.Rational(1, 2)])).map(lambda a: a[0] ** a[1]),
        children.map(sp.sin), children.map(sp.cos), st.tuples(children, children).map(lambda a: sp.atan2(*a)),
    )


@settings(max_examples=200, deadline=None)
@given(st.recursive(_leaves, _combine, max_leaves=12))
def test_random_expressions_load_as_the_same_tree(expr):
    loaded = _same(expr)
    assert sp.srepr(loaded) == sp.srepr(expr) and loaded == expr and hash(loaded) == hash(expr)


def test_an_arms_equations_of_motion_round_trip():
    """The dynamics of an arm (tests/data/dynamics/rrp_arm.toml): every kernel's outputs and the program."""
    model = derivations.load(DATA / "dynamics" / "rrp_arm.toml")
    dynamics = model.dynamics
    loaded = _same(dynamics)
    assert loaded == dynamics
    assert [sp.srepr(e) for _, e in loaded.program] == [sp.srepr(e) for _, e in dynamics.program]
    assert sp.srepr(loaded.mass_matrix) == sp.srepr(dynamics.mass_matrix)


def test_a_class_with_its_own_reduction_keeps_it():
    """derivations.ik.primitives' written Piecewise pickles itself (it is never evaluated, and is
    not importable under its printed name): it loads as written, a condition holding a Piecewise
    left unfolded."""
    from derivations.ik.primitives import WrittenPiecewise, written_piecewise
    inner = written_piecewise((x, x > 0), (-x, True))
    value = written_piecewise((y, inner > 1), (z, True))
    loaded = _same(value)
    assert isinstance(loaded, WrittenPiecewise) and sp.srepr(loaded) == sp.srepr(value)

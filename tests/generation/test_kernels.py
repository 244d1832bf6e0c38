"""Generated kernels: equal to SymPy, shaped and guarded as the contract says."""
import numpy as np
import pytest

import generated
from codegen.verify import jacobian_by_finite_differences, verify_model
from conftest import ROBOT_NAMES, kernels

BACKENDS = ["numpy", "c"]


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_every_kernel_matches_sympy_at_30_digits(models, name):
    checks = verify_model(models[name], {b: kernels(name, b) for b in BACKENDS}, samples=5, seed=7)
    failed = [c for c in checks if not c.ok]
    assert not failed, failed
    # every kernel in both backends, plus finite differences of jacobian (and, with rate kernels,
    # of jacobian_dot and task_jacobian_dot)
    rate_checks = 2 if "jacobian_dot" in {f.name for f in models[name].functions()} else 0
    assert len(checks) == 2 * len(models[name].functions()) + 2 * (1 + rate_checks)
    assert all(c.points > 0 for c in checks)  # ik: some branch existed at some sample


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_shapes_broadcast_over_batch_dimensions(models, name, backend):
    k = kernels(name, backend)
    n, m = len(k.JOINTS), len(k.TASK)
    q = np.random.default_rng(0).uniform(-1, 1, (2, 3, n))
    assert k.fk(q).shape == (2, 3, 4, 4)
    assert k.frames(q).shape == (2, 3, n + 1, 4, 4)
    assert k.jacobian(q).shape == (2, 3, 6, n)
    assert k.task(q).shape == (2, 3, m)
    assert k.task_jacobian(q).shape == (2, 3, m, n)
    assert k.fk(q[0, 0]).shape == (4, 4)
    assert k.fk(q[:0]).shape == (0, 3, 4, 4)
    np.testing.assert_allclose(k.frames(q)[..., -1, :, :], k.fk(q), rtol=0, atol=1e-15)
    assert k.fk(q[0, 0].tolist()).shape == (4, 4)  # lists work too
    assert k.fk(np.zeros(n, dtype=np.int64)).dtype == np.float64


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_c_and_numpy_agree_on_a_large_batch(name):
    kn, kc = kernels(name, "numpy"), kernels(name, "c")
    q = np.random.default_rng(1).uniform(-3, 3, (1000, len(kn.JOINTS)))
    for kernel in ("fk", "frames", "jacobian", "task", "task_jacobian"):
        np.testing.assert_allclose(getattr(kc, kernel)(q), getattr(kn, kernel)(q), rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("backend", BACKENDS)
def test_parameters_are_keywords_with_the_papers_defaults(backend):
    k = kernels("adept_three", backend)
    assert k.PARAMS == {"l1": 0.559, "l2": 0.508, "d1": 0.8763, "d4": 0.0}
    q = np.array([0.3, -0.4, 0.1, 0.2])
    x_default = k.task(q)
    x_explicit = k.task(q, l1=0.559, l2=0.508, d1=0.8763, d4=0.0)
    np.testing.assert_array_equal(x_default, x_explicit)
    assert k.task(q, d4=0.1)[2] == pytest.approx(x_default[2] - 0.1, abs=1e-15)
    assert k.task(q, l1=0.0)[0] == pytest.approx(0.508 * np.cos(0.3 - 0.4), abs=1e-15)


@pytest.mark.parametrize("backend", BACKENDS)
def test_finite_differences_of_fk_give_the_geometric_jacobian(backend):
    k = kernels("puma560", backend)
    q = np.random.default_rng(5).uniform(-2, 2, (50, 6))
    np.testing.assert_allclose(k.jacobian(q), jacobian_by_finite_differences(k.fk, q), atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_bad_input_raises_value_error_naming_the_expected_shape(backend):
    k = kernels("puma560", backend)
    with pytest.raises(ValueError, match=r"expected q of shape \(\.\.\., 6\), got shape \(5,\)"):
        k.fk(np.zeros(5))
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 6\)"):
        k.fk(np.zeros((3, 7)))
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 6\)"):
        k.jacobian(0.5)
    with pytest.raises(ValueError, match="real numeric array"):
        k.fk(["a"] * 6)
    with pytest.raises(ValueError, match="real numeric array"):
        k.fk(np.zeros(6, dtype=complex))
    with pytest.raises(ValueError, match="NaN or inf"):
        k.fk([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(ValueError, match="parameter d1"):
        k.fk(np.zeros(6), d1=np.ones(2))
    with pytest.raises(ValueError, match="parameter a2"):
        k.fk(np.zeros(6), a2="long")
    with pytest.raises(ValueError, match="parameter a3 must be finite"):
        k.fk(np.zeros(6), a3=float("inf"))
    with pytest.raises(TypeError):
        k.fk(np.zeros(6), unknown=1.0)


def test_load_names_robots_and_backends():
    assert generated.load("planar_2r").__name__ == "generated.planar_2r.numpy_kernels"
    assert generated.load("planar_2r", backend="c").__name__ == "generated.planar_2r.c_kernels"
    with pytest.raises(ValueError, match="unknown robot 'nope'; generated robots: .*puma560"):
        generated.load("nope")
    with pytest.raises(ValueError, match="unknown backend 'fortran'"):
        generated.load("puma560", backend="fortran")
    assert set(generated.ROBOTS) == set(ROBOT_NAMES)


def test_module_constants(models):
    for name in ROBOT_NAMES:
        k = kernels(name, "numpy")
        m = models[name]
        assert k.JOINTS == tuple(str(q) for q in m.q)
        assert k.TASK == m.task_names
        assert k.PARAMS == {str(p): v for p, v in m.params.items()}
        assert len(k.LIMITS) == m.n


def test_tree_only_cse_of_long_programs_keeps_every_value(monkeypatch):
    """Kernels past kernels.TREE_CSE_ONLY get SymPy's tree CSE without opt_cse.  With the threshold
    at 1, the rate and dynamics kernels of an arm (program-form definitions) go that way: their
    temporaries and outputs, evaluated in order at 30 digits, equal the symbolic kernel's program
    evaluated at the same point."""
    import random

    import sympy as sp

    import derivations
    from codegen import kernels as prepared_kernels
    from codegen.generate import REPO
    from derivations.program import evaluate
    model = derivations.load(REPO / "tests" / "data" / "dynamics" / "rrp_arm.toml")
    monkeypatch.setattr(prepared_kernels, "TREE_CSE_ONLY", 1)
    rng = random.Random(7)
    names = ("inverse_dynamics", "coriolis", "regressor", "forward_dynamics", "jacobian_dot")
    functions = [f for f in model.functions() if f.name in names]
    assert len(functions) == len(names)
    for function in functions:
        prepared = prepared_kernels.prepare(function, tuple(str(s) for s in model.params))
        point = {s: sp.Rational(repr(v)) for s, v in model.params.items()}
        for argument in function.arguments:
            point.update({s: sp.Rational(repr(rng.uniform(-1.0, 1.0))) for s in argument.symbols})
        expected = evaluate(function.definitions, [e for o in function.outputs for e in o.values], point)
        known = {sp.Symbol(str(s), real=True): v for s, v in point.items()}
        for name, expr in prepared.temporaries:
            known[sp.Symbol(name, real=True)] = sp.sympify(expr).xreplace(known).evalf(30)
        got = [sp.sympify(e).xreplace(known).evalf(30) for o in prepared.outputs for e in o.entries]
        scale = max(1.0, max(abs(float(e)) for e in expected))
        assert max(abs(float(g - e)) for g, e in zip(got, expected)) < 1e-20 * scale, function.name

"""Rate kinematics: the papers' velocity equations, the inverse maps, singularities, damping.

Sources: the velocity-model slides (2R DVM/IVM and its singularity, Paul's
wrist partition), Kumar section 5.5 (Eqs. 11-13), Rehiara section 4 (Eqs. 36-42).
Expected values come from the printed equations, from numpy linear algebra on
the position-level kernels (det, SVD, solve, pinv), or from finite differences.
"""
import warnings

import numpy as np
import pytest
import sympy as sp

import derivations
from codegen.verify import derivative_along
from conftest import ROBOT_NAMES, kernels

import derivations

# Rate kinematics covers the DH chains; the AVR 3000 carries its own rate maps (tests/test_avr3000_*.py).
DH_ROBOTS = [n for n in ROBOT_NAMES if derivations.ROBOTS[n].suffix == ".toml"]
from derivations.chain import simplify_entry
from derivations.damping import MAX_DAMPING, SINGULAR_MEASURE
from derivations.robots._common import parameters as params

c, s = sp.cos, sp.sin
BACKENDS = ["numpy", "c"]
MU0, LAMBDA_MAX = float(SINGULAR_MEASURE), float(MAX_DAMPING)
SQUARE = ["planar_2r", "planar_3r", "planar_rp", "planar_pp", "adept_three"]


def function(model, name):
    return {f.name: f for f in model.functions()}[name]


def outputs(model, name, index=0):
    return sp.Matrix(function(model, name).outputs[index].values)


def zero(expr):
    return sp.simplify(sp.expand_trig(expr)) == 0


def regular_configurations(model, k, count, seed, margin=5.0):
    """Joint values within the limits whose normalised manipulability exceeds margin * mu_0."""
    rng = np.random.default_rng(seed)
    low = np.array([lim[0] if lim else (-np.pi if t == "R" else -1.0) for lim, t in zip(model.limits, model.joint_types)])
    high = np.array([lim[1] if lim else (np.pi if t == "R" else 1.0) for lim, t in zip(model.limits, model.joint_types)])
    q = rng.uniform(low, high, (50 * count, model.n))
    w, _ = k.manipulability(q)
    L = float(model.singularities.reference_length.subs(model.params))
    power = model.rates.scaling.power if model.rates.strategy != "wide" else sum(model.rates.scaling.rows)
    if model.rates.strategy == "wrist partition":
        power = 3
    keep = w / L**power > margin * MU0
    assert keep.sum() >= count
    return q[keep][:count]


# --- the slides: 2R direct and inverse velocity model ---------------------------------------

def test_slides_2r_inverse_velocity_closed_form(models):
    """Slides, "IVM of a 2R planer robot": the closed form of theta1_dot and theta2_dot."""
    m = models["planar_2r"]
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    X, Y = m.rates.xd
    c1, s1, c12, s12, s2 = c(q1), s(q1), c(q1 + q2), s(q1 + q2), s(q2)
    theta1_dot = (l2 * c12 * X + l2 * s12 * Y) / (l1 * l2 * s2)
    theta2_dot = -((l1 * c1 + l2 * c12) * X + (l1 * s1 + l2 * s12) * Y) / (l1 * l2 * s2)
    closed = m.rates.inverse.inverse * sp.Matrix([X, Y])
    assert zero(closed[0] - theta1_dot) and zero(closed[1] - theta2_dot)
    # The kernels' regular branch is that closed form; check both backends numerically.
    rng = np.random.default_rng(2)
    for backend in BACKENDS:
        k = kernels("planar_2r", backend)
        q = regular_configurations(m, k, 20, seed=3)
        xd = rng.uniform(-1, 1, (len(q), 2))
        a, b = q[:, 0], q[:, 1]
        L1, L2 = m.params[l1], m.params[l2]
        det = L1 * L2 * np.sin(b)
        expected = np.stack([(L2 * np.cos(a + b) * xd[:, 0] + L2 * np.sin(a + b) * xd[:, 1]) / det,
                             -((L1 * np.cos(a) + L2 * np.cos(a + b)) * xd[:, 0]
                               + (L1 * np.sin(a) + L2 * np.sin(a + b)) * xd[:, 1]) / det], axis=-1)
        qd, singular = k.joint_velocity(q, xd)
        assert not singular.any()
        np.testing.assert_allclose(qd, expected, rtol=1e-12, atol=1e-12)


def test_E6_slides_2r_inverse_in_the_intermediate_step(models):
    """Erratum E6: the slides' step before the closed form inverts the adjugate a second time.

    Printed: [t1_dot; t2_dot] = -1/(l1 l2 s2) [[-l2 c12, -l2 s12], [l1 c1 + l2 c12, l1 s1 + l2 s12]]^-1 [X; Y].
    Without the ^-1 the step is right (and gives the slides' final formulas).
    """
    m = models["planar_2r"]
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    X, Y = m.rates.xd
    # The slides' 2x2 rule T^-1 = -1/det(T) [[-d, b], [c, -a]] is itself right:
    a, b, c_, d = sp.symbols("a b c d")
    T = sp.Matrix([[a, b], [c_, d]])
    assert sp.simplify(T.inv() - (-1 / T.det()) * sp.Matrix([[-d, b], [c_, -a]])) == sp.zeros(2, 2)
    printed_matrix = sp.Matrix([[-l2 * c(q1 + q2), -l2 * s(q1 + q2)],
                                [l1 * c(q1) + l2 * c(q1 + q2), l1 * s(q1) + l2 * s(q1 + q2)]])
    factor = -1 / (l1 * l2 * s(q2))
    printed = factor * printed_matrix.inv() * sp.Matrix([X, Y])
    corrected = factor * printed_matrix * sp.Matrix([X, Y])
    derived = m.rates.inverse.inverse * sp.Matrix([X, Y])
    assert all(zero(e) for e in corrected - derived)
    point = {q1: 0.4, q2: 1.1, l1: 0.559, l2: 0.508, X: 0.3, Y: -0.2}
    assert abs(float((printed - derived)[0].subs(point))) > 0.1


def test_E7_slides_2r_dvm_matrix_has_six_rows(models):
    """Erratum E7: the DVM slide prints J (6 x 2 on the previous slide) with five rows."""
    m = models["planar_2r"]
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    printed = sp.Matrix([[-l1 * s(q1) - l2 * s(q1 + q2), -l2 * s(q1 + q2)],
                         [l1 * c(q1) + l2 * c(q1 + q2), l2 * c(q1 + q2)], [0, 0], [0, 0], [1, 1]])
    assert printed.shape == (5, 2) and m.jacobian.shape == (6, 2)
    # It is the geometric Jacobian with one of the zero rows (w_x or w_y) dropped.
    assert all(zero(e) for e in printed - m.jacobian[[0, 1, 2, 3, 5], :])
    # The slide's v and w: v = (-l1 s1 t1_dot - l2 s12 (t1_dot + t2_dot), ..., 0), w_z = t1_dot + t2_dot.
    t1, t2 = m.rates.qd
    twist = outputs(m, "twist")
    expected = [-l1 * s(q1) * t1 - l2 * s(q1 + q2) * (t1 + t2), l1 * c(q1) * t1 + l2 * c(q1 + q2) * (t1 + t2),
                0, 0, 0, t1 + t2]
    assert all(zero(e) for e in twist - sp.Matrix(expected))


def test_slides_2r_singularity(models):
    """Slides: |J| = 0 => l1 l2 s2 = 0 => theta2 = 0 or theta2 = pi."""
    m = models["planar_2r"]
    q1, q2 = m.q
    l1, l2 = params(m, "l1", "l2")
    sing = m.singularities
    assert sing.determinant == l1 * l2 * s(q2)
    assert [cond.name for cond in sing.conditions] == ["elbow"]
    (equation,) = sing.conditions[0].equations
    assert set(sp.solve(equation, q2)) == {0, sp.pi}


# --- Kumar section 5.5 ------------------------------------------------------------------------

def test_kumar_velocity_equations_of_the_3r_arm(models):
    """Kumar 5.5: x_dot = -l1 t1_dot s1 - l2 (t1_dot + t2_dot) s12 - l3 (t1_dot + t2_dot + t3_dot) s123, ..."""
    m = models["planar_3r"]
    q1, q2, q3 = m.q
    l1, l2, l3 = params(m, "l1", "l2", "l3")
    t1, t2, t3 = m.rates.qd
    kumar = [-l1 * t1 * s(q1) - l2 * (t1 + t2) * s(q1 + q2) - l3 * (t1 + t2 + t3) * s(q1 + q2 + q3),
             l1 * t1 * c(q1) + l2 * (t1 + t2) * c(q1 + q2) + l3 * (t1 + t2 + t3) * c(q1 + q2 + q3),
             t1 + t2 + t3]
    assert all(zero(e) for e in outputs(m, "task_velocity") - sp.Matrix(kumar))


def test_kumar_eq12_and_eq13(models):
    """Eq. 12: q_dot = J^-1 p_dot; Eq. 13: |J| = l1 l2 sin(theta2), singular at theta2 = 0 or 180 degrees."""
    m = models["planar_3r"]
    q1, q2, q3 = m.q
    l1, l2 = params(m, "l1", "l2")
    assert m.singularities.determinant == l1 * l2 * s(q2)
    assert m.rates.inverse.determinant == l1 * l2 * s(q2)
    product = (m.rates.inverse.inverse * m.task_jacobian).applyfunc(simplify_entry)
    assert product == sp.eye(3)
    (condition,) = m.singularities.conditions
    assert condition.name == "elbow" and set(sp.solve(condition.equations[0], q2)) == {0, sp.pi}


# --- singular sets of every robot -------------------------------------------------------------

def test_singular_sets_are_factored(models):
    q = {name: models[name].q for name in DH_ROBOTS}
    assert models["adept_three"].singularities.determinant == sp.Mul(*params(models["adept_three"], "l1", "l2")) * s(q["adept_three"][1])
    assert models["planar_rp"].singularities.determinant == -q["planar_rp"][1]  # Kumar's R-P arm: det = -d2
    assert models["planar_pp"].singularities.conditions == ()  # the Cartesian arm is never singular
    puma = models["puma560"]
    q1, q2, q3, q4, q5, q6 = puma.q
    d1, a2, a3, d3, d4 = params(puma, "d1", "a2", "a3", "d3", "d4")
    by_name = {cond.name: cond.factors for cond in puma.singularities.conditions}
    assert set(by_name) == {"shoulder", "elbow", "wrist"}
    assert zero(by_name["elbow"][0] - (a3 * s(q3) + d4 * c(q3)))
    assert zero(by_name["shoulder"][0] - (a2 * c(q2) + a3 * c(q2 + q3) - d4 * s(q2 + q3)))
    assert by_name["wrist"] == (s(q5),)
    scorbot = models["scorbot_er7"]
    q1, q2, q3, q4, q5 = scorbot.q
    a1, a2, a3, d5 = params(scorbot, "a1", "a2", "a3", "d5")
    by_name = {cond.name: cond.factors for cond in scorbot.singularities.conditions}
    assert zero(by_name["shoulder"][0] - (a1 + a2 * c(q2) + a3 * c(q2 + q3) + d5 * c(q2 + q3 + q4)))
    assert set(by_name["elbow"]) == {s(q3), s(q4)}


def test_the_size_bound_of_a_determinant_is_count_ops_or_below_it(models):
    """singular._operations_within: count_ops up to the limit; past it, a bound that count_ops exceeds."""
    from derivations.singular import _operations_within
    x, y, z = sp.symbols("x y z")
    samples = [x / y, -x / 2, 2 * x**2, sp.sin(x) * sp.cos(y) - sp.sqrt(3) / 3 * z, (x + y)**3 * sp.sin(z) / 7]
    puma = models["puma560"]
    samples += [e for e in puma.jacobian[:3, :3]] + [puma.jacobian[:3, :3].det(method="berkowitz")]
    for expr in samples:
        ops = int(sp.count_ops(expr))
        assert _operations_within([expr], 10**6) == ops
        for limit in range(0, ops + 2):
            bound = _operations_within([expr], limit)
            assert (bound == ops) if ops <= limit else (limit < bound <= ops), (expr, limit)


def test_scorbot_elbow_with_the_gripper_horizontal(models):
    """Predescu and Stroe keep theta2 + theta3 + theta4 = 0; the position Jacobian of (theta1, theta2, theta3)
    is then square, with det = -a2 a3 sin(theta3) (a1 + a2 c2 + a3 c23 + d5): the elbow and the reach."""
    m = models["scorbot_er7"]
    q1, q2, q3, q4, q5 = m.q
    a1, a2, a3, d5 = params(m, "a1", "a2", "a3", "d5")
    horizontal = {q4: -q2 - q3}
    J = m.task_jacobian
    constrained = (J[:, :3] - J[:, 3] * sp.Matrix([[0, 1, 1]])).subs(horizontal)
    det = sp.trigsimp(sp.factor(sp.expand(constrained.det())))
    assert zero(det + a2 * a3 * s(q3) * (a1 + a2 * c(q2) + a3 * c(q2 + q3) + d5))


@pytest.mark.parametrize("name", DH_ROBOTS)
def test_determinant_matches_numpy(models, name):
    """The factored determinant equals numpy's det of the generated Jacobian (det J J^T when wide)."""
    m = models[name]
    k = kernels(name, "numpy")
    q = np.random.default_rng(11).uniform(-2, 2, (20, m.n))
    sing = m.singularities
    values = np.array([float(sing.determinant.subs(dict(zip(m.q, row))).subs(m.params)) for row in q])
    if m.rates.strategy == "square":
        expected = np.linalg.det(k.task_jacobian(q))
    elif m.rates.strategy == "wrist partition":
        expected = np.linalg.det(k.jacobian(q))
    else:
        Jx = k.task_jacobian(q)
        expected = np.linalg.det(Jx @ np.swapaxes(Jx, -1, -2))
    np.testing.assert_allclose(values, expected, rtol=1e-9, atol=1e-14)
    w, _ = k.manipulability(q)
    np.testing.assert_allclose(w, np.sqrt(np.abs(expected)) if m.rates.strategy == "wide" else np.abs(expected),
                               rtol=1e-9, atol=1e-14)


def singular_configurations(name, model):
    """Configurations on each singular set, solved by hand from the conditions."""
    P = {str(k): v for k, v in model.params.items()}
    if name in ("planar_2r", "adept_three", "planar_3r"):
        base = {"planar_2r": [0.3, 0.0], "planar_3r": [0.3, 0.0, 0.5], "adept_three": [0.3, 0.0, 0.1, 0.4]}[name]
        folded = list(base)
        folded[1] = np.pi
        return [base, folded]
    if name == "planar_rp":
        return [[0.7, 0.0]]
    if name == "scorbot_er7":
        a1, a2, a3, d5 = P["a1"], P["a2"], P["a3"], P["d5"]
        q2, q3 = np.pi / 2, 0.5  # shoulder: reach a1 + a2 c2 + a3 c23 + d5 c234 = 0
        q234 = np.arccos(-(a1 + a2 * np.cos(q2) + a3 * np.cos(q2 + q3)) / d5)
        return [[0.2, q2, q3, q234 - q2 - q3, 0.3], [0.2, 0.4, 0.0, 0.0, 0.3], [0.2, 0.4, np.pi, 0.0, 0.3]]
    if name == "puma560":
        a2, a3, d4 = P["a2"], P["a3"], P["d4"]
        elbow = np.arctan2(-d4, a3)  # a3 s3 + d4 c3 = 0
        q3 = -0.8
        shoulder = np.arctan2(a2 + a3 * np.cos(q3) - d4 * np.sin(q3), a3 * np.sin(q3) + d4 * np.cos(q3))
        return [[0.1, 0.3, elbow, 0.2, 0.6, 0.1], [0.1, shoulder, q3, 0.2, 0.6, 0.1], [0.1, 0.3, -0.8, 0.2, 0.0, 0.1]]
    return []


@pytest.mark.parametrize("name", DH_ROBOTS)
def test_singular_configurations_lose_rank_and_are_flagged(models, name):
    m = models[name]
    for backend in BACKENDS:
        k = kernels(name, backend)
        for q in singular_configurations(name, m):
            J = k.jacobian(q) if m.rates.strategy == "wrist partition" else k.task_jacobian(q)
            sigma = np.linalg.svd(J, compute_uv=False)
            assert sigma[min(J.shape) - 1] < 1e-12 * sigma[0], (q, sigma)
            w, singular = k.manipulability(q)
            assert singular and w < 1e-12


# --- inverse maps: round trips, minimum norm, damping -----------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", SQUARE + ["puma560"])
def test_inverse_velocity_and_acceleration_round_trip(models, name, backend):
    m = models[name]
    k = kernels(name, backend)
    q = regular_configurations(m, k, 30, seed=5)
    rng = np.random.default_rng(6)
    qd, qdd = rng.uniform(-1, 1, q.shape), rng.uniform(-1, 1, q.shape)
    back, singular = k.joint_velocity(q, k.task_velocity(q, qd))
    assert not singular.any()
    np.testing.assert_allclose(back, qd, rtol=1e-9, atol=1e-9)
    back, singular = k.joint_acceleration(q, qd, k.task_acceleration(q, qd, qdd))
    assert not singular.any()
    np.testing.assert_allclose(back, qdd, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_scorbot_inverse_is_the_minimum_norm_solution(models, backend):
    m = models["scorbot_er7"]
    k = kernels("scorbot_er7", backend)
    q = regular_configurations(m, k, 30, seed=8)
    rng = np.random.default_rng(9)
    xd, qd, xdd = rng.uniform(-1, 1, (len(q), 3)), rng.uniform(-1, 1, q.shape), rng.uniform(-1, 1, (len(q), 3))
    J = k.task_jacobian(q)
    solution, singular = k.joint_velocity(q, xd)
    assert not singular.any()
    np.testing.assert_allclose(solution, np.einsum("kij,kj->ki", np.linalg.pinv(J), xd), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", J, solution), xd, atol=1e-9)
    rhs = xdd - np.einsum("kij,kj->ki", k.task_jacobian_dot(q, qd), qd)
    solution, _ = k.joint_acceleration(q, qd, xdd)
    np.testing.assert_allclose(solution, np.einsum("kij,kj->ki", np.linalg.pinv(J), rhs), rtol=1e-9, atol=1e-9)


def damped_reference(J, b, rows, columns, L):
    """Damped least squares as the README documents it, in numpy (J square or wide)."""
    Sx, Sq = np.diag(L ** np.asarray(rows, float)), np.diag(L ** np.asarray(columns, float))
    Jn = np.linalg.solve(Sx, J) @ Sq
    # sqrt(det(Jn Jn^T)) as the product of the singular values: forming Jn Jn^T would square the
    # condition number, and near mu_0 = 1e-8 its determinant would drown in rounding.
    mu = float(np.prod(np.linalg.svd(Jn, compute_uv=False)))
    lam2 = LAMBDA_MAX**2 * max(0.0, 1 - (mu / MU0) ** 2)
    # Jn^T (Jn Jn^T + lambda^2 I)^-1 bn, through Jn's SVD: sum_i s_i / (s_i^2 + lambda^2) (u_i . bn) v_i
    # (the normal equations would lose eps / lambda^2 = 1e-10 to rounding, near the tolerance)
    U, sv, Vt = np.linalg.svd(Jn, full_matrices=False)
    xn = Vt.T @ (sv / (sv**2 + lam2) * (U.T @ np.linalg.solve(Sx, b)))
    return Sq @ xn, mu < MU0


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ["planar_2r", "planar_3r", "planar_rp", "adept_three", "scorbot_er7"])
def test_near_singularities_the_answer_is_damped_least_squares(models, name, backend):
    m = models[name]
    k = kernels(name, backend)
    scaling = m.rates.scaling
    L = float(scaling.length.subs(m.params))
    rng = np.random.default_rng(4)
    configurations = singular_configurations(name, m)
    # ... and just inside the threshold, where the damping is partial
    if name in ("planar_2r", "planar_3r", "adept_three"):
        near = list(configurations[0])
        near[1] = 0.5 * MU0 * L**2 / float(sp.Mul(*params(m, "l1", "l2")).subs(m.params))
        configurations.append(near)
    for q in configurations:
        xd = rng.uniform(-1, 1, len(m.task_names))
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no division by zero, no invalid value
            qd, singular = k.joint_velocity(q, xd)
        expected, expected_flag = damped_reference(k.task_jacobian(q), xd, scaling.rows, scaling.columns, L)
        assert singular and expected_flag
        # max-norm relative: the damped problem's condition number is about 1 / lambda_max^2 = 1e6,
        # so rounding alone moves its answer by eps / lambda_max^2 = 1e-10 of its size
        np.testing.assert_allclose(qd, expected, rtol=0, atol=1e-9 * max(1.0, np.abs(expected).max()))
        assert np.all(np.isfinite(qd)) and np.max(np.abs(qd)) < 1 / (2 * LAMBDA_MAX) * 10


@pytest.mark.parametrize("backend", BACKENDS)
def test_damping_switches_on_continuously_at_the_threshold(models, backend):
    m = models["planar_2r"]
    k = kernels("planar_2r", backend)
    L = float(m.rates.scaling.length.subs(m.params))
    at = MU0 * L**2 / (0.559 * 0.508)  # sin(q2) where mu = mu_0
    xd = np.array([0.3, -0.7])
    inside, flag_inside = k.joint_velocity([0.2, np.arcsin(at * (1 - 1e-9))], xd)
    outside, flag_outside = k.joint_velocity([0.2, np.arcsin(at * (1 + 1e-9))], xd)
    assert flag_inside and not flag_outside
    np.testing.assert_allclose(inside, outside, rtol=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_puma_wrist_singularity_damps_the_wrist_block_only(models, backend):
    m = models["puma560"]
    k = kernels("puma560", backend)
    L = float(m.rates.scaling.length.subs(m.params))
    twist = np.array([0.1, -0.2, 0.3, 0.5, -0.4, 0.2])
    for q in singular_configurations("puma560", m):
        J = k.jacobian(q)
        A, B, C, D = J[:3, :3], J[:3, 3:], J[3:, :3], J[3:, 3:]
        np.testing.assert_allclose(B, 0, atol=1e-15)  # Paul: the wrist does not move the wrist centre
        arm, _ = damped_reference(A, twist[:3], (1, 1, 1), (0, 0, 0), L)
        wrist, _ = damped_reference(D, twist[3:] - C @ arm, (0, 0, 0), (0, 0, 0), L)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            qd, singular = k.joint_velocity_from_twist(q, twist)
        assert singular
        np.testing.assert_allclose(qd, np.concatenate([arm, wrist]), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name", DH_ROBOTS)
def test_c_and_numpy_agree_on_the_rate_kernels(models, name):
    m = models[name]
    kn, kc = kernels(name, "numpy"), kernels(name, "c")
    rng = np.random.default_rng(12)
    q = np.concatenate([rng.uniform(-3, 3, (500, m.n)), np.array(singular_configurations(name, m)).reshape(-1, m.n)])
    qd, qdd = rng.uniform(-1, 1, q.shape), rng.uniform(-1, 1, q.shape)
    xd = rng.uniform(-1, 1, (len(q), len(m.task_names)))
    for f in m.rate_functions():
        args = {"q": q, "qd": qd, "qdd": qdd, "xd": xd, "xdd": xd, "twist": rng.uniform(-1, 1, (len(q), 6))}
        values = [args[a.name] for a in f.arguments]
        got_n, got_c = getattr(kn, f.name)(*values), getattr(kc, f.name)(*values)
        for a, b in zip(got_n if isinstance(got_n, tuple) else (got_n,), got_c if isinstance(got_c, tuple) else (got_c,)):
            if a.dtype == bool:
                np.testing.assert_array_equal(a, b, err_msg=f.name)
            else:
                np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=f.name)


# --- forward maps against finite differences --------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", DH_ROBOTS)
def test_rates_are_time_derivatives(models, name, backend):
    """x_dot = d/dt task(q + t q_dot), J_dot = d/dt J(q + t q_dot), x_ddot along q + t q_dot + t^2 q_ddot / 2."""
    k = kernels(name, backend)
    n = models[name].n
    rng = np.random.default_rng(13)
    q, qd, qdd = rng.uniform(-2, 2, (20, n)), rng.uniform(-1, 1, (20, n)), rng.uniform(-1, 1, (20, n))
    np.testing.assert_allclose(k.task_velocity(q, qd), derivative_along(k.task, q, qd), atol=1e-8)
    np.testing.assert_allclose(k.jacobian_dot(q, qd), derivative_along(k.jacobian, q, qd), atol=1e-8)
    np.testing.assert_allclose(k.task_jacobian_dot(q, qd), derivative_along(k.task_jacobian, q, qd), atol=1e-8)
    np.testing.assert_allclose(k.twist(q, qd), np.einsum("kij,kj->ki", k.jacobian(q), qd), atol=1e-14)
    h = 1e-4
    path = [k.task(q + t * qd + t * t / 2 * qdd) for t in (-h, 0.0, h)]
    np.testing.assert_allclose(k.task_acceleration(q, qd, qdd), (path[0] - 2 * path[1] + path[2]) / h**2, atol=1e-6)


# --- Paul's wrist partition -------------------------------------------------------------------

def test_paul_partition_is_the_slides_model_and_the_geometric_jacobian(models):
    m = models["puma560"]
    part = m.rates.partition
    frames = m.frames
    z = [f[:3, 2] for f in frames]
    o = [f[:3, 3] for f in frames]
    O_w = part.wrist_centre
    # Slides: A = [Z0 x O_wrist, Z1 x (O_wrist - O1), Z2 x (O_wrist - O2)], C = [Z0 Z1 Z2], D = [Z3 Z4 Z5]
    A = sp.Matrix.hstack(z[0].cross(O_w), z[1].cross(O_w - o[1]), z[2].cross(O_w - o[2]))
    assert (A - part.A).applyfunc(simplify_entry) == sp.zeros(3, 3)
    assert part.C == sp.Matrix.hstack(z[0], z[1], z[2]) and part.D == sp.Matrix.hstack(z[3], z[4], z[5])
    B = sp.Matrix.hstack(*[z[i].cross(O_w - o[i]) for i in (3, 4, 5)])
    assert B.applyfunc(simplify_entry) == sp.zeros(3, 3)
    assert (part.tool_jacobian - m.jacobian).applyfunc(simplify_entry) == sp.zeros(6, 6)


def test_paul_partition_with_a_tool_offset(tmp_path):
    """With a tool 0.1 m beyond the wrist centre, V_E = V_wrist + w x (O_E - O_wrist) still gives J."""
    text = derivations.ROBOTS["puma560"].read_text().replace('name = "puma560"', 'name = "puma_tool"')
    path = tmp_path / "puma_tool.toml"
    path.write_text(text + "\n[tool]\nxyz = [0, 0, 0.1]\n")
    m = derivations.load(path)
    from derivations.paul import wrist_blocks
    part = wrist_blocks(m)
    assert part.tool_offset.applyfunc(simplify_entry) == (m.fk[:3, 2] / 10).applyfunc(simplify_entry)
    assert (part.tool_jacobian - m.jacobian).applyfunc(simplify_entry) == sp.zeros(6, 6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_partitioned_inverse_equals_the_6x6_solve(models, backend):
    m = models["puma560"]
    k = kernels("puma560", backend)
    q = regular_configurations(m, k, 50, seed=14)
    twist = np.random.default_rng(15).uniform(-1, 1, (len(q), 6))
    qd, singular = k.joint_velocity_from_twist(q, twist)
    assert not singular.any()
    np.testing.assert_allclose(qd, np.linalg.solve(k.jacobian(q), twist[..., None])[..., 0], rtol=1e-9, atol=1e-9)


def test_puma_pose_rates_become_the_twist(models):
    """joint_velocity of the pose task goes through the twist: w from the skew part of R_dot R^T."""
    k = kernels("puma560", "numpy")
    q = regular_configurations(models["puma560"], k, 10, seed=16)
    qd = np.random.default_rng(17).uniform(-1, 1, q.shape)
    via_pose, _ = k.joint_velocity(q, k.task_velocity(q, qd))
    via_twist, _ = k.joint_velocity_from_twist(q, k.twist(q, qd))
    np.testing.assert_allclose(via_pose, via_twist, rtol=1e-10, atol=1e-10)


# --- Rehiara: the tool configuration vector -----------------------------------------------------

def rehiara_printed_eq40(m):
    q1, q2, d3, q4 = m.q
    l1, l2, d1, d4 = params(m, "l1", "l2", "d1", "d4")
    return sp.Matrix([l2 * c(q1 + q2) + l1 * c(q1), l2 * s(q1 + q2) + l1 * s(q1), -d4 - d3 + d1, 0, 0,
                      sp.exp(q4 / sp.pi)])


def rehiara_printed_eq42(m):
    q1, q2, d3, q4 = m.q
    l1, l2 = params(m, "l1", "l2")
    return sp.Matrix([[-l1 * s(q1) - l2 * s(q1 + q2), -l2 * s(q1 + q2), 0, 0],
                      [l1 * c(q1) + l2 * c(q1 + q2), l2 * c(q1 + q2), 0, 0],
                      [0, 0, -1, 0], [0, 0, 0, 0], [0, 0, 0, 0],
                      [0, 0, 0, sp.exp(q4 / sp.pi) / sp.pi]])


def test_rehiara_eq42_is_the_derivative_of_the_printed_eq40(models):
    m = models["adept_three"]
    assert rehiara_printed_eq40(m).jacobian(sp.Matrix(m.q)) == rehiara_printed_eq42(m)


def test_E3_rehiara_eq40_sign_of_the_scaled_approach_vector(models):
    """Erratum E3: Eq. 39 with Eq. 13's approach vector a = (0, 0, -1) gives w6 = -exp(theta4/pi);
    Eq. 40 prints +exp(theta4/pi), and Eq. 42 inherits the sign."""
    m = models["adept_three"]
    q4 = m.q[3]
    assert m.fk[:3, 2] == sp.Matrix([0, 0, -1])  # also the third column of the printed Eq. 13
    derived = outputs(m, "tool_configuration")
    printed = rehiara_printed_eq40(m)
    assert all(zero(e) for e in (derived - printed)[:5, :])
    assert derived[5] == -sp.exp(q4 / sp.pi) and printed[5] == sp.exp(q4 / sp.pi)
    Jw = sp.Matrix(6, 4, function(m, "tool_configuration_jacobian").outputs[0].values)
    assert all(zero(e) for e in (Jw - rehiara_printed_eq42(m))[:5, :])
    assert Jw[5, 3] == -rehiara_printed_eq42(m)[5, 3]


def test_rehiara_direct_jacobian_and_the_geometric_jacobian(models):
    """Rehiara calls the first 3x3 of Eq. 42 the direct Jacobian, "square and invertible": det = -l1 l2 sin(theta2),
    invertible except at the elbow singularity.  Side by side, the geometric Jacobian shares rows 1-3 (dp/dq) and
    has the angular velocity w_z = q1_dot + q2_dot - q4_dot where Eq. 42 has d(+-exp(theta4/pi))/dq."""
    m = models["adept_three"]
    q1, q2, d3, q4 = m.q
    l1, l2 = params(m, "l1", "l2")
    direct = rehiara_printed_eq42(m)[:3, :3]
    assert zero(direct.det() + l1 * l2 * s(q2))
    Jw = sp.Matrix(6, 4, function(m, "tool_configuration_jacobian").outputs[0].values)
    assert (m.jacobian[:3, :] - Jw[:3, :]).applyfunc(simplify_entry) == sp.zeros(3, 4)
    assert m.jacobian[3:, :] == sp.Matrix([[0, 0, 0, 0], [0, 0, 0, 0], [1, 1, 0, -1]])


@pytest.mark.parametrize("backend", BACKENDS)
def test_tool_configuration_kernels(models, backend):
    k = kernels("adept_three", backend)
    rng = np.random.default_rng(18)
    q = rng.uniform(-2, 2, (20, 4))
    numeric = np.stack([derivative_along(k.tool_configuration, q, np.eye(4)[i]) for i in range(4)], axis=-1)
    np.testing.assert_allclose(k.tool_configuration_jacobian(q), numeric, atol=1e-8)
    np.testing.assert_allclose(k.tool_configuration(q)[..., 5], -np.exp(q[..., 3] / np.pi), rtol=1e-15)


# --- contract: shapes, bad input, reserved names ------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_rate_kernels_broadcast_and_reject_bad_input(backend):
    k = kernels("planar_2r", backend)
    q = np.random.default_rng(0).uniform(-1, 1, (4, 3, 2))
    qd, singular = k.joint_velocity(q, np.array([0.1, 0.2]))
    assert qd.shape == (4, 3, 2) and singular.shape == (4, 3) and singular.dtype == bool
    w, flag = k.manipulability(q[0, 0])
    assert w.shape == () and flag.shape == ()
    assert k.task_jacobian_dot(q, q).shape == (4, 3, 2, 2) and k.jacobian_dot(q, q).shape == (4, 3, 6, 2)
    assert k.task_acceleration(q, q, q).shape == (4, 3, 2) and k.twist(q, q).shape == (4, 3, 6)
    with pytest.raises(ValueError, match=r"expected xd of shape \(\.\.\., 2\), got shape \(3,\)"):
        k.joint_velocity([0.1, 0.2], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="qd contains NaN or inf"):
        k.task_velocity([0.1, 0.2], [np.nan, 0.0])
    with pytest.raises(ValueError, match=r"^joint_velocity: the batch dimensions \(all but the last axis\) of "
                                         r"q \(3, 2\), xd \(4, 2\) do not broadcast$"):
        k.joint_velocity(np.zeros((3, 2)), np.zeros((4, 2)))


@pytest.mark.parametrize("name", ["qd1", "qdd2", "xd_x", "twist_vx"])
def test_parameter_names_cannot_shadow_rate_arguments(name):
    from derivations.description import DescriptionError, parse_description
    text = f'name = "arm"\n[params]\n{name} = 1.0\n[[joint]]\ntype = "R"\na = "{name}"\n'
    with pytest.raises(DescriptionError, match="not a valid parameter name"):
        parse_description(text, "robot.toml")


TALL = """
name = "tall_rr"
task = ["x", "y", "z"]
[params]
l1 = 0.5
l2 = 0.3
[[joint]]
type = "R"
a = "l1"
alpha = "pi/2"
[[joint]]
type = "R"
a = "l2"
"""


def test_a_tall_task_jacobian_gets_the_least_squares_inverse(tmp_path):
    """A user's arm with two joints and task (x, y, z): joint_velocity is the least-squares solution."""
    path = tmp_path / "tall.toml"
    path.write_text(TALL)
    m = derivations.load(path)
    assert m.rates.strategy == "tall"
    rng = np.random.default_rng(19)
    for _ in range(3):
        point = {qi: float(v) for qi, v in zip(m.q, rng.uniform(0.3, 1.2, 2))}
        point.update({x: float(v) for x, v in zip(m.rates.xd, rng.uniform(-1, 1, 3))})
        point.update(m.params)
        J = np.array(m.task_jacobian.subs(point).evalf(), dtype=float)
        xd = np.array([point[x] for x in m.rates.xd])
        qd = np.array(m.rates.joint_velocity.subs(point).evalf(), dtype=float).ravel()
        np.testing.assert_allclose(qd, np.linalg.lstsq(J, xd, rcond=None)[0], rtol=1e-10)

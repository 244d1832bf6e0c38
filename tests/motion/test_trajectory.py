"""Time laws and interpolated motion: Predescu and Stroe Eqs. 4.1 and 4.8, the velocity-model slides.

Expected values come from the papers (cited), or from mathematics: boundary
conditions, areas under velocity profiles, finite differences.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

import derivations
from codegen import build, generate
from codegen.verify import verify_model
from conftest import kernels
from derivations import trajectory as tr
from derivations.trajectory import t

BACKENDS = ["numpy", "c"]


def at(expr, time):
    return expr.subs(t, time)


# -- the polynomial laws -------------------------------------------------------------------

def test_cubic_meets_its_boundary_conditions():
    q0, qf, T, v0, vf = sp.symbols("q0 qf T v0 vf", real=True)
    law = tr.cubic(q0, qf, T, v0, vf)
    assert sp.Poly(law, t).degree() == 3
    q, v, _ = tr.position_velocity_acceleration(law)
    assert [sp.simplify(e) for e in (at(q, 0) - q0, at(v, 0) - v0, at(q, T) - qf, at(v, T) - vf)] == [0] * 4


def test_quintic_meets_its_boundary_conditions():
    q0, qf, T, v0, vf, a0, af = sp.symbols("q0 qf T v0 vf a0 af", real=True)
    law = tr.quintic(q0, qf, T, v0, vf, a0, af)
    assert sp.Poly(law, t).degree() == 5
    q, v, a = tr.position_velocity_acceleration(law)
    residuals = [at(q, 0) - q0, at(v, 0) - v0, at(a, 0) - a0, at(q, T) - qf, at(v, T) - vf, at(a, T) - af]
    assert [sp.simplify(e) for e in residuals] == [0] * 6


def test_rest_to_rest_laws_have_the_textbook_coefficients():
    # 3 s^2 - 2 s^3 and 10 s^3 - 15 s^4 + 6 s^5 on the unit interval
    assert tr.cubic(0, 1, 1) == 3 * t**2 - 2 * t**3
    assert tr.quintic(0, 1, 1) == 10 * t**3 - 15 * t**4 + 6 * t**5


def test_cubic_with_zero_end_velocities_has_the_form_of_eq_4_1():
    # Predescu and Stroe Eq. 4.1: theta2 = 13.4685 + 3.3946 t^2 - 0.2263 t^3 over 10 s, i.e. the cubic
    # q0 + 3 D t^2 / T^2 - 2 D t^3 / T^3 with D = 3.3946 T^2 / 3 = 113.15 deg.
    D = sp.Rational(33946, 10000) * 100 / 3
    law = tr.cubic(sp.Rational(134685, 10000), sp.Rational(134685, 10000) + D, 10)
    coefficients = sp.Poly(law, t).all_coeffs()  # t^3, t^2, t, 1
    assert coefficients[1] == sp.Rational(33946, 10000) and coefficients[2] == 0
    assert coefficients[3] == sp.Rational(134685, 10000)
    assert round(float(coefficients[0]), 4) == -0.2263


def test_cycloidal_law_is_eq_4_8_and_starts_and_stops_at_rest():
    theta_i, A0, omega0 = sp.symbols("theta_i A0 omega0", positive=True)
    printed = theta_i + A0 * omega0 / (2 * sp.pi) * (t - sp.sin(omega0 * t) / omega0)  # Eq. 4.8 in rad
    law = tr.cycloidal(theta_i, A0, omega0)
    assert sp.simplify(law - printed) == 0
    q, v, a = tr.position_velocity_acceleration(law)
    period = 2 * sp.pi / omega0
    assert sp.simplify(at(q, period) - (theta_i + A0)) == 0
    assert [sp.simplify(at(e, x)) for e in (v, a) for x in (0, period)] == [0] * 4


# -- trapezoid and synchronisation (velocity-model slides) -----------------------------------

def test_slides_worked_example_interpolated_motion():
    """Slides, "Numerical Example": L_x = 110 cm, v_x = 11 cm/s, t_ax = 2 s, t_dx = 3 s -> t_mx = 7.5 s,
    12.5 s in all; L_y = 70 cm with t_ay = 1 s, t_dy = 1.5 s -> t_my = 10 s and v_y = 6.222 cm/s."""
    x, y = tr.synchronize([110, 70], [11, 11], [2, 1], [3, sp.Rational(3, 2)])
    assert x.cruise_velocity == 11 and x.cruise_time == sp.Rational(15, 2) and x.duration == sp.Rational(25, 2)
    assert y.duration == sp.Rational(25, 2) and y.cruise_time == 10
    assert y.cruise_velocity == sp.Rational(56, 9)  # 70 / (0.5 + 0.75 + 10)
    assert round(float(y.cruise_velocity), 3) == 6.222
    # the slides' own equation for L_x holds
    assert x.accel_time * 11 / 2 + x.cruise_time * 11 + x.decel_time * 11 / 2 == 110


def test_synchronize_takes_one_value_for_all_axes_and_floats():
    x, y = tr.synchronize([1.10, 0.70], 0.11, [2.0, 1.0], [3.0, 1.5])
    assert float(x.duration) == pytest.approx(12.5, abs=1e-12)
    assert float(y.cruise_velocity) == pytest.approx(0.06222222222222222, abs=1e-15)


def test_the_slowest_axis_sets_the_duration_whichever_it_is():
    a, b, c = tr.synchronize([10, -40, 5], [10, 20, 1], [1, 1, 1], [1, 1, 1])
    # alone: 1 + 1 = 2 s, 2 + 1 = 3 s, 5 + 1 = 6 s; the third axis is the slowest
    assert a.duration == b.duration == c.duration == 6
    assert c.cruise_velocity == 1 and b.cruise_velocity == sp.Rational(-40, 5)  # a backward move keeps its sign
    for axis in (a, b, c):
        position = axis.position()
        assert at(position, axis.duration) == axis.length and at(position, 0) == 0


@pytest.mark.parametrize("length, speed, ta, td", [(110, 11, 2, 3), (70, sp.Rational(56, 9), 1, sp.Rational(3, 2)),
                                                     (-2, 1, sp.Rational(1, 2), sp.Rational(1, 4))])
def test_trapezoid_is_continuous_and_its_velocity_area_is_the_length(length, speed, ta, td):
    length, speed, ta, td = (sp.S(x) for x in (length, speed, ta, td))
    law = tr.trapezoid(length, speed, ta, td)
    q, v, a = tr.position_velocity_acceleration(law)
    T = abs(length) / speed + (ta + td) / 2
    assert sp.integrate(v, (t, 0, T)) == length
    for corner in (0, ta, T - td, T):  # position and velocity continuous at every phase change
        for e in (q, v):
            assert sp.limit(e, t, corner, "-") == sp.limit(e, t, corner, "+")
    sign = 1 if length > 0 else -1
    assert at(v, (ta + T - td) / 2) == sign * speed          # cruising
    assert at(a, ta / 2) == sign * speed / ta                # uniform acceleration
    assert at(a, T - td / 2) == -sign * speed / td           # uniform deceleration
    assert at(q, -1) == 0 and at(q, T + 1) == length         # at rest outside the move


@pytest.mark.parametrize("call, message", [
    (lambda: tr.cubic(0, 1, 0), "duration must be > 0 s"),
    (lambda: tr.cubic(0, 1, -2), "duration must be > 0 s"),
    (lambda: tr.quintic(0, 1, float("inf")), "duration must be a finite real number"),
    (lambda: tr.cubic("zero", 1, 1), "q0 must be a real number"),
    (lambda: tr.cubic(0, 1 + 2j, 1), "qf must be a finite real number"),
    (lambda: tr.cycloidal(0, 1, 0), "omega must be > 0"),
    (lambda: tr.trapezoid(0, 1, 1, 1), "zero-length move"),
    (lambda: tr.trapezoid(1, 1, -1, 1), "accel_time must be > 0 s"),
    (lambda: tr.trapezoid(1, 1, 1, 0), "decel_time must be > 0 s"),
    (lambda: tr.trapezoid(1, 0, 1, 1), "speed must be > 0"),
    (lambda: tr.trapezoid(1, 1, 1, 2), r"phases cover .* = 3/2 > \|length\| = 1"),
    (lambda: tr.synchronize([110, 0], 11, 1, 1), "axis 1: a zero-length move"),
    (lambda: tr.synchronize([110, 70], 11, [2, -1], 1), "axis 1: accel time must be > 0 s, got -1"),
    (lambda: tr.synchronize([10, 70], 11, 2, 3), r"axis 0: .* cover 55/2 > \|length\| = 10"),
    (lambda: tr.synchronize([110, 70], [11], 1, 1), "max_velocities has 1 entries for 2 axes"),
    (lambda: tr.synchronize([], 11, 1, 1), "non-empty sequence"),
    (lambda: tr.synchronize([sp.Symbol("L")], 1, 1, 1), "must be a number"),
])
def test_impossible_moves_are_refused_naming_the_constraint(call, message):
    with pytest.raises(tr.TrajectoryError, match=message):
        call()


# -- generated kernels ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def trajectory_kernels():
    return derivations.load_kernel_set("trajectory")


def test_every_time_law_kernel_matches_sympy_at_30_digits(trajectory_kernels):
    checks = verify_model(trajectory_kernels, {b: kernels("trajectory", b) for b in BACKENDS}, samples=25, seed=11)
    assert len(checks) == 4 * 2
    assert not [c for c in checks if not c.ok], checks


def test_trajectory_c_compiles_strictly_and_runs_clean_under_sanitizers(trajectory_kernels):
    package = generate.GENERATED / "trajectory"
    build.compile_strict(package, "trajectory")
    # the driver needs the entry points only, not the CSE of a render (generate.entry_points)
    assert build.sanitizer_run(package, "trajectory", generate.entry_points(trajectory_kernels), 0).count("\n") >= 8


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernels_sample_the_derivations_laws(backend):
    k = kernels("trajectory", backend)
    times = np.linspace(-0.5, 13.0, 55)
    cases = [
        (k.cubic, [0.2, 1.4, 10.0, 0.05, -0.1], tr.cubic(0.2, 1.4, 10, 0.05, -0.1)),
        (k.quintic, [0.2, 1.4, 10.0, 0.05, -0.1, 0.01, 0.02], tr.quintic(0.2, 1.4, 10, 0.05, -0.1, 0.01, 0.02)),
        (k.cycloidal, [0.235, 1.975, np.pi / 5], tr.cycloidal(0.235, 1.975, sp.pi / 5)),
        (k.trapezoid, [70.0, 56 / 9, 1.0, 1.5], tr.trapezoid(70, sp.Rational(56, 9), 1, sp.Rational(3, 2))),
    ]
    for kernel, arguments, law in cases:
        state, valid = kernel(times[:, None], arguments)
        assert state.shape == (55, 3) and valid.shape == (55,) and valid.all()
        expected = np.array([[float(at(e, sp.Rational(x))) for e in tr.position_velocity_acceleration(law)]
                             for x in times])
        np.testing.assert_allclose(state, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernel_velocity_and_acceleration_are_derivatives_of_position(backend):
    k = kernels("trajectory", backend)
    times = np.linspace(0.3, 9.7, 30)[:, None]
    h = 1e-5
    for kernel, arguments in ((k.cubic, [0, 1, 10, 0.1, 0]), (k.quintic, [0, 1, 10, 0, 0.1, 0, 0.01]),
                              (k.cycloidal, [0.235, 1.975, np.pi / 5])):
        (state, _), (ahead, _), (behind, _) = (kernel(times + d, arguments) for d in (0.0, h, -h))
        np.testing.assert_allclose(state[:, 1], (ahead[:, 0] - behind[:, 0]) / (2 * h), atol=1e-8)
        np.testing.assert_allclose(state[:, 2], (ahead[:, 1] - behind[:, 1]) / (2 * h), atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernels_flag_inputs_that_describe_no_move(backend):
    k = kernels("trajectory", backend)
    with np.errstate(divide="ignore", invalid="ignore"):
        assert k.cubic([[1.0]], [[0, 1, 0.0, 0, 0], [0, 1, -1.0, 0, 0], [0, 1, 2.0, 0, 0]])[1].tolist() == [
            False, False, True]
        assert k.cycloidal([1.0], [0, 1, -1.0])[1].item() is False
        profiles = [[0, 1, 1, 1], [1, 1, 1, 2], [1, 1, 0, 1], [1, -1, 0.5, 0.5], [1, 1, 0.5, 0.5], [-1, 1, 1, 1]]
        assert k.trapezoid([1.0], profiles)[1].tolist() == [False, False, False, False, True, True]


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernels_broadcast_times_against_laws_and_check_shapes(backend):
    k = kernels("trajectory", backend)
    times = np.linspace(0, 10, 7)[:, None]                         # (7, 1)
    laws = np.array([[0, 1, 10, 0, 0], [1, 0, 5, 0, 0]])[:, None]  # (2, 1, 5)
    state, valid = k.cubic(times, laws)
    assert state.shape == (2, 7, 3) and valid.shape == (2, 7)
    with pytest.raises(ValueError, match=r"expected time of shape \(\.\.\., 1\), got shape \(7,\)"):
        k.cubic(np.linspace(0, 1, 7), [0, 1, 10, 0, 0])
    with pytest.raises(ValueError, match=r"expected boundary of shape \(\.\.\., 5\)"):
        k.cubic(times, [0, 1, 10])
    with pytest.raises(ValueError, match="NaN or inf"):
        k.trapezoid([[np.nan]], [1, 1, 0.1, 0.1])


RENDER = "import json, sys; from codegen.generate import render_tree; json.dump(render_tree(['{0}']), sys.stdout)"


@pytest.mark.parametrize("name", ["trajectory", "scorbot_path"])
def test_kernel_sets_generate_byte_identical_files_from_a_cold_derivation(name):
    """Derived cold (no cache) in a process with a hash seed of its own, the kernel set renders the
    committed files of generated/ byte for byte.  Those were rendered by other processes, with other
    seeds and from the cache, and test_codegen's tree check renders them again from the cache (hash
    seed 12345): so the files depend on neither.  One cold render is enough: the committed files
    stand for the second seed and the warm render this test once made beside it."""
    env = dict(os.environ, PYTHONHASHSEED="4242", KINEGEN_NO_CACHE="1")
    result = subprocess.run([sys.executable, "-c", RENDER.format(name)], capture_output=True, text=True,
                            env=env, check=True)
    tree = json.loads(result.stdout)
    del tree["__init__.py"]  # the package list of a tree of this set alone
    assert tree and all(path.startswith(f"{name}/") for path in tree)
    assert generate.stale_files(tree) == []

"""The generated AVR 3000 kernels: the paper's numbers, round trips, unreachable and singular input, the script."""
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

import generated
from codegen import cli
from derivations.motor_limits import INCH, axis_limits, ramp_acceleration

BACKENDS = ["numpy", "c"]
A = 10.5 * INCH
RPM_TR = 4500 / 60 * 8192  # counts/s at 4500 rpm (2048 lines x 4)


@pytest.fixture(params=BACKENDS)
def k(request):
    return generated.load("avr3000", backend=request.param)


def relative(got, want):
    """Max-norm relative error per coordinate over a batch (absolute where the coordinate is all zero)."""
    scale = np.maximum(np.max(np.abs(want), axis=tuple(range(want.ndim - 1))), 1e-300)
    return float(np.max(np.abs(got - want) / scale))


def motor_positions(k, rng, count):
    """Motor positions whose q2 lies in (0.2, 2 pi - 0.2): inside the one branch of Eq. 8, away from its ends."""
    tool = np.stack([rng.uniform(-3, 3, count), rng.uniform(-1.9 * A, 1.9 * A, count),
                     rng.uniform(0, 6 * INCH, count)], -1)
    return k.tool_to_motor(tool)


def test_module_constants_and_names(k):
    assert k.GEAR_T == 1.0
    assert k.GEAR_R == pytest.approx(-0.47935881, abs=5e-9)  # Sotirov section 4, sign from the model
    assert k.JOINTS == ("q1", "q2", "q3") and k.TASK == ("T", "R", "Z") and k.BRANCHES == ("principal",)
    for name in ("motor_to_joint", "joint_to_tool_velocity", "tool_to_joint_acceleration",
                 "motor_to_cartesian_velocity", "cartesian_to_motor_acceleration"):
        assert callable(getattr(k, name))


def test_matlab_script_position_example(k):
    """Sotirov section 6: R = 18.3 in at T = 0 gives q2 = 1.025378 rad and the tip at x = 0, y = 18.3 in."""
    tool = np.array([0.0, 18.3 * INCH, 0.0])
    q = k.tool_to_joint(tool)
    assert q[1] == pytest.approx(1.025378, abs=5e-7)
    assert q[0] == pytest.approx((math.pi - q[1]) / 2, abs=1e-15)  # the script's q1 = (pi - q2)/2
    for tip in (k.tool_to_cartesian(tool), k.joint_to_cartesian(q), k.fk(q)[:3, 3]):
        np.testing.assert_allclose(tip / INCH, [0.0, 18.3, 0.0], atol=1e-12)


def test_pure_r_and_pure_t_motion_at_18_3_in(k):
    """Section 4 gears at 4500 rpm: pure R gives Tdot = 0, |Rdot| = 121.886 in/s; pure T gives Rdot = 0."""
    motor = k.tool_to_motor([0.0, 18.3 * INCH, 0.0])
    pure_r = np.array([k.GEAR_R * -RPM_TR, -RPM_TR, 0.0])  # the script's [0.4794 x, -1 x] 4500 rpm
    pure_t = np.array([RPM_TR, k.GEAR_T * RPM_TR, 0.0])
    T_dot, R_dot, Z_dot = k.motor_to_tool_velocity(motor, pure_r)
    assert abs(T_dot) < 1e-12 * 24.7 and Z_dot == 0
    assert abs(R_dot) / INCH == pytest.approx(121.886, abs=5e-4)
    T_dot, R_dot, Z_dot = k.motor_to_tool_velocity(motor, pure_t)
    assert R_dot == 0 and abs(T_dot) > 20
    # Cartesian: at T = 0 the arm points along y, so pure R moves the tip along y only.
    xyz = k.motor_to_cartesian_velocity(motor, pure_r)
    assert abs(xyz[0]) < 1e-12 and xyz[1] / INCH == pytest.approx(-121.886, abs=5e-4)


@pytest.mark.parametrize("level", ["position", "velocity", "acceleration"])
def test_round_trip_motor_tool_motor(k, level):
    rng = np.random.default_rng(3)
    motor = motor_positions(k, rng, 2000)
    rates = [rng.uniform(-RPM_TR, RPM_TR, (2000, 3)), rng.uniform(-1e7, 1e7, (2000, 3))]
    suffix = "" if level == "position" else f"_{level}"
    count = {"position": 0, "velocity": 1, "acceleration": 2}[level]
    given = ([motor] + rates)[:count + 1]
    tool = getattr(k, f"motor_to_tool{suffix}")(*given)
    tool_args = [k.motor_to_tool(motor)] + ([k.motor_to_tool_velocity(motor, rates[0])] if count >= 1 else [])
    back = getattr(k, f"tool_to_motor{suffix}")(*(tool_args[:count] + [tool]))
    assert relative(back, given[-1]) < 1e-12


@pytest.mark.parametrize("level", ["position", "velocity", "acceleration"])
@pytest.mark.parametrize("branch, seed", [("", 4), ("_reversed", 14)], ids=["first", "reversed"])
def test_round_trip_cartesian_motor_cartesian(k, level, branch, seed):
    """Both Cartesian branches (R - e = +-sqrt(x^2 + y^2)) reach the point back, at every level."""
    rng = np.random.default_rng(seed)
    angle, radius = rng.uniform(-math.pi, math.pi, 2000), rng.uniform(0.05, 1.9 * A, 2000)
    cart = np.stack([radius * np.sin(angle), radius * np.cos(angle), rng.uniform(0, 0.15, 2000)], -1)
    rates = [rng.uniform(-2, 2, (2000, 3)), rng.uniform(-20, 20, (2000, 3))]
    count = {"position": 0, "velocity": 1, "acceleration": 2}[level]
    suffix = "" if level == "position" else f"_{level}"
    given = ([cart] + rates)[:count + 1]
    to_motor = f"cartesian_to_motor{branch}"
    motor = getattr(k, f"{to_motor}{suffix}")(*given)
    motor_args = [getattr(k, to_motor)(cart)] + ([getattr(k, f"{to_motor}_velocity")(cart, rates[0])] if count else [])
    back = getattr(k, f"motor_to_cartesian{suffix}")(*(motor_args[:count] + [motor]))
    assert relative(back, given[-1]) < 1e-12


def test_the_two_cartesian_branches_differ_by_half_a_turn_and_fold_through_the_axis(k):
    rng = np.random.default_rng(15)
    e = 0.02
    angle, radius = rng.uniform(-math.pi, math.pi, 500), rng.uniform(0.01, 0.4, 500)
    cart = np.stack([radius * np.sin(angle), radius * np.cos(angle), rng.uniform(0, 0.15, 500)], -1)
    first, second = k.cartesian_to_tool(cart, e=e), k.cartesian_to_tool_reversed(cart, e=e)
    np.testing.assert_allclose(first[:, 1] - e, radius, rtol=1e-14)
    np.testing.assert_allclose(second[:, 1] - e, -radius, rtol=1e-14)  # R - e = -sqrt(x^2 + y^2)
    turn = np.mod(second[:, 0] - first[:, 0], 2 * math.pi)
    np.testing.assert_allclose(turn, math.pi, atol=1e-14)
    assert (np.abs(second[:, 0]) <= math.pi).all()
    np.testing.assert_allclose(second[:, 2], cart[:, 2], rtol=0, atol=0)
    for tool in (first, second):
        assert relative(k.tool_to_cartesian(tool, e=e), cart) < 1e-14
    # Joints on the two branches: both reach the point.
    for joints in (k.cartesian_to_joint(cart, e=e), k.cartesian_to_joint_reversed(cart, e=e)):
        assert relative(k.joint_to_cartesian(joints, e=e), cart) < 1e-12


def test_the_reversed_branch_reaches_where_the_first_cannot_with_an_end_effector(k):
    """With e > 0 the first branch needs R = e + rho <= 2a; the reversed one R = e - rho >= -2a."""
    point = [0.0, 2 * A - 0.01, 0.05]  # rho = 2a - 1 cm
    with pytest.raises(ValueError, match="unreachable"):
        k.cartesian_to_joint(point, e=0.02)
    joints = k.cartesian_to_joint_reversed(point, e=0.02)
    np.testing.assert_allclose(k.joint_to_cartesian(joints, e=0.02), point, rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="singular: the tip is on the T axis"):
        k.cartesian_to_tool_reversed([0.0, 0.0, 0.1])


def test_velocity_maps_are_time_derivatives_of_the_position_maps(k):
    """Central differences along a path x(t) = x0 + v t + w t^2/2 check velocity and acceleration maps."""
    rng = np.random.default_rng(5)
    for source, target in (("tool", "joint"), ("motor", "cartesian"), ("cartesian", "motor")):
        if source == "motor":
            x0 = motor_positions(k, rng, 50)
            v, w = rng.uniform(-1e3, 1e3, (50, 3)), rng.uniform(-1e3, 1e3, (50, 3))
        else:
            x0 = k.joint_to_tool([[0.3, 2.0, 0.05]] * 50) if source == "tool" else \
                k.joint_to_cartesian(np.stack([rng.uniform(-3, 3, 50), rng.uniform(0.5, 2.5, 50),
                                               rng.uniform(0, 0.1, 50)], -1))
            v, w = rng.uniform(-0.1, 0.1, (50, 3)), rng.uniform(-0.1, 0.1, (50, 3))
        forward = getattr(k, f"{source}_to_{target}")
        h = 1e-4
        path = [forward(x0 + v * t + w * t * t / 2) for t in (-h, 0.0, h)]
        velocity = getattr(k, f"{source}_to_{target}_velocity")(x0, v)
        acceleration = getattr(k, f"{source}_to_{target}_acceleration")(x0, v, w)
        assert relative((path[2] - path[0]) / (2 * h), velocity) < 1e-6, (source, target)
        assert relative((path[2] - 2 * path[1] + path[0]) / (h * h), acceleration) < 1e-4, (source, target)


def test_ik_contract_gives_the_tool_pose_back(k):
    rng = np.random.default_rng(6)
    tool = np.stack([rng.uniform(-3, 3, 500), rng.uniform(-2 * A, 2 * A, 500), rng.uniform(0, 0.15, 500)], -1)
    Q, valid = k.ik(tool)
    assert Q.shape == (500, 1, 3) and valid.shape == (500, 1) and valid.all()
    back = k.task(Q[:, 0])
    turn = back[:, 0] - tool[:, 0]
    assert np.abs(turn - 2 * np.pi * np.round(turn / (2 * np.pi))).max() < 1e-14  # T modulo 2 pi (q1 is wrapped)
    assert np.abs(Q[:, 0, 0]).max() <= np.pi  # q1 wrapped to (-pi, pi]
    np.testing.assert_allclose(back[:, 1:], tool[:, 1:], rtol=0, atol=1e-15)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Q, valid = k.ik([[0.0, 2.5 * A, 0.0], [0.0, -2.01 * A, 0.0]])
    assert not valid.any() and np.isfinite(Q).all()  # reported, never a NaN


def test_ik_keeps_q2_in_0_to_2pi_as_its_docstring_says(k):
    """q2 enters the pose as q2 / 2: wrapped to (-pi, pi] it would name another configuration (the
    fuzz found the docstring promising the wrap).  q2 = 4 rad, inside the limits, comes back as 4."""
    assert "q2 = 2 acos(R / 2a) stays in [0, 2 pi]" in " ".join(k.ik.__doc__.split()) or \
        "q2 = 2 acos(R / 2a) stays in [0, 2 pi]" in " ".join(generated.load("avr3000").ik.__doc__.split())
    q = np.array([0.3, 4.0, 0.05])
    Q, valid = k.ik(k.task(q))
    assert valid.all() and abs(Q[0, 1] - 4.0) < 1e-12 and k.within_limits(Q).all()
    moved = Q[0].copy()
    moved[1] -= 2 * np.pi  # what a wrap would give: another pose
    assert np.abs(k.task(moved) - k.task(q)).max() > 0.1


@pytest.mark.parametrize("R", [2.0000001 * A, -2.5 * A, 1.0])
def test_unreachable_radius_raises_naming_the_problem(k, R):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no floating-point warning before the error either
        for name, args in (("tool_to_joint", ([0.1, R, 0.0],)), ("tool_to_motor_velocity", ([0.1, R, 0], [1, 1, 1])),
                           ("tool_to_joint_acceleration", ([0.1, R, 0], [1, 1, 1], [1, 1, 1]))):
            with pytest.raises(ValueError, match=rf"{name}: unreachable: the links reach \|R\| <= 2a"):
                getattr(k, name)(*args)
    module = sys.modules[k.__name__.rsplit(".", 1)[0] + "._runtime"]
    with pytest.raises(module.UnreachableError, match=r"at batch index \(1,\)"):
        k.tool_to_joint([[0.1, 0.2, 0.0], [0.1, R, 0.0], [0.0, 0.0, 0.0]])


def test_cartesian_target_beyond_reach_or_on_the_axis(k):
    assert np.isfinite(k.cartesian_to_joint([0.3, 0.3, 0.0])).all()  # R = 0.424 m < 2a = 0.533 m
    with pytest.raises(ValueError, match="unreachable"):
        k.cartesian_to_joint([0.3, 0.3, 0.0], e=0.2)  # R = e + 0.424 m > 2a = 0.533 m
    with pytest.raises(ValueError, match="singular: the tip is on the T axis"):
        k.cartesian_to_tool([0.0, 0.0, 0.1])


@pytest.mark.parametrize("q2", [0.0, 2 * math.pi])
def test_fully_extended_arm_is_singular_for_inverse_velocity_and_acceleration(k, q2):
    """q2 = 0 or 2 pi: sin(q2/2) = 0 in Eqs. 9-10.  Position maps still work; the rate maps report singular."""
    tool = k.joint_to_tool([0.4, q2, 0.0])
    assert abs(tool[1]) == pytest.approx(2 * A, rel=1e-15)
    q = k.tool_to_joint(tool)  # the position inverse exists at the boundary
    assert q[1] == pytest.approx(q2, abs=1e-7)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name, extra in (("tool_to_joint_velocity", 1), ("tool_to_motor_acceleration", 2)):
            with pytest.raises(ValueError, match="singular: sin\\(q2/2\\) = 0: the arm is fully extended"):
                getattr(k, name)(tool, *[[0.1, 0.1, 0.1]] * extra)


def test_just_inside_the_singularity_rates_are_finite_or_reported(k):
    """Never an inf or NaN: the singular check tests the very radicand the kernels divide by."""
    edge = [np.nextafter(2 * A, 0), np.nextafter(np.nextafter(2 * A, 0), 0), np.nextafter(-2 * A, 0)]
    for R in edge:
        for name in ("tool_to_joint_velocity", "tool_to_motor_acceleration"):
            args = [[0.0, R, 0.0]] + [[0.1, 0.1, 0.1]] * (1 if name.endswith("velocity") else 2)
            try:
                out = getattr(k, name)(*args)
            except ValueError as exc:
                assert "singular" in str(exc) or "unreachable" in str(exc)
            else:
                assert np.isfinite(out).all()


def test_c_status_codes_and_no_output_on_failure():
    ck = generated.load("avr3000", backend="c")
    from generated.avr3000._avr3000_c import ffi, lib
    header = (generated.avr3000.__path__[0] + "/avr3000.h")
    text = open(header).read()
    assert "#define AVR3000_UNREACHABLE 1" in text and "#define AVR3000_SINGULAR 2" in text
    assert "#define AVR3000_GEAR_R -0.47935881" in text
    out = ffi.new("double[3]", [7.0, 7.0, 7.0])
    assert lib.avr3000_tool_to_joint(ffi.new("double[3]", [0.0, 0.6, 0.0]), ffi.NULL, out) == lib.AVR3000_UNREACHABLE
    assert list(out) == [7.0, 7.0, 7.0]
    assert lib.avr3000_tool_to_joint(ffi.new("double[3]", [0.0, float("nan"), 0.0]), ffi.NULL, out) != 0
    full = ffi.new("double[3]", [0.0, 2 * A, 0.0])
    assert lib.avr3000_tool_to_joint_velocity(full, ffi.new("double[3]", [0, 1, 0]), ffi.NULL, out) == \
        lib.AVR3000_SINGULAR
    assert lib.avr3000_tool_to_joint(ffi.new("double[3]", [0.0, 0.3, 0.0]), ffi.NULL, out) == 0
    tools = ffi.new("double[9]", [0.0, 0.3, 0.0, 0.0, 0.6, 0.0, 0.0, 2 * A, 0.0])
    status = ffi.new("int[3]")
    assert lib.avr3000_tool_to_joint_velocity_batch(3, tools, ffi.new("double[9]"), ffi.NULL,
                                                     ffi.new("double[9]"), status) == 2
    assert list(status) == [0, lib.AVR3000_UNREACHABLE, lib.AVR3000_SINGULAR]
    assert lib.avr3000_tool_to_joint_batch(3, tools, ffi.NULL, ffi.new("double[9]"), ffi.NULL) == 1
    assert ck.GEAR_T == 1.0


def test_axis_limits_reproduce_the_script():
    limits = axis_limits()
    r, t, z = limits.motion("R"), limits.motion("T"), limits.motion("Z")
    assert abs(r.tool_velocity[0]) < 1e-12 and r.velocity / INCH == pytest.approx(121.886, abs=5e-4)
    assert t.tool_velocity[1] == 0
    # Independent: Z speed = 5500 rpm x GearZ [in/count] x 10000 counts/rev (the script's JMJ(3,3)).
    assert z.velocity / INCH == pytest.approx(5500 / 60 * 10000 * 6.5616798e-6, rel=1e-12)
    # The script's rule, AccMax = 1.5 v^2 / path and TimeAcc = 1.5 v / AccMax, on its strokes (30 in, 2 pi, 6 in).
    for motion, path in ((r, 30 * INCH), (t, 2 * math.pi), (z, 6 * INCH)):
        assert motion.acceleration == pytest.approx(1.5 * motion.velocity**2 / path, rel=1e-14)
        assert motion.time_to_speed == pytest.approx(1.5 * motion.velocity / motion.acceleration, rel=1e-14)
    assert r.motor_rpm == pytest.approx((0.479358811234781 * 4500, -4500, 0), rel=1e-10)


def test_section_2_1_2_motor_speeds_in_rad_per_s():
    """Sotirov section 2.1.2: "4500 RPM = 471.23 rad/s" (M1, M2) and "6000 RPM = 628.32 rad/s" (M3), to the
    printed two decimals (the paper cuts 471.2389 to 471.23), from the counts/s the script's limits give."""
    limits = axis_limits()
    t_motion, paper_z = limits.motion("T"), limits.paper_z
    assert t_motion.motor_rpm[:2] == (4500, 4500) and paper_z.motor_rpm[2] == 6000
    assert t_motion.motor_shaft_velocity[0] == pytest.approx(471.23, abs=0.01)
    assert t_motion.motor_shaft_velocity[1] == pytest.approx(471.23, abs=0.01)
    assert math.floor(t_motion.motor_shaft_velocity[0] * 100) / 100 == 471.23
    assert round(paper_z.motor_shaft_velocity[2], 2) == 628.32
    # The counts: 2048 lines x 4 per revolution on M1 (section 5), 2500 x 4 on M3.
    assert t_motion.motor_velocity[0] == pytest.approx(4500 / 60 * 8192, rel=1e-15)
    assert paper_z.motor_velocity[2] == pytest.approx(6000 / 60 * 10000, rel=1e-15)


def test_pure_z_at_the_papers_6000_rpm_beside_the_scripts_5500(capsys):
    """Z speed = rpm / 60 x 10000 counts/rev x J33 (6.5616798e-6 in/count, Eq. 1): 6.01487 in/s at the
    script's 5500 rpm, 6.56168 in/s at the 6000 rpm of sections 2.1.2 and 5; the command prints both."""
    limits = axis_limits()
    assert limits.motion("Z").velocity / INCH == pytest.approx(5500 / 60 * 10000 * 6.5616798e-6, rel=1e-12)
    assert limits.paper_z.velocity / INCH == pytest.approx(6000 / 60 * 10000 * 6.5616798e-6, rel=1e-12)
    assert f"{limits.paper_z.velocity / INCH:.6g}" == "6.56168"
    assert axis_limits(paper_z_rpm=None).paper_z is None and axis_limits(paper_z_rpm=5500).paper_z is None
    assert cli.main(["--quiet", "avr3000-limits", "--units", "in"]) == 0
    out = capsys.readouterr().out
    header = next(line for line in out.splitlines() if line.startswith("quantity"))
    assert "pure Z  pure Z, 6000 rpm" in header
    zdot = next(line for line in out.splitlines() if line.startswith("tool Zdot"))
    assert zdot.split()[-2:] == ["6.01487", "6.56168"]
    assert "471.239" in out and "628.319" in out


def test_the_acceleration_rule_is_a_cubic_ramp_to_speed_at_mid_stroke():
    peak, ramp_time, v, L = ramp_acceleration()
    assert str(peak) == "3*v**2/(2*L)" and str(ramp_time) == "L/v"
    # Numerically, without the derivation: the ramp v(3 s^2 - 2 s^3) over L/v covers L/2 and peaks at 1.5 v^2/L.
    speed, stroke = 3.1, 0.762
    t = np.linspace(0, stroke / speed, 200001)
    s = t / t[-1]
    velocity = speed * (3 * s**2 - 2 * s**3)
    assert np.trapezoid(velocity, t) == pytest.approx(stroke / 2, rel=1e-9)
    assert np.max(np.gradient(velocity, t)) == pytest.approx(1.5 * speed**2 / stroke, rel=1e-6)


def test_limits_command_prints_the_table_in_si_and_inches(capsys):
    assert cli.main(["--quiet", "avr3000-limits", "--R", "18.3in"]) == 0
    out = capsys.readouterr().out
    assert "SI units" in out and "inches (the paper's units)" in out
    assert "-121.886" in out and "-3.0959" in out and "GearR = -0.47935881" in out
    assert cli.main(["--quiet", "avr3000-limits", "--R", "22in"]) == 2
    assert "expected |R| < 2a" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["avr3000-limits", "--R", "18.3ft"])


def test_limits_command_runs_as_a_module():
    result = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "avr3000-limits", "--R=18.3in",
                             "--units", "in"], capture_output=True, text=True, check=True)
    assert "121.886" in result.stdout and "SI units" not in result.stdout



def test_section5_ranges_are_the_tool_space_limits(k):
    """Sotirov section 5, "Ranges": T 0 - 500 deg, R -8.9 in - 21 in, Z 0 - 6 in, in SI."""
    (t_low, t_high), (r_low, r_high), (z_low, z_high) = k.SPACE_LIMITS["tool"]
    assert (t_low, t_high) == (0.0, pytest.approx(500 * math.pi / 180, rel=1e-15))
    assert r_low / INCH == pytest.approx(-8.9, rel=1e-14) and r_high / INCH == pytest.approx(21, rel=1e-14)
    assert (z_low, z_high / INCH) == (0.0, pytest.approx(6, rel=1e-14))
    # Through Eq. 4, R = 2a cos(q2/2) >= -8.9 in bounds q2; R <= 21 in = 2a bounds nothing; Z = q3.
    assert k.LIMITS[0] is None
    assert k.LIMITS[1] == (0.0, pytest.approx(2 * math.acos(-8.9 / 21), rel=1e-14))
    assert k.LIMITS[2] == (0.0, pytest.approx(6 * INCH, rel=1e-14))


def test_within_limits_follows_the_printed_ranges(k):
    """A tool point inside section 5's ranges maps (Eq. 8) to joints within_limits accepts; R below -8.9 in
    or Z outside 0 - 6 in is refused. T spans more than a turn, so every q1 is inside."""
    inch = INCH
    inside = np.array([[0.0, -8.9 * inch, 0.0], [1.0, -8.89 * inch, 3 * inch], [-3.0, 0.0, 6 * inch],
                       [2.5, 20.99 * inch, 0.5 * inch], [0.0, 21 * inch, 0.0]])
    outside = np.array([[0.0, -8.95 * inch, 0.0], [0.0, -10 * inch, 3 * inch], [0.0, 10 * inch, 6.01 * inch],
                        [0.0, 10 * inch, -0.01 * inch]])
    q_in = k.tool_to_joint(inside)
    assert k.within_limits(q_in).all()
    assert not k.within_limits(k.tool_to_joint(outside)).any()
    # The edge itself, R = -8.9 in, is q2 = 2 acos(-8.9 / 21): on the limit, inside.
    assert q_in[0, 1] == pytest.approx(2 * math.acos(-8.9 / 21), rel=1e-14)
    q1_any = np.column_stack([np.linspace(-10, 10, 9), np.full(9, 1.0), np.full(9, 0.01)])
    assert k.within_limits(q1_any).all()

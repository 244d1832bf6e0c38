"""AVR 3000 vacuum robot: Sotirov, "Kinematics of AVR 3000 Vacuum Robot" (Genmark Automation, 2011).

A 3-DOF arm of two equal links (length ``a``) whose hand stays on the bisector
of the two links, driven by motors M1 and M2 through a coupled T/R transmission,
and a vertical Z axis driven by M3.  Four coordinate spaces (Sotirov section 1
and 2.3), SI units throughout:

=========  ==================  =====================================================
space      coordinates         units
=========  ==================  =====================================================
motor      theta1 .. theta3    encoder counts (8192 per rev for M1, M2; 10000 for M3)
joint      q1, q2, q3          rad, rad, m
tool       T, R, Z             rad, m, m
cartesian  x, y, z             m (the tip of an end-effector of length ``e``)
=========  ==================  =====================================================

Three position maps are taken from the paper: Eq. 1 (motor -> joint, linear in
the Jacobian elements J11, J21, J22, J33), Eq. 4 (joint -> tool) and the arm
geometry behind Eq. 7 (joint -> Cartesian, here from the link frames).  Every
other map is derived: inverses are solved (Eqs. 8 and 11), longer maps composed
(Eq. 14, the Matlab JMT and JMC), and every velocity and acceleration map
differentiated from its position map (Eqs. 2, 3, 5, 6, 9, 10, 12, 13 and the
J^x of section 2.3.2 come out and are checked in tests/test_avr3000_paper.py).

The DESIGN contract reads: ``q`` = (q1, q2, q3) (R, R, P); ``frames`` = base,
link 1, link 2, end-effector tip (x along the hand's radial direction, the
direction of increasing R); ``task`` = tool (T, R, Z) with one ``ik`` branch,
Eq. 8 (q2 = 2 acos(R / 2a) in [0, 2 pi]).
"""
from __future__ import annotations

from dataclasses import replace

import sympy as sp

from derivations.chain import simplify_entry
from derivations.ik import WrapAngle
from derivations.model import IKBranch, Requirement
from derivations.spaces import SpaceMap, SpacesModel, compose, coordinate_space, differentiate, position_map

INCH = sp.Rational(254, 10000)  # metres per inch, exact

# Sotirov section 5 and the Matlab script: 2048-line encoders on M1 and M2, 2500 on M3, read in quadrature.
COUNTS_PER_REV = (2048 * 4, 2048 * 4, 2500 * 4)

a = sp.Symbol("a", positive=True)       # link length (both links), m
e = sp.Symbol("e", real=True)           # end-effector length (Eq. 7), m
J11, J21, J22, J33 = sp.symbols("J11 J21 J22 J33", real=True)  # Eq. 1: rad/count (J33: m/count)

# Defaults, exact: section 5 (link length 10.5 in) and the values printed under Eq. 1.  The paper gives J33
# in in/count; e is not given (the Matlab script computes the tip with e = 0).
PARAMS = {
    a: sp.Rational(21, 2) * INCH,
    e: sp.S.Zero,
    J11: sp.Rational("-4.0175691732e-5"),
    J21: sp.Rational("2.6036376953e-5"),
    J22: sp.Rational("-2.6036376953e-5"),
    J33: sp.Rational("6.5616798e-6") * INCH,
}
Z_STROKE = 6 * INCH  # section 5: Z-axis 0 - 6 in
# Section 5, "Ranges": T 0 - 500 deg, R -8.9 in - 21 in, Z 0 - 6 in (SI, exact). T spans more than a
# turn: it is the range of a multi-turn axis, not of an angle modulo 2 pi.
TOOL_RANGES = ((0, 500 * sp.pi / 180), (-sp.Rational(89, 10) * INCH, 21 * INCH), (0, Z_STROKE))


def joint_limits(params=PARAMS):
    """The joint ranges that keep the tool within section 5's ranges, through Eq. 4 (R = 2a cos(q2/2)).

    R <= 21 in = 2a holds for every q2; R >= -8.9 in bounds q2 in [0, 2 acos(-8.9 in / 2a)] (q2 in
    [0, 2 pi] is Eq. 8's range). Z = q3 in [0, 6 in]. T = pi/2 - q1 - q2/2 over 500 deg > one turn
    leaves q1 (counted modulo 2 pi, like every revolute joint in ``within_limits``) free.
    """
    (r_low, r_high), (z_low, z_high) = TOOL_RANGES[1], TOOL_RANGES[2]
    reach = 2 * params[a]
    if not r_high <= reach:
        raise ValueError("section 5's R range reaches beyond 2a")
    return (None, (sp.S.Zero, 2 * sp.acos(r_low / reach)), (z_low, z_high))

motor = coordinate_space("motor", ("theta1", "theta2", "theta3"), ("count", "count", "count"),
                         "motor positions of M1, M2 (T/R pair) and M3 (Z)")
joint = coordinate_space("joint", ("q1", "q2", "q3"), ("rad", "rad", "m"), "joint coordinates")
tool = coordinate_space("tool", ("T", "R", "Z"), ("rad", "m", "m"), "tool coordinates: rotation, radial reach, height")
cartesian = coordinate_space("cartesian", ("x", "y", "z"), ("m", "m", "m"), "the end-effector tip in the base frame")
SPACES = (motor, joint, tool, cartesian)


def _translation(x, y, z) -> sp.Matrix:
    m = sp.eye(4)
    m[:3, 3] = sp.Matrix([x, y, z])
    return m


def _rotation_z(angle) -> sp.Matrix:
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def link_frames(q) -> list[sp.Matrix]:
    """Base, link 1, link 2 and the end-effector tip.

    Z lifts the whole arm; link 1 turns by q1 about the base axis, link 2 by q2
    at the elbow (a along link 1); the hand sits at the wrist (a along link 2),
    turned back by q2/2 onto the bisector of the links, and the tip lies a
    distance e behind the wrist along the hand (the sign of Eq. 7).
    """
    q1, q2, q3 = q
    link1 = _translation(0, 0, q3) * _rotation_z(q1)
    link2 = link1 * _translation(a, 0, 0) * _rotation_z(q2)
    tip = link2 * _translation(a, 0, 0) * _rotation_z(-q2 / 2) * _translation(-e, 0, 0)
    return [sp.eye(4)] + [frame.applyfunc(simplify_entry) for frame in (link1, link2, tip)]


def geometric_jacobian(fk: sp.Matrix, q) -> sp.Matrix:
    """``[dp/dq; w]`` with ``w_i = vee(dR/dq_i R^T)``, the angular velocity per unit joint rate."""
    rotation = fk[:3, :3]
    columns = []
    for qi in q:
        spin = (rotation.diff(qi) * rotation.T).applyfunc(simplify_entry)
        columns.append(sp.Matrix([spin[2, 1], spin[0, 2], spin[1, 0]]))
    return sp.Matrix.vstack(fk[:3, 3].jacobian(sp.Matrix(q)), sp.Matrix.hstack(*columns)).applyfunc(simplify_entry)


def _solve_linear(equations, unknowns) -> sp.Matrix:
    solution = sp.solve(list(equations), list(unknowns), dict=True)
    if len(solution) != 1:
        raise ValueError(f"expected one solution for {unknowns}, got {solution}")
    return sp.Matrix([sp.expand(solution[0][u]) for u in unknowns])


def _check_identity(name, expressions, symbols):
    residual = (sp.Matrix(expressions) - sp.Matrix(symbols)).applyfunc(lambda v: sp.simplify(sp.expand_trig(v)))
    if residual != sp.zeros(*residual.shape):
        raise ValueError(f"{name}: the round trip is not the identity: {list(residual)}")


def position_maps() -> dict[str, SpaceMap]:
    """The twelve position maps between the four spaces, and the second branch of the three
    Cartesian inverses (``*_reversed``), by kernel name."""
    theta1, theta2, theta3 = motor.position
    q1, q2, q3 = joint.position
    T, R, Z = tool.position
    x, y, z = cartesian.position

    # Sotirov Eq. 1: the motors drive the joints linearly; q2 = pi with the motors at zero.
    motor_to_joint = position_map(motor, joint, [J11 * theta1, sp.pi + J21 * theta1 + J22 * theta2, J33 * theta3],
                                  cite="Sotirov Eq. 1")
    # Eq. 11 is Eq. 1 solved for the motor coordinates.
    joint_to_motor = position_map(
        joint, motor, _solve_linear(sp.Matrix(joint.position) - motor_to_joint.values, motor.position),
        cite="Sotirov Eq. 11")

    # Sotirov Eq. 4: T is measured from the y axis, R along the bisector of the links.
    joint_to_tool = position_map(joint, tool, [sp.pi / 2 - q1 - q2 / 2, 2 * a * sp.cos(q2 / 2), q3],
                                 cite="Sotirov Eq. 4")
    # Eq. 8: R = 2a cos(q2/2) inverted on q2 in [0, 2 pi] (the one branch of the arm), then T and Z solved for q1, q3.
    reach = R / (2 * a)
    q2_of_tool = 2 * sp.acos(reach)
    q1_q3 = _solve_linear([T - joint_to_tool.values[0].subs(q2, q2_of_tool), Z - joint_to_tool.values[2]], (q1, q3))
    tool_to_joint = position_map(
        tool, joint, [q1_q3[0], q2_of_tool, q1_q3[1]],
        requires=[Requirement(sp.And(reach >= -1, reach <= 1), "unreachable",
                              "the links reach |R| <= 2a only (R in [-2a, 2a])")],
        # Eqs. 9-10 divide by a sin(q2/2) = a sqrt(1 - (R/2a)^2): zero with the arm fully extended.
        derivative_requires=[Requirement(1 - reach**2 > 0, "singular",
                                         "sin(q2/2) = 0: the arm is fully extended (|R| = 2a)")],
        cite="Sotirov Eq. 8")

    # Eq. 7 from the link frames: the tip of the end-effector.
    tip = link_frames(joint.position)[-1]
    joint_to_cartesian = position_map(joint, cartesian, tip[:3, 3], cite="Sotirov Eq. 7")
    # Tool -> Cartesian: Eq. 7 after Eq. 8, simplified to polar form (defined for every R, unlike Eq. 8).
    through_joints = compose(joint_to_cartesian, tool_to_joint)
    polar = through_joints.values.applyfunc(lambda v: sp.simplify(sp.expand_trig(v)))
    if polar.has(sp.acos):
        raise ValueError(f"tool -> cartesian did not simplify to polar form: {list(polar)}")
    tool_to_cartesian = position_map(tool, cartesian, polar, cite="Sotirov Eqs. 7 and 8; the Matlab JX")
    # Its inverse on the branch R - e = +sqrt(x^2 + y^2) (the tip on the hand's side of the axis).
    radius_squared = x**2 + y**2
    cartesian_to_tool = position_map(
        cartesian, tool, [sp.atan2(x, y), e + sp.sqrt(radius_squared), z],
        requires=[Requirement(radius_squared > 0, "singular",
                              "the tip is on the T axis (x = y = 0), where T is undetermined")],
        doc="Branch R - e = +sqrt(x^2 + y^2), T = atan2(x, y) in (-pi, pi].")

    # The other branch, R - e = -sqrt(x^2 + y^2): the arm turned half a turn, folded through the
    # T axis (R < e), as the script's RMin = -10 in allows. T wrapped to (-pi, pi] like the first.
    cartesian_to_tool_reversed = position_map(
        cartesian, tool, [WrapAngle(sp.atan2(x, y) + sp.pi), e - sp.sqrt(radius_squared), z],
        requires=[Requirement(radius_squared > 0, "singular",
                              "the tip is on the T axis (x = y = 0), where T is undetermined")],
        branch="reversed",
        doc="Branch R - e = -sqrt(x^2 + y^2), T = atan2(x, y) + pi wrapped to (-pi, pi]: "
            "the arm turned half a turn and folded through the T axis.")

    _check_identity("tool -> joint -> tool", compose(joint_to_tool, tool_to_joint).values, tool.position)
    _check_identity("motor -> joint -> motor", compose(joint_to_motor, motor_to_joint).values, motor.position)
    _check_identity("cartesian -> tool -> cartesian", compose(tool_to_cartesian, cartesian_to_tool).values,
                    cartesian.position)
    # The wrap changes T by whole turns only, which sin and cos of tool_to_cartesian do not see.
    unwrapped = cartesian_to_tool_reversed.values.replace(WrapAngle, lambda angle: angle)
    _check_identity("cartesian -> tool (reversed) -> cartesian",
                    compose(tool_to_cartesian, replace(cartesian_to_tool_reversed, values=unwrapped)).values,
                    cartesian.position)

    maps = [motor_to_joint, joint_to_motor, joint_to_tool, tool_to_joint, joint_to_cartesian,
            tool_to_cartesian, cartesian_to_tool]
    maps.append(compose(joint_to_tool, motor_to_joint, cite="Sotirov Eq. 14; the Matlab JMT"))
    maps.append(compose(joint_to_cartesian, motor_to_joint, cite="the Matlab JMC"))
    maps.append(compose(joint_to_motor, tool_to_joint, cite="Sotirov Eqs. 8 and 11"))
    cartesian_to_joint = compose(tool_to_joint, cartesian_to_tool)
    maps.append(cartesian_to_joint)
    maps.append(compose(joint_to_motor, cartesian_to_joint))
    cartesian_to_joint_reversed = compose(tool_to_joint, cartesian_to_tool_reversed)
    maps += [cartesian_to_tool_reversed, cartesian_to_joint_reversed, compose(joint_to_motor, cartesian_to_joint_reversed)]
    return {m.name: m for m in maps}


# Order of the generated kernels: direct maps up the chain motor -> joint -> tool -> Cartesian, then inverses.
MAP_ORDER = ("motor_to_joint", "joint_to_tool", "joint_to_cartesian", "tool_to_cartesian", "motor_to_tool",
             "motor_to_cartesian", "joint_to_motor", "tool_to_joint", "tool_to_motor", "cartesian_to_tool",
             "cartesian_to_joint", "cartesian_to_motor", "cartesian_to_tool_reversed", "cartesian_to_joint_reversed",
             "cartesian_to_motor_reversed")

DERIVATIVE_CITES = {
    "motor_to_joint": ("Sotirov Eq. 2", "Sotirov Eq. 3"),
    "joint_to_tool": ("Sotirov Eq. 5", "Sotirov Eq. 6"),
    "joint_to_cartesian": ("Sotirov section 2.3.2, J^x", ""),
    "motor_to_tool": ("Sotirov Eq. 14; the Matlab JMT", ""),
    "motor_to_cartesian": ("the Matlab JMC", ""),
    "tool_to_cartesian": ("the Matlab JX", ""),
    "joint_to_motor": ("Sotirov Eq. 12", "Sotirov Eq. 13"),
    "tool_to_joint": ("Sotirov Eq. 9", "Sotirov Eq. 10"),
}


def gear_ratios(motor_to_tool_velocity: sp.Matrix) -> dict[str, sp.Expr]:
    """Sotirov section 4: motor speed ratios thetadot1 / thetadot2 that move T alone or R alone.

    With thetadot = (g w, w, 0): GearT solves Rdot = 0 (Eq. 14, second row) and
    GearR solves Tdot = 0 (Eq. 14, first row).
    """
    g, w = sp.Symbol("g"), sp.Symbol("w", positive=True)
    thetadot1, thetadot2, thetadot3 = motor.velocity
    rates = motor_to_tool_velocity.xreplace({thetadot1: g * w, thetadot2: w, thetadot3: 0})
    ratios = {}
    for name, row in (("GEAR_T", 1), ("GEAR_R", 0)):
        # Rdot carries the factor -a sin(q2/2) (nonzero away from the singular arm): solve on the factor in g.
        factors = [f for f in sp.factor_list(rates[row])[1] if f[0].has(g)]
        if len(factors) != 1:
            raise ValueError(f"{name}: expected one factor in g, got {factors}")
        (solution,) = sp.solve(factors[0][0], g)
        ratios[name] = sp.simplify(solution)
    return ratios


def build() -> SpacesModel:
    """The AVR 3000 model (slow symbolic work; ``derivations.load`` caches it)."""
    positions = position_maps()
    maps = {}
    for name in MAP_ORDER:
        pmap = positions[name]
        maps[name] = pmap
        velocity_cite, acceleration_cite = DERIVATIVE_CITES.get(name, ("", ""))
        maps[f"{name}_velocity"] = differentiate(pmap, "velocity", cite=velocity_cite)
        maps[f"{name}_acceleration"] = differentiate(pmap, "acceleration", cite=acceleration_cite)

    q = joint.position
    frames = link_frames(q)
    joint_to_tool = positions["joint_to_tool"]
    tool_to_joint = positions["tool_to_joint"]
    reach = tool_to_joint.requires[0].condition
    x_, y_ = cartesian.position[:2]
    T, R, Z = tool.position
    sample_ranges = {
        # Motor counts: a few turns of T either way; M3 over the 6 in Z stroke (0.15 m / 1.7e-7 m per count).
        **{s: (-2 * 10**5, 2 * 10**5) for s in motor.position[:2]}, motor.position[2]: (0, 10**6),
        **{s: (-6 * 10**5, 6 * 10**5) for s in motor.velocity}, **{s: (-10**7, 10**7) for s in motor.acceleration},
        q[0]: (-sp.pi, sp.pi), q[1]: (0, 2 * sp.pi), q[2]: (0, Z_STROKE),
        T: (-sp.pi, sp.pi), R: (-sp.Rational(19, 10) * a, sp.Rational(19, 10) * a), Z: (0, Z_STROKE),
        # |x|, |y| <= (1.9 a - e) / sqrt 2 keeps R = e + sqrt(x^2 + y^2) within 1.9 a.
        x_: (-(sp.Rational(19, 10) * a - e) / sp.sqrt(2), (sp.Rational(19, 10) * a - e) / sp.sqrt(2)),
        y_: (-(sp.Rational(19, 10) * a - e) / sp.sqrt(2), (sp.Rational(19, 10) * a - e) / sp.sqrt(2)),
        cartesian.position[2]: (0, Z_STROKE),
        **{s: (-2, 2) for space in (joint, tool, cartesian) for s in space.velocity},
        **{s: (-20, 20) for space in (joint, tool, cartesian) for s in space.acceleration},
    }
    model = SpacesModel(
        name="avr3000",
        title="AVR 3000 vacuum robot (frog-leg arm with coupled T/R transmission)",
        source='Z. M. Sotirov, "Kinematics of AVR 3000 Vacuum Robot", Genmark Automation, 2011',
        joint_types=("R", "R", "P"), q=q, params={s: float(v) for s, v in PARAMS.items()},
        frames=frames, jacobian=geometric_jacobian(frames[-1], q),
        task_names=tuple(str(s) for s in tool.position), task=joint_to_tool.values,
        task_jacobian=joint_to_tool.values.jacobian(sp.Matrix(q)),
        # Section 5's ranges through Eq. 4: q2 in [0, 2 acos(-8.9 in / 2a)] (R >= -8.9 in), q3 = Z in [0, 6 in].
        limits=tuple(None if lim is None else (float(lim[0]), float(lim[1])) for lim in joint_limits()),
        # q1 wrapped to (-pi, pi] like every revolute joint of an IK branch; q2 keeps Eq. 8's [0, 2 pi]:
        # the pose holds q2 / 2, so q2 and q2 - 2 pi are two configurations, not one (ik_ranges).
        ik=[IKBranch("principal", (WrapAngle(tool_to_joint.values[0]),) + tuple(tool_to_joint.values[1:]), reach,
                     "Sotirov Eq. 8: q2 = 2 acos(R / 2a) in [0, 2 pi], q1 = pi/2 - q2/2 - T wrapped to (-pi, pi], "
                     "q3 = Z")],
        ik_ranges="q1 is wrapped to (-pi, pi]; q2 = 2 acos(R / 2a) stays in [0, 2 pi] (Sotirov Eq. 8: "
                  "the pose holds q2 / 2, so q2 and q2 - 2 pi are two configurations).",
        constants=gear_ratios(maps["motor_to_tool_velocity"].values),
        spaces={s.name: s for s in SPACES}, maps=maps, sample_ranges=sample_ranges,
        space_limits={"tool": tuple((float(low), float(high)) for low, high in TOOL_RANGES)},
    )
    model.notes.update({
        "counts_per_rev": "M1, M2: 2048 lines x 4 = 8192; M3: 2500 x 4 = 10000 (the Matlab script)",
        "e": "the paper gives no end-effector length; the default 0 puts the tip at the wrist, as the Matlab script",
    })
    return model

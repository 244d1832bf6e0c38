"""The SCORBOT ER-VII pick-and-place path of Predescu and Stroe, section 4.

The tool point P5 moves on the segment from M(0.750, 0, 0.300) to
N(0.300, 0, 0.750) (metres) in 10 s with the gripper horizontal
(theta2 + theta3 + theta4 = 0, Eq. 3.10).  Two ways to drive it:

* **The paper's way: a time law on theta2.**  The joint angles at M and N come
  from the inverse kinematics (Eqs. 3.1-3.11); theta2 follows a cubic (Eq. 4.1)
  or the cycloidal law (Eq. 4.8), and the wrist centre O4 is where the circle of
  radius a3 about the moving elbow O3 meets the line through O4 at M and at N
  (Eqs. 4.2-4.6); P5 is O4 shifted by d5 (Eq. 4.7).  P5 then runs along MN at a
  speed the geometry dictates: :func:`tool_point_from_theta2`, :func:`tool_motion`.
* **The Cartesian way: a time law on the straight line.**  P5 = M + s(t) (N - M)
  with a rest-to-rest law s(t) from 0 to 1, and the inverse kinematics at every
  instant gives the joint angles, rates and accelerations: :func:`joints_along_line`.

The inverse kinematics is the robot model's own (``derivations.load
("scorbot_er7").ik``) when it has one, else the paper's Eqs. 3.1-3.11 written
out here (:func:`paper_ik_branches`).  Of its branches the paper's is the one with
theta1 = atan2(y, x) and the elbow above the shoulder-wrist line, theta3 < 0 in
our angles (theta2 up from the horizontal, theta3 relative): only that one gives
Eq. 4.1's starting value theta2(M) = 13.4685 deg.  Eq. 3.5 as printed, with the
principal arccosine (theta3 >= 0), gives the other elbow and theta2(M) = -33.23 deg
(erratum E11 in the README).

Angles in radians, lengths in metres, time in seconds; the paper's degrees are
converted in :func:`eq_4_1_degrees` and the tests.
"""
from __future__ import annotations

import sympy as sp

from . import trajectory
from .kernelset import KernelSet
from .model import Argument, IKBranch, Output, SymbolicFunction

__all__ = ["M", "N", "DURATION", "paper_ik_branches", "paper_branch", "joint_angles", "theta2_cubic",
           "eq_4_1_degrees", "theta2_cycloidal", "CYCLOIDAL_PARAMETERS", "tool_point_from_theta2",
           "tool_motion", "line_point", "joints_along_line", "kernel_set", "PathError"]

M = (sp.Rational(3, 4), sp.S.Zero, sp.Rational(3, 10))
N = (sp.Rational(3, 10), sp.S.Zero, sp.Rational(3, 4))
DURATION = sp.Integer(10)
# Eq. 4.8: theta_i = 0.235 rad, A0 = 1.975 rad, omega0 = pi/5 1/s, as printed (rounded).
CYCLOIDAL_PARAMETERS = (sp.Rational(235, 1000), sp.Rational(1975, 1000), sp.pi / 5)


class PathError(ValueError):
    """A path the SCORBOT cannot follow as asked (e.g. no branch of the IK fits)."""


def _param(model, name: str) -> sp.Symbol:
    for symbol in model.params:
        if str(symbol) == name:
            return symbol
    raise PathError(f"{model.name} has no parameter {name!r}")


def paper_ik_branches(model) -> list[IKBranch]:
    """Predescu and Stroe's inverse kinematics, Eqs. 3.1-3.11, both elbows, in the task symbols.

    theta1 = atan2(y, x) (3.1); theta3 = -+acos(...) (3.5); theta2 = beta - alpha
    (3.6-3.9); theta4 = -theta2 - theta3 (3.11); theta5 = 0 (not determined by a
    position).  ``elbow_up`` is theta3 = -acos(...), the elbow above the line from
    the shoulder O2 to the wrist O4 (the paper's Eq. 4.1 branch).
    """
    x, y, z = model.task_symbols
    a1, a2, a3, d1, d5 = (_param(model, n) for n in ("a1", "a2", "a3", "d1", "d5"))
    horizontal = sp.sqrt(x**2 + y**2) - a1 - d5        # O2B
    vertical = z - d1                                  # O4B
    cos3 = (horizontal**2 + vertical**2 - a2**2 - a3**2) / (2 * a2 * a3)  # Eq. 3.5
    reachable = sp.And(cos3 >= -1, cos3 <= 1)
    branches = []
    for name, sign in (("elbow_up", -1), ("elbow_down", 1)):
        theta3 = sign * sp.acos(cos3)
        alpha = sp.atan2(a3 * sp.sin(theta3), a2 + a3 * sp.cos(theta3))  # Eq. 3.6
        beta = sp.atan2(vertical, horizontal)                            # Eq. 3.7
        theta2 = beta - alpha                                            # Eq. 3.8
        branches.append(IKBranch(name, (sp.atan2(y, x), theta2, theta3, -theta2 - theta3, sp.S.Zero),
                                 reachable, f"Predescu and Stroe Eqs. 3.1-3.11, {name}"))
    return branches


def _evaluate(expr, values) -> complex:
    return complex(sp.sympify(expr).evalf(30, subs=values))


def paper_branch(model) -> IKBranch:
    """The IK branch the paper's path uses: theta1 = atan2(y, x) and theta3 < 0 at M.

    Taken from ``model.ik`` when the model has branches, else from
    :func:`paper_ik_branches`.
    """
    branches = list(model.ik) or paper_ik_branches(model)
    values = {**dict(zip(model.task_symbols, M)), **{s: sp.Rational(str(v)) for s, v in model.params.items()}}
    chosen = []
    for branch in branches:
        if sp.sympify(branch.condition).subs(values) is not sp.true:
            continue
        q = [_evaluate(e, values) for e in branch.solution]
        if any(abs(v.imag) > 1e-12 for v in q):
            continue
        if abs(q[0].real) < 1e-12 and q[2].real < 0:
            chosen.append(branch)
    if len(chosen) != 1:
        raise PathError(f"{model.name}: expected exactly one IK branch with theta1 = 0 and theta3 < 0 at M, "
                        f"found {[b.name for b in chosen]} among {[b.name for b in branches]}")
    return chosen[0]


def joint_angles(model, point, branch: IKBranch | None = None) -> tuple[sp.Expr, ...]:
    """Exact joint angles (rad) at ``point`` = (x, y, z) in metres on ``branch`` (default: the paper's)."""
    branch = branch or paper_branch(model)
    values = {**dict(zip(model.task_symbols, (sp.nsimplify(c) for c in point))),
              **{s: sp.Rational(str(v)) for s, v in model.params.items()}}
    if sp.sympify(branch.condition).subs(values) is not sp.true:
        raise PathError(f"{model.name}: the point {tuple(point)} is out of reach on branch {branch.name}")
    return tuple(sp.sympify(e).subs(values) for e in branch.solution)


def theta2_cubic(model) -> sp.Expr:
    """theta2(t) in rad: the rest-to-rest cubic from theta2(M) to theta2(N) in 10 s (Eq. 4.1, in rad)."""
    start, end = joint_angles(model, M)[1], joint_angles(model, N)[1]
    return trajectory.cubic(start, end, DURATION)


def eq_4_1_degrees(model) -> sp.Expr:
    """Eq. 4.1 as the paper prints it: theta2(t) in degrees (exact; evalf for the paper's digits)."""
    return sp.expand(theta2_cubic(model) * 180 / sp.pi)


def theta2_cycloidal() -> sp.Expr:
    """theta2(t) in rad by Eq. 4.8 with the paper's theta_i, A0 and omega0."""
    return trajectory.cycloidal(*CYCLOIDAL_PARAMETERS)


def _wrist_line(model, theta2, start, end):
    """x and z of the wrist centre O4 on the line through O4 at ``start`` and ``end`` (Eqs. 4.2-4.7)."""
    a1, a2, a3, d1, d5 = (_param(model, n) for n in ("a1", "a2", "a3", "d1", "d5"))
    (x_i, z_i), (x_f, z_f) = (start[0] - d5, start[1]), (end[0] - d5, end[1])  # O4 = P5 - d5 (Eq. 4.7)
    m = (z_i - z_f) / (x_i - x_f)
    n = z_f - x_f * m
    x_o3 = a1 + a2 * sp.cos(theta2)
    z_o3 = d1 + a2 * sp.sin(theta2)
    A = m**2 + 1                                                   # Eq. 4.2
    B = 2 * (m * n - m * z_o3 - x_o3)                              # Eq. 4.3
    C = x_o3**2 + z_o3**2 - a3**2 - 2 * n * z_o3 + n**2            # Eq. 4.4
    discriminant = B**2 - 4 * A * C
    x_o4 = (-B + sp.sqrt(discriminant)) / (2 * A)                  # Eq. 4.5
    z_o4 = m * x_o4 + n                                            # Eq. 4.6
    return x_o4 + d5, z_o4, discriminant                           # Eq. 4.7: P5


def tool_point_from_theta2(model, theta2, start=(M[0], M[2]), end=(N[0], N[2])) -> tuple[sp.Expr, sp.Expr]:
    """(x, z) of P5 in metres for the elbow angle ``theta2`` (rad), by Eqs. 4.2-4.7.

    ``start`` and ``end`` are (x, z) of P5 at M and N (the path lies in y = 0);
    the paper's slope form of the line needs them at different x.  Eq. 4.5 takes
    the larger-x intersection, which is the elbow-up wrist on this path.
    """
    x, z, _ = _wrist_line(model, theta2, start, end)
    return x, z


def tool_motion(model, theta2_law: sp.Expr):
    """Position, velocity and acceleration of P5 (each a 2-vector x, z) for ``theta2_law`` in ``t``.

    Metres, m/s, m/s^2; the paper's Figs. 8 (cubic) and 10 (cycloidal).
    """
    theta = sp.Symbol("theta2", real=True)
    x, z = tool_point_from_theta2(model, theta)
    defaults = {s: sp.Rational(str(v)) for s, v in model.params.items()}
    position = sp.Matrix([x, z]).xreplace(defaults).xreplace({theta: theta2_law})
    velocity = position.diff(trajectory.t)
    return position, velocity, velocity.diff(trajectory.t)


def line_point(s) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """P5 = M + s (N - M), metres."""
    return tuple(m + s * (n - m) for m, n in zip(M, N))


def _without_clamps(expr: sp.Expr) -> sp.Expr:
    """``expr`` with the IK's acos/asin argument clamps ``Min(1, Max(-1, u))`` replaced by ``u``.

    For differentiation only: the path lies strictly inside the workspace, where
    the clamp is the identity (its derivative would otherwise bring Heaviside
    and DiracDelta terms that are zero there).
    """
    ends = (sp.S.One, sp.S.NegativeOne)
    return expr.replace(
        lambda e: isinstance(e, (sp.Min, sp.Max)) and len(e.args) == 2 and any(a in ends for a in e.args),
        lambda e: next(a for a in e.args if a not in ends))


def joints_along_line(model, s_law: sp.Expr, branch: IKBranch | None = None):
    """Joint angles, rates and accelerations (5-vectors, rad, rad/s, rad/s^2) along MN.

    ``s_law`` is the path parameter as a function of ``t`` (0 at M, 1 at N), e.g.
    ``trajectory.cubic(0, 1, 10)``; the angles are the inverse kinematics on
    ``branch`` (default: the paper's) at ``line_point(s_law)``.
    """
    branch = branch or paper_branch(model)
    values = {**dict(zip(model.task_symbols, line_point(s_law))),
              **{s: sp.Rational(str(v)) for s, v in model.params.items()}}
    angles = sp.Matrix([sp.sympify(e).xreplace(values) for e in branch.solution])
    rates = angles.applyfunc(_without_clamps).diff(trajectory.t)
    return angles, rates, rates.diff(trajectory.t)


# -- generated kernels -----------------------------------------------------------------------

def kernel_set(model=None) -> KernelSet:
    """The path constructions as kernels (``generated/scorbot_path``).

    ``tool_point_from_theta2(theta2_state)``: theta2, its rate and acceleration
    (..., 3) -> ``p`` (..., 3, 2): rows position, velocity, acceleration of P5,
    columns x, z; ``valid`` (...) where the elbow circle meets the line (Eqs. 4.2-4.7;
    the line in the paper's slope form, so xM != xN).

    ``joints_along_line(path)``: s, ds/dt, d2s/dt2 (..., 3) -> ``q`` (..., 3, 5):
    rows joint angles, rates, accelerations on the paper's branch at
    P5 = M + s (N - M); ``valid`` (...) where the point is in reach.

    Parameters: the robot's a1, a2, a3, d1, d5 and the end points xM .. zN (m).
    ``model`` defaults to ``derivations.load("scorbot_er7")``.
    """
    if model is None:
        from . import load
        model = load("scorbot_er7")
    real = {"real": True}
    end_points = sp.symbols("xM yM zM xN yN zN", **real)
    xM, yM, zM, xN, yN, zN = end_points
    params = dict(model.params)
    params.update({s: float(v) for s, v in zip(end_points, M + N)})

    theta, theta_rate, theta_accel = sp.symbols("theta2 theta2_rate theta2_accel", **real)
    x, z, discriminant = _wrist_line(model, theta, (xM, zM), (xN, zN))
    p = []
    for coordinate in (x, z):
        first = sp.diff(coordinate, theta)
        p.append((coordinate, first * theta_rate, sp.diff(first, theta) * theta_rate**2 + first * theta_accel))
    tool = SymbolicFunction(
        "tool_point_from_theta2",
        (Argument("theta2_state", (theta, theta_rate, theta_accel),
                  "theta2 (rad), its rate (rad/s) and acceleration (rad/s^2): shape (..., 3)"),),
        (Output("p", tuple(p[c][r] for r in range(3) for c in range(2)), (3, 2),
                doc="P5 position (m), velocity (m/s), acceleration (m/s^2); columns x, z"),
         Output("valid", (discriminant >= 0,), (), "bool", "the elbow circle meets the line")),
        "P5 on the line MN for a theta2 state, by Predescu and Stroe Eqs. 4.2-4.7: "
        "(p (..., 3, 2) rows position, velocity, acceleration, columns x, z; valid (...)).")

    branch = paper_branch(model)
    s, s_rate, s_accel = sp.symbols("s s_rate s_accel", **real)
    point = {task: a + s * (b - a) for task, a, b in zip(model.task_symbols, (xM, yM, zM), (xN, yN, zN))}
    angles = [sp.sympify(e).xreplace(point) for e in branch.solution]
    first = [sp.diff(_without_clamps(e), s) for e in angles]
    second = [sp.diff(e, s) for e in first]
    rows = (angles, [f * s_rate for f in first], [f2 * s_rate**2 + f * s_accel for f, f2 in zip(first, second)])
    line = SymbolicFunction(
        "joints_along_line",
        (Argument("path", (s, s_rate, s_accel),
                  "s (0 at M, 1 at N), ds/dt (1/s), d2s/dt2 (1/s^2): shape (..., 3)"),),
        (Output("q", tuple(e for row in rows for e in row), (3, len(angles)),
                doc="joint angles (rad), rates (rad/s), accelerations (rad/s^2)"),
         Output("valid", (sp.sympify(branch.condition).xreplace(point),), (), "bool", "the point is in reach")),
        f"Joint motion along P5 = M + s (N - M) on the IK branch {branch.name} (the paper's): "
        "(q (..., 3, 5) rows angles, rates, accelerations; valid (...)).")

    theta_m, theta_n = (float(joint_angles(model, point)[1]) for point in (M, N))
    param_ranges = {symbol: (0.98 * v, 1.02 * v) for symbol, v in model.params.items()}
    param_ranges.update({symbol: (v - 0.01, v + 0.01) for symbol, v in zip(end_points, M + N)})
    domains = {
        "tool_point_from_theta2": {"theta2_state": ((theta_m + 0.1, theta_n - 0.1), (-1.0, 1.0), (-1.0, 1.0))},
        "joints_along_line": {"path": ((0.0, 1.0), (-0.3, 0.3), (-0.1, 0.1))},
    }
    return KernelSet(
        name="scorbot_path",
        title="SCORBOT ER-VII pick-and-place path",
        source="Predescu and Stroe, On the kinematics of the SCORBOT ER-VII robot, section 4 (Eqs. 4.1-4.8)",
        kernels=[tool, line],
        params=params,
        domains=domains,
        param_ranges=param_ranges,
    )

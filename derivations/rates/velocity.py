"""Rate kinematics: from joint rates to tool rates and back, and where that breaks down.

Forward maps (velocity-model slides, "DVM"; Kumar section 5.5, Eq. 11; Rehiara Eq. 36):

    task rates        x_dot  = J_x(q) q_dot                         J_x = d task / d q
    tool twist        [v; w] = J(q) q_dot                           J: geometric Jacobian
    accelerations     x_ddot = J_x q_ddot + J_x_dot q_dot,          J_x_dot = sum_k dJ_x/dq_k q_dot_k

Inverse maps (slides' "IVM"; Kumar Eq. 12; Rehiara Eq. 37), by the shape of J_x:

* square (the planar arms, the AdeptThree): ``q_dot = adj(J_x) x_dot / det J_x`` and
  ``q_ddot = J_x^-1 (x_ddot - J_x_dot q_dot)`` in closed form;
* wide (the SCORBOT: 3 task coordinates, 5 joints): the minimum-norm solution
  ``J_x^T (J_x J_x^T)^-1 x_dot`` (joint rates in rad/s, lengths in units of L);
* the pose task of a 6R arm with a spherical wrist (the PUMA 560): the 12 pose
  rates are turned into the tool twist (``v = p_dot``, ``[w]x`` = the skew part of
  ``R_dot R^T``, its least-squares fit), which Paul's partition inverts by two
  3 x 3 solves (:mod:`derivations.rates.paul`);
* tall (a user's arm with fewer joints than task coordinates): least squares.

Near a singularity every inverse flags it and answers by damped least squares
(:mod:`derivations.rates.damping`: thresholds, damping and units).

Singularities: ``det J_x`` factored (square), ``det A det D`` (Paul), or
``det(J_x J_x^T)`` as a sum of squared minors (Cauchy-Binet; wide), each split
into its constant factor and the conditions under which it vanishes
(:class:`Singularities`, exposed as ``model.singularities``).

Everything here is derived once per robot and cached on disk
(:func:`derivations.support.cache.cached`).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import sympy as sp

from ..support.cache import cached
from ..chain import PRISMATIC, derivative
from .damping import (ClosedFormInverse, Minors, Scaling, closed_form_inverse, factored, measure_squared,
                      reference_length, regularised_solve, singular_flag)
from ..model import POSE_NAMES, Argument, NumericSolve, Output, SymbolicFunction, with_program
from ..program import Program
from .paul import WristPartition, wrist_partition

__all__ = ["RateKinematics", "Singularities", "SingularCondition", "rate_kinematics", "derive_rates",
           "time_derivative", "pose_rates_to_twist", "closed_form_shape", "TWIST_NAMES", "MAX_CLOSED_FORM"]

TWIST_NAMES = ("vx", "vy", "vz", "wx", "wy", "wz")
# Closed-form (adjugate) inverses are derived up to this size; beyond it they grow too large.
MAX_CLOSED_FORM = 4
# A wide or tall task Jacobian gets closed forms while its maximal minors are at most
# MAX_MINOR_SIZE x MAX_MINOR_SIZE and at most MAX_MINORS of them (the SCORBOT's 3 x 5: ten 3 x 3).
MAX_MINOR_SIZE = 3
MAX_MINORS = 10
# ... and while J_x has at most this many operations (count_ops).
MAX_CLOSED_FORM_OPS = 200

def rate_symbols(prefix: str, names) -> tuple[sp.Symbol, ...]:
    """``prefix`` + name for each name: ``qd1``, ``xd_x``, ``twist_vx`` (valid C identifiers)."""
    return tuple(sp.Symbol(f"{prefix}{name}", real=True) for name in names)


def time_derivative(M: sp.Matrix, q, qd) -> sp.Matrix:
    """``dM/dt = sum_k dM/dq_k q_dot_k`` (the chain rule along a joint trajectory).

    Entry by entry, each sum built at once: adding whole matrices joint by joint rebuilt
    every growing sum n times (a Panda's J_dot and task J_dot: 6 s of its 13 s of rates).
    """
    pairs = [(qk, qdk) for qk, qdk in zip(q, qd)]
    return M.applyfunc(lambda entry: sp.Add(*[derivative(entry, qk) * qdk for qk, qdk in pairs if entry.has(qk)]))


def pose_rates_to_twist(R: sp.Matrix, rates) -> sp.Matrix:
    """The tool twist ``[v; w]`` from the rates of the pose task (x, y, z, r11 .. r33).

    ``v`` is the position rate; ``[w]x = R_dot R^T`` for a consistent ``R_dot``, and
    ``w = vee((R_dot R^T - R R_dot^T) / 2)`` is the least-squares fit otherwise.
    The same map turns pose accelerations into ``[v_dot; w_dot]``: the skew part of
    ``R_ddot R^T`` is ``[w_dot]x`` (``R_dot R_dot^T`` is symmetric).
    """
    v = sp.Matrix(rates[:3])
    W = sp.Matrix(3, 3, list(rates[3:12])) * R.T
    w = sp.Matrix([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2
    return sp.Matrix.vstack(v, w)


@dataclass(frozen=True)
class SingularCondition:
    """A singular configuration set: where every one of ``factors`` vanishes."""

    name: str
    factors: tuple[sp.Expr, ...]
    description: str = ""

    @property
    def equations(self) -> tuple[sp.Eq, ...]:
        return tuple(sp.Eq(f, 0) for f in self.factors)

    @property
    def joints(self) -> tuple[str, ...]:
        symbols = set().union(*(f.free_symbols for f in self.factors))
        names = [str(s) for s in symbols if re.fullmatch(r"q\d+", str(s))]
        return tuple(sorted(names, key=lambda name: int(name[1:])))


@dataclass(frozen=True)
class Singularities:
    """Where a robot's inverse rate maps break down.

    ``matrix`` says which determinant: ``"det J_x"`` (square task Jacobian),
    ``"det J = det A det D"`` (geometric Jacobian through Paul's partition) or
    ``"det(J_x J_x^T)"`` (wide).  ``determinant`` is that determinant, factored;
    ``constant`` its factor free of the joints; the robot is singular where any one
    of ``conditions`` holds.  ``manipulability`` is Yoshikawa's ``w`` (|det J| when
    square, ``sqrt(det(J J^T))`` when wide) in SI units; ``singular`` is the
    kernels' flag (``mu < mu_0``, see :mod:`derivations.rates.damping`).
    """

    matrix: str
    determinant: sp.Expr
    constant: sp.Expr
    conditions: tuple[SingularCondition, ...]
    manipulability: sp.Expr
    singular: sp.Basic
    reference_length: sp.Expr


@dataclass(frozen=True)
class RateKinematics:
    """Everything at rate level for one robot (see the module docstring).

    ``strategy`` names how the inverse maps are built: ``"square"``, ``"wide"``, ``"numeric"``,
    ``"tall"``, ``"wrist partition"`` or ``None`` (no inverse kernels).
    """

    qd: tuple[sp.Symbol, ...]
    qdd: tuple[sp.Symbol, ...]
    xd: tuple[sp.Symbol, ...]
    xdd: tuple[sp.Symbol, ...]
    twist: tuple[sp.Symbol, ...]
    task_jacobian_dot: sp.Matrix
    jacobian_dot: sp.Matrix
    strategy: str | None
    inverse: ClosedFormInverse | None
    partition: WristPartition | None
    scaling: Scaling
    singularities: Singularities | None
    joint_velocity: sp.Matrix | None
    joint_acceleration: sp.Matrix | None
    functions: tuple[SymbolicFunction, ...]
    # A model written as a program (derivations.program): its steps and the rates' own after them,
    # which the rate expressions above read; () for an explicit model.
    program: tuple = ()


def rate_kinematics(model) -> RateKinematics | None:
    """The rate kinematics of ``model``, derived once and cached (None for a non-DH model)."""
    if model.chain is None:
        return None
    memo = model.__dict__.get("_rate_kinematics")
    if memo is not None:
        return memo
    key = "\n".join([model.name, repr(model.joint_types), repr(model.task_names), repr(model.limits),
                     sp.srepr(sp.Tuple(*model.q)), sp.srepr(sp.Tuple(*model.params)),
                     sp.srepr(sp.ImmutableMatrix(model.fk)), sp.srepr(sp.ImmutableMatrix(model.jacobian)),
                     sp.srepr(sp.ImmutableMatrix(model.task)), repr(model.chain),
                     repr(getattr(model, "rate_form", None)), sp.srepr(sp.Tuple(*map(sp.Tuple, model.program)))])
    result = cached(f"rates-{model.name}", key.encode(), lambda: derive_rates(model))
    model.__dict__["_rate_kinematics"] = result
    return result


def derive_rates(model) -> RateKinematics:
    """Derive every rate-level quantity of ``model`` (the slow step; prefer :func:`rate_kinematics`)."""
    q, n, m = model.q, model.n, len(model.task_names)
    qd = rate_symbols("qd", range(1, n + 1))
    qdd = rate_symbols("qdd", range(1, n + 1))
    xd = rate_symbols("xd_", model.task_names)
    xdd = rate_symbols("xdd_", model.task_names)
    twist = rate_symbols("twist_", TWIST_NAMES)
    Jx, J = model.task_jacobian, model.jacobian
    program = Program(model.program, taken=[str(s) for s in model.params]) if model.program else None
    if program is not None:  # the rates are steps of the program too (forward mode along qd)
        along = dict(zip(q, qd))
        Jx_dot = Jx.applyfunc(lambda e: program.time_derivative(e, along))
        J_dot = J.applyfunc(lambda e: program.time_derivative(e, along))
    else:
        Jx_dot = time_derivative(Jx, q, qd)
        J_dot = time_derivative(J, q, qd)
    length = reference_length(model.chain)
    scaling = Scaling(length, tuple(1 if name in ("x", "y", "z") else 0 for name in model.task_names),
                      tuple(1 if t == PRISMATIC else 0 for t in model.joint_types))

    # Paul's partition where the robot's module asks for it (the PUMA's paper model): its flag is
    # per 3 x 3 block determinant, not a condition number, and flagged a Meca500 and an LR Mate
    # at condition numbers below 1e3; any other arm solves at run time, flagged by cond(Jn).
    partition = (wrist_partition(model, length)
                 if model.task_names == POSE_NAMES and getattr(model, "rate_form", None) == "wrist partition"
                 else None)
    xd_col, xdd_col, qd_col = sp.Matrix(xd), sp.Matrix(xdd), sp.Matrix(qd)
    if partition is not None:
        strategy = "wrist partition"
    elif program is not None:  # closed forms of a program's Jacobian would factor its steps, not the joints
        strategy = "numeric"
    else:
        strategy = closed_form_shape(m, n, int(sp.count_ops(Jx)))
    inverse = minors = singularities = velocity = acceleration = None
    if strategy in ("square", "wide", "tall"):
        if strategy == "square":
            inverse = closed_form_inverse(Jx)
            minors = Minors.of_square(Jx, inverse)
        else:
            minors = Minors(Jx)
        if all(minor == 0 for minor in minors.maximal().values()):
            # J_x loses rank everywhere (a z task of a planar arm): no closed form divides by a
            # determinant that is identically zero; the run-time solve flags it and damps.
            strategy, inverse, minors = "numeric", None, None
    if strategy in ("square", "wide", "tall"):
        singularities = _singularities(model, strategy, scaling, inverse, partition, minors)
        velocity = regularised_solve(Jx, xd_col, scaling, minors, inverse).solution
        acceleration = regularised_solve(Jx, xdd_col - Jx_dot * qd_col, scaling, minors, inverse).solution
    elif strategy == "wrist partition":
        singularities = _singularities(model, strategy, scaling, inverse, partition, minors)
        R = model.fk[:3, :3]
        velocity, _ = partition.solve(pose_rates_to_twist(R, xd))
        acceleration, _ = partition.solve(pose_rates_to_twist(R, xdd) - J_dot * qd_col)

    rates = dict(qd=qd, qdd=qdd, xd=xd, xdd=xdd, twist=twist, task_jacobian_dot=Jx_dot, jacobian_dot=J_dot,
                 strategy=strategy, inverse=inverse, partition=partition, scaling=scaling,
                 singularities=singularities, joint_velocity=velocity, joint_acceleration=acceleration)
    functions = _functions(model, rates)
    if program is not None:
        functions = with_program(functions, program.steps)
    return RateKinematics(**rates, functions=tuple(functions), program=tuple(program.steps) if program else ())


def closed_form_shape(m: int, n: int, operations: int = 0) -> str:
    """How the inverse rate maps of an m x n task Jacobian are built, by its size alone.

    ``"square"`` (adjugate over determinant) up to ``MAX_CLOSED_FORM`` joints;
    ``"wide"`` or ``"tall"`` (damped least squares from the maximal minors) while
    there are at most ``MAX_MINORS`` of them, each at most ``MAX_MINOR_SIZE`` square;
    either only while ``J_x`` has at most ``MAX_CLOSED_FORM_OPS`` operations (the
    SCORBOT's: 116; a 5-joint chain with twists of pi/3 has 1018 and its minors took
    minutes).  Otherwise ``"numeric"``: the kernels solve the system at run time
    (:class:`derivations.model.NumericSolve`), which costs a few hundred operations
    where a symbolic 6 x 6 adjugate costs minutes to derive and 10^5 operations to run.
    """
    if operations > MAX_CLOSED_FORM_OPS:
        return "numeric"
    if m == n:
        return "square" if n <= MAX_CLOSED_FORM else "numeric"
    k = min(m, n)
    if k <= MAX_MINOR_SIZE and math.comb(max(m, n), k) <= MAX_MINORS:
        return "wide" if m < n else "tall"
    return "numeric"


# --- singularities -------------------------------------------------------------------------------

def _split(expr: sp.Expr, q) -> tuple[sp.Expr, list[sp.Expr]]:
    """``expr = constant * prod(factors^k)``: its factor free of ``q`` and the rest, sign-normalised."""
    constant, factors = sp.S.One, []
    joints = set(q)
    for term in sp.Mul.make_args(expr):
        base, power = (term.base, term.exp) if term.is_Pow and term.exp.is_Integer and term.exp > 0 else (term, 1)
        if not base.free_symbols & joints:
            constant *= term
            continue
        if base.could_extract_minus_sign():
            base, constant = -base, constant * (-1)**power
        if base not in factors:
            factors.append(base)
    return constant, factors


def _same_up_to_sign(a: sp.Expr, b: sp.Expr) -> bool:
    return sp.expand(a - b) == 0 or sp.expand(a + b) == 0


def _reduce_simultaneous(residuals: list[sp.Expr], q) -> list[sp.Expr]:
    """Simplify "all of ``residuals`` vanish" where one of them depends on a single joint.

    Each root of that one is substituted into the others; when every root leaves
    the same remaining conditions, the set is that factor plus those (recursively).
    The SCORBOT's three residual minors reduce to ``sin(q4) = 0, sin(q3) = 0``.
    """
    for f in residuals:
        joints = f.free_symbols & set(q)
        if len(joints) != 1:
            continue
        joint = joints.pop()
        try:
            roots = sp.solve(f, joint)
        except NotImplementedError:
            continue
        if not roots:
            continue
        branches = []
        for root in roots:
            remaining = []
            for g in residuals:
                if g is f:
                    continue
                _, parts = _split(factored(g.subs(joint, root)), q)
                if parts:
                    remaining.append(sp.Mul(*parts))
            branches.append(remaining)
        first = branches[0]
        if all(len(b) == len(first) and all(any(_same_up_to_sign(x, y) for y in b) for x in first)
               for b in branches[1:]):
            unique = []
            for g in first:
                if not any(_same_up_to_sign(g, u) for u in unique):
                    unique.append(g)
            return [f] + _reduce_simultaneous(unique, q)
    return residuals


def _condition(model, factors, q) -> SingularCondition:
    """The set where ``factors`` vanish, named as the robot's module names it (``model.singular_names``,
    keyed by the joints the factors involve), else by those joints."""
    joints = set().union(*(f.free_symbols for f in factors)) & set(q)
    key = tuple(sorted((str(s) for s in joints), key=lambda name: int(name[1:])))
    name, description = getattr(model, "singular_names", {}).get(key, (f"factor in {', '.join(key)}", ""))
    return SingularCondition(name, tuple(factors), description)


def _singularities(model, strategy, scaling: Scaling, inverse, partition, minors) -> Singularities | None:
    q, length = model.q, scaling.length
    if strategy == "wrist partition":
        determinant = partition.determinant
        arm_constant, arm_factors = _split(partition.arm_inverse.determinant, q)
        wrist_constant, wrist_factors = _split(partition.wrist_inverse.determinant, q)
        constant = arm_constant * wrist_constant
        conditions = [_condition(model, (f,), q) for f in arm_factors + wrist_factors]
        arm_flag, wrist_flag = partition.singular_flags()
        return Singularities("det J = det A det D", determinant, constant, tuple(conditions),
                             sp.Abs(determinant), sp.Or(arm_flag, wrist_flag), length)
    if strategy == "square":
        constant, factors = _split(inverse.determinant, q)
        conditions = [_condition(model, (f,), q) for f in factors]
        return Singularities("det J_x", inverse.determinant, constant, tuple(conditions),
                             sp.Abs(inverse.determinant), singular_flag(measure_squared(minors, scaling)), length)
    if strategy == "wide":
        maximal = {key: minor for key, minor in minors.maximal().items() if minor != 0}
        split = {key: _split(minor, q) for key, minor in maximal.items()}
        first = next(iter(split.values()))[1]
        common = [f for f in first if all(any(_same_up_to_sign(f, g) for g in fs) for _, fs in split.values())]
        residuals = []
        for constant_part, fs in split.values():
            rest = [f for f in fs if not any(_same_up_to_sign(f, c) for c in common)]
            residuals.append(sp.Mul(*rest))
        conditions = [_condition(model, (f,), q) for f in common]
        if all(r.free_symbols & set(q) for r in residuals):
            conditions.append(_condition(model, _reduce_simultaneous(residuals, q), q))
        squares = sum((c * sp.Mul(*fs) / sp.Mul(*common))**2 for c, fs in split.values())
        determinant = sp.Mul(*[f**2 for f in common]) * squares
        manipulability = sp.sqrt(sum(minor**2 for minor in maximal.values()))
        return Singularities("det(J_x J_x^T)", determinant, sp.S.One, tuple(conditions), manipulability,
                             singular_flag(measure_squared(minors, scaling)), length)
    if strategy == "tall":  # the Gram determinant by Cauchy-Binet, not analysed further
        gram = sum((minor**2 for minor in minors.maximal().values()), sp.S.Zero)
        return Singularities("det(J_x^T J_x)", gram, sp.S.One, (), sp.sqrt(gram),
                             singular_flag(measure_squared(minors, scaling)), length)
    return None  # too large for closed forms: more than MAX_CLOSED_FORM joints and no wrist partition


# --- kernels -------------------------------------------------------------------------------------

def _functions(model, rates: dict) -> list[SymbolicFunction]:
    n, m = model.n, len(model.task_names)
    task = ", ".join(model.task_names)
    units = ", ".join(f"{s}: {'m' if t == PRISMATIC else 'rad'}" for s, t in zip(model.q, model.joint_types))
    q = Argument("q", model.q, f"joint coordinates, shape (..., {n}) ({units})")
    qd = Argument("qd", rates["qd"], f"joint rates, shape (..., {n}) (per second)")
    qdd = Argument("qdd", rates["qdd"], f"joint accelerations, shape (..., {n}) (per second squared)")
    xd = Argument("xd", rates["xd"], f"task rates d({task})/dt, shape (..., {m}) (per second)")
    xdd = Argument("xdd", rates["xdd"], f"task accelerations, shape (..., {m}) (per second squared)")
    twist = Argument("twist", rates["twist"], "tool twist [v; w], shape (..., 6): v (m/s) of the tool point, "
                                              "w (rad/s), base frame")
    Jx, J = model.task_jacobian, model.jacobian
    qd_col, qdd_col = sp.Matrix(rates["qd"]), sp.Matrix(rates["qdd"])
    singular = rates["singularities"].singular if rates["singularities"] is not None else sp.false
    flag_doc = "true where the normalised manipulability is below mu_0 (see derivations/rates/damping.py)"

    def flag():
        return Output("singular", (singular,), (), "bool", flag_doc)

    functions = [
        SymbolicFunction("task_velocity", (q, qd), (Output("xd", tuple(Jx * qd_col), (m,)),),
                         f"Task rates x_dot = J_x q_dot, shape (..., {m})."),
        SymbolicFunction("twist", (q, qd), (Output("twist", tuple(J * qd_col), (6,)),),
                         "Tool twist [v; w] = J q_dot (geometric Jacobian), shape (..., 6); m/s and rad/s."),
        SymbolicFunction("task_jacobian_dot", (q, qd), (Output.from_matrix("Jx_dot", rates["task_jacobian_dot"]),),
                         f"d(J_x)/dt = sum_k dJ_x/dq_k q_dot_k, shape (..., {m}, {n})."),
        SymbolicFunction("jacobian_dot", (q, qd), (Output.from_matrix("J_dot", rates["jacobian_dot"]),),
                         f"d(J)/dt of the geometric Jacobian, shape (..., 6, {n})."),
        SymbolicFunction("task_acceleration", (q, qd, qdd),
                         (Output("xdd", tuple(Jx * qdd_col + rates["task_jacobian_dot"] * qd_col), (m,)),),
                         f"Task accelerations x_ddot = J_x q_ddot + J_x_dot q_dot, shape (..., {m})."),
    ]
    if rates["singularities"] is not None:
        functions.append(SymbolicFunction(
            "manipulability", (q,), (Output("manipulability", (rates["singularities"].manipulability,), ()), flag()),
            f"Manipulability w ({rates['singularities'].matrix}; |det| or sqrt(det J J^T)), "
            "shape (...), and the singular flag, shape (...)."))
    if rates["joint_velocity"] is not None:
        how = {"square": "adj(J_x) x_dot / det J_x",
               "wide": "minimum-norm J_x^T (J_x J_x^T)^-1 x_dot",
               "tall": "least squares (J_x^T J_x)^-1 J_x^T x_dot",
               "wrist partition": "twist from the pose rates, then Paul's partitioned inverse"}[rates["strategy"]]
        functions += [
            SymbolicFunction("joint_velocity", (q, xd), (Output("qd", tuple(rates["joint_velocity"]), (n,)), flag()),
                             f"Joint rates from task rates: {how}; damped least squares where singular. "
                             f"Shapes (..., {n}) and (...)."),
            SymbolicFunction("joint_acceleration", (q, qd, xdd),
                             (Output("qdd", tuple(rates["joint_acceleration"]), (n,)), flag()),
                             "Joint accelerations J_x^-1 (x_ddot - J_x_dot q_dot), solved as joint_velocity. "
                             f"Shapes (..., {n}) and (...)."),
        ]
    if rates["partition"] is not None:
        solution, partition_flag = rates["partition"].solve(sp.Matrix(rates["twist"]))
        functions.append(SymbolicFunction(
            "joint_velocity_from_twist", (q, twist),
            (Output("qd", tuple(solution), (n,)), Output("singular", (partition_flag,), (), "bool", flag_doc)),
            "Joint rates from the tool twist by Paul's wrist partition (two 3 x 3 solves; "
            f"damped least squares per block where singular). Shapes (..., {n}) and (...)."))
    if rates["strategy"] == "numeric":
        functions += _numeric_functions(model, rates, (q, qd, xd, xdd, twist))
    return functions


def _numeric_functions(model, rates: dict, arguments) -> list[SymbolicFunction]:
    """manipulability, joint_velocity, joint_acceleration and joint_velocity_from_twist as
    linear systems solved at run time (``NumericSolve``), each beside the kernel that forms its
    system in closed form (``<name>_system``).

    The pose task goes through the tool twist, as the PUMA's wrist partition does: the 12 pose
    rates become ``[v; w]`` and the 6 x n geometric Jacobian is solved; other tasks solve J_x.
    """
    q, qd, xd, xdd, twist = arguments
    n = model.n
    scaling = rates["scaling"]
    qd_col = sp.Matrix(rates["qd"])
    if model.task_names == POSE_NAMES:
        R = model.fk[:3, :3]
        A, A_dot, rows, what = model.jacobian, rates["jacobian_dot"], (1, 1, 1, 0, 0, 0), "J (the tool twist)"

        def rhs(values):
            return pose_rates_to_twist(R, values)
    else:
        A, A_dot, rows, what = model.task_jacobian, rates["task_jacobian_dot"], scaling.rows, "J_x"

        def rhs(values):
            return sp.Matrix(values)
    m = A.rows
    L = scaling.length
    row_scale = Output("row_scale", tuple(L**-r for r in rows), (m,), doc="1/L on length rows, 1 on angle rows")
    col_scale = Output("col_scale", tuple(L**c for c in scaling.columns), (n,),
                       doc="L on prismatic columns, 1 on revolute ones")
    geometric = (1, 1, 1, 0, 0, 0)
    flag_doc = (f"true where cond(An) > {NumericSolve.COND_LIMIT:g} for the normalised An: an exact solve would "
                "lose more than 4 of the 16 digits (derivations.model.NumericSolve)")
    how = {"solution": "exact where regular (minimum norm when redundant, least squares when short of joints), "
                       "damped least squares where singular; solved at run time",
           "measure": "the product of the singular values, computed at run time"}

    def pair(name, args, matrix, b, scales, result, doc, kind="solution"):
        outputs = [Output.from_matrix("A", matrix, f"the {matrix.rows} x {matrix.cols} matrix of the system")]
        if b is not None:
            outputs.append(Output("b", tuple(b), (matrix.rows,), doc="the right-hand side"))
        outputs += list(scales)
        system = SymbolicFunction(
            f"{name}_system", args, tuple(outputs),
            f"The linear system that {name} solves at run time: A, "
            + ("b, " if b is not None else "") + "row_scale, col_scale (closed forms).")
        solved = SymbolicFunction(
            name, args, (result, Output("singular", (), (), "bool", flag_doc)),
            f"{doc}: {how[kind]}. Shapes {result.shape and f'(..., {result.shape[0]})' or '(...)'} and (...).",
            solve=NumericSolve(system.name, matrix.rows, matrix.cols, kind))
        return [system, solved]

    scales = (row_scale, col_scale)
    twist_scales = (Output("row_scale", tuple(L**-r for r in geometric), (6,), doc=row_scale.doc), col_scale)
    functions = pair("manipulability", (q,), A, None, scales, Output("manipulability", (), ()),
                     f"Manipulability w = sqrt(det(A A^T)) of A = {what} (SI units), and the singular flag",
                     kind="measure")
    functions += pair("joint_velocity", (q, xd), A, rhs(rates["xd"]), scales, Output("qd", (), (n,)),
                      f"Joint rates from task rates, A q_dot = b with A = {what}")
    functions += pair("joint_acceleration", (q, qd, xdd), A, rhs(rates["xdd"]) - A_dot * qd_col, scales,
                      Output("qdd", (), (n,)),
                      f"Joint accelerations, A q_ddot = b - A_dot q_dot with A = {what}")
    functions += pair("joint_velocity_from_twist", (q, twist), model.jacobian, sp.Matrix(rates["twist"]),
                      twist_scales, Output("qd", (), (n,)), "Joint rates from the tool twist, J q_dot = [v; w]")
    return functions

"""A robot's kernels, assembled: the one place that puts a model, its IK, its rates and its dynamics together.

:func:`robot_kernels` is the list code generation reads (``RobotModel.functions()``), in a fixed
order: the kinematics (fk, frames, jacobian, jacobian_tool, task, task_jacobian), ``ik``, a
general 6R's ``ik_equations``, the rate kernels (:mod:`derivations.rates.velocity`), the robot's own
``extra_functions`` (declared by its module under ``derivations/robots/``), then the dynamics
(:mod:`derivations.mechanics.dynamics`).  :func:`ik_kernel` turns the IK branches into the ``ik`` kernel,
step by step where the branches carry steps.

This module imports the model and the layers that derive from it; the model imports none of
them, and reaches this module through :func:`derivations.model.install_assembly`, called below.
"""
from __future__ import annotations

import sys

from dataclasses import replace

import sympy as sp

from .chain import REVOLUTE
from .ik.general_6r import equations_function, fast_equations_function
from .ik.primitives import ClampUnit, WrapAngle, kernel_form
from .model import Argument, Output, RobotModel, SymbolicFunction, install_assembly, with_program
from .program import needed

__all__ = ["robot_kernels", "position_kernels", "kinematics_kernels", "ik_kernel", "rate_kernels", "rates", "dynamics"]


def kinematics_kernels(model: RobotModel) -> list[SymbolicFunction]:
    """fk, frames, jacobian, jacobian_tool, task and task_jacobian, each with the program steps it reads."""
    n, m = model.n, len(model.task_names)
    q = Argument("q", model.q, f"joint coordinates, shape (..., {n}) ({model._units()})")
    count = len(model.frames)
    frames = sp.Array([list(f) for f in model.frames]).reshape(count, 4, 4)
    return with_program([
        SymbolicFunction("fk", (q,), (Output.from_matrix("T", model.fk),),
                         "Tool pose: homogeneous transform base -> tool, shape (..., 4, 4); metres."),
        SymbolicFunction("frames", (q,), (Output("frames", tuple(sp.flatten(frames.tolist())), (count, 4, 4)),),
                         f"Frames T_0 (base) .. T_{n} (" + ("flange), then the tool frame" if count > n + 1 else "tool)")
                         + f", shape (..., {count}, 4, 4)."),
        SymbolicFunction("jacobian", (q,), (Output.from_matrix("J", model.jacobian),),
                         f"Geometric Jacobian [v; w] of the tool point in the base frame, shape (..., 6, {n})."),
        SymbolicFunction("jacobian_tool", (q,), (Output.from_matrix("J_tool", model.jacobian_tool),),
                         f"Geometric Jacobian [v; w] of the tool point in the tool frame (the Robotics Toolbox's "
                         f"jacobe, Pinocchio's LOCAL): [R^T v; R^T w], shape (..., 6, {n})."),
        SymbolicFunction("task", (q,), (Output("x", tuple(model.task), (m,)),),
                         f"Task coordinates {', '.join(model.task_names)}, shape (..., {m})."),
        SymbolicFunction("task_jacobian", (q,), (Output.from_matrix("Jx", model.task_jacobian),),
                         f"d task / d q, shape (..., {m}, {n})."),
    ], model.program)


def robot_kernels(model: RobotModel) -> list[SymbolicFunction]:
    """The kernels of the generated-code contract, in a fixed order (see the module's docstring)."""
    return position_kernels(model) + model.rate_functions() + model.dynamics_functions()


def position_kernels(model: RobotModel) -> list[SymbolicFunction]:
    """The first of :func:`robot_kernels`: those that need neither the rate kinematics nor the
    dynamics (a render prepares them while those are derived)."""
    # A general 6R (derivations.ik.general_6r): the closed-form equations its ik solves numerically, and
    # the pose with the Jacobian at once for its Newton steps (one set of sines where task and jacobian
    # took two).
    general = equations_function(model)
    return (kinematics_kernels(model) + ([model.ik_function()] if model.ik else [])
            + ([general[0], fast_equations_function(*general), *pose_and_jacobian(model),
                pose_and_jacobian_from_sines(model)] if general else []))


def pose_and_jacobian(model: RobotModel) -> list[SymbolicFunction]:
    """``ik_6r_pose_jacobian(q) -> (x, J)``: ``task`` and ``jacobian`` in one kernel, for the general 6R's
    Newton steps (general_6r.c.j2), which read both at each candidate."""
    n, m = model.n, len(model.task_names)
    q = Argument("q", model.q, f"joint coordinates, shape (..., {n}) ({model._units()})")
    return with_program([SymbolicFunction(
        "ik_6r_pose_jacobian", (q,),
        (Output("x", tuple(model.task), (m,)), Output.from_matrix("J", model.jacobian)),
        f"Task coordinates {', '.join(model.task_names)} (..., {m}) and the geometric Jacobian [v; w] of the tool "
        f"point in the base frame (..., 6, {n}) at once: the general 6R's Newton steps read both.")], model.program)


def pose_and_jacobian_from_sines(model: RobotModel) -> SymbolicFunction:
    """``ik_6r_pose_jacobian_sc(q, cs) -> (x, J)``: :func:`pose_and_jacobian` with the sine and the cosine
    of every angle that is a sum of joints (with signs) and a constant taken from ``cs`` (c1, s1, ..., cn,
    sn, of q1 .. qn) by the addition formulas, not from ``sin`` and ``cos``: the general 6R's C has them
    from its candidates (the half-angle tangents and the loop's atan2 terms), where they cost nothing,
    and Newton's first look at a candidate then calls no ``sin`` (general_6r.c.j2).  An angle of another
    form keeps its ``sin`` and ``cos`` of ``q``."""
    kernel = pose_and_jacobian(model)[0]
    n = model.n
    cs = tuple(sp.Symbol(f"{f}{k + 1}_of_q", real=True) for k in range(n) for f in ("cos", "sin"))
    joint = {q: k for k, q in enumerate(model.q)}
    linear: dict = {}  # a step that is a sum of joints and a constant: that sum (its sine from cs too)
    memo: dict = {}

    def pair(angle):
        """(sin, cos) of angle by the addition formulas over its terms, or None."""
        s, c = sp.S.Zero, sp.S.One
        for term in sp.Add.make_args(angle.xreplace(linear)):
            sign, base = (-1, -term) if term.could_extract_minus_sign() else (1, term)
            if base in joint:
                t = (sign * cs[2 * joint[base] + 1], cs[2 * joint[base]])
            elif not (term.free_symbols & set(model.q)):
                t = (sp.sin(term), sp.cos(term))
            else:
                return None
            s, c = s * t[1] + c * t[0], c * t[1] - s * t[0]
        return s, c

    def rewrite(expr):
        expr = sp.sympify(expr)
        swaps = {}  # not `replace`: that is dataclasses.replace, which this function calls below
        for f in expr.atoms(sp.sin, sp.cos):
            if f not in memo:
                found = pair(f.args[0])
                memo[f] = f if found is None else found[0 if isinstance(f, sp.sin) else 1]
            swaps[f] = memo[f]
        return expr.xreplace(swaps) if swaps else expr

    steps = []
    for symbol, expr in kernel.definitions:
        expr = rewrite(expr)
        steps.append((symbol, expr))
        if expr.is_Add and all(t.is_number or t in joint or -t in joint or t in linear for t in expr.args):
            linear[symbol] = expr.xreplace(linear)
    outputs = tuple(replace(o, values=tuple(rewrite(v) for v in o.values)) for o in kernel.outputs)
    reads = [v for o in outputs for v in o.values]
    return replace(kernel, name="ik_6r_pose_jacobian_sc",
                   arguments=kernel.arguments + (Argument("cs", cs, f"cos and sin of each joint, shape (..., {2 * n})"),),
                   outputs=outputs, definitions=needed(tuple(steps), reads),
                   doc=kernel.doc + " The sines and cosines of the joints from cs (cos q1, sin q1, ...), where "
                   "q gives the angles only where an angle is not a sum of joints and a constant.")


def ik_kernel(model: RobotModel) -> SymbolicFunction:
    """The ``ik`` kernel: every branch of ``model.ik`` at once.

    ``Q`` (k, n) holds each branch's joint values (revolute joints wrapped to
    (-pi, pi], see ``derivations.ik.kernel_form``); ``valid`` (k,) is each
    branch's existence condition.  The generated code also marks a branch
    invalid wherever its joint values are not finite (a NaN or inf target).
    """
    k, n = len(model.ik), model.n
    names = ", ".join(b.name for b in model.ik)
    x = Argument("x", model.task_symbols, f"task coordinates {', '.join(model.task_names)}, shape (..., "
                 f"{len(model.task_names)})")
    arguments = (x,)
    if model.ik_free is not None:
        free = model.q[model.ik_free]
        arguments += (Argument("free", (free,), f"the value of the free joint {free} "
                               f"({model.joint_unit(model.ik_free)}), shape (..., 1), (...) or a number, "
                               "at most 1e4 in size"),)
    revolute = [t == REVOLUTE for t in model.joint_types]
    definitions: tuple = ()
    if all(b.step_condition is not None for b in model.ik):
        definitions, values, valid = _ik_program(model, revolute)
    else:
        values = tuple(kernel_form(e, r) for branch in model.ik for e, r in zip(branch.solution, revolute))
        valid = tuple(sp.sympify(b.condition) for b in model.ik)
    return SymbolicFunction(
        "ik", arguments,
        (Output("Q", values, (k, n), "float", f"joint values of each branch ({names})"),
         Output("valid", valid, (k,), "bool", "whether each branch exists")),
        f"Inverse kinematics, all {k} branches ({names}): Q (..., {k}, {n}), valid (..., {k}).",
        definitions=definitions)


def _ik_program(model: RobotModel, revolute):
    """The branches' steps as one straight-line program: a step that several branches share
    (the same definition in the same earlier steps) once, each other step renamed
    ``ik_<name>_b<k>`` after the first branch k that defines it."""
    from .ik.decompose import substitute_unevaluated  # loaded on first use, as derivations.ik loads it
    taken = {str(s) for s in model.params} | {str(s) for s in model.task_symbols}
    definitions, known = [], {}
    values, valid = [], []
    for k, branch in enumerate(model.ik):
        rename: dict = {}
        memo: dict = {}
        for symbol, expr in branch.steps:
            expr = substitute_unevaluated(expr, rename, memo)
            key = (symbol.name, expr)
            if key not in known:
                name = f"ik_{symbol.name}_b{k}"
                if name in taken:
                    raise ValueError(f"{model.name}: the inverse-kinematics step {name} is also a parameter's name")
                taken.add(name)
                known[key] = sp.Symbol(name, real=True)
                definitions.append((known[key], expr))
            rename[symbol] = known[key]
        values.extend(kernel_form(rename.get(q, q), r) for q, r in zip(model.q, revolute))  # q: a free joint
        valid.append(substitute_unevaluated(branch.step_condition, rename, memo))
    return sines_from_roots(definitions, values, valid, taken)


def sines_from_roots(definitions, values, valid, taken: set):
    """The program with ``sin`` and ``cos`` of its angles written without calling them, where the
    angle is a root the program computed: ``theta = atan2(a, b)`` has ``sin = a / r`` and
    ``cos = b / r`` with ``r = sqrt(a**2 + b**2)``; ``acos(c)`` has ``sin = sqrt((1 - c)(1 + c))`` and
    ``cos = c``; a sum or a negation of such angles and constants by the addition formulas.

    Each ``sin(theta)`` and ``cos(theta)`` a later step reads becomes a step of its own,
    ``_sin_<theta>`` / ``_cos_<theta>``, placed right after ``theta``.  Where ``r`` is 0 (an
    ``atan2(0, 0)`` at a singular target, whose angle is a convention: 0 or pi by the signs of
    the zeros) the sine is 0 and the cosine the sign of ``b``'s zero, as ``atan2`` returns, so
    that the sine and cosine always belong to the angle the kernel returns.  The result is the same
    number to rounding; a 6-joint arm's ``ik`` calls about half as many transcendental
    functions (the xArm-type three-parallel arm: 44 sines and cosines before).
    """
    from .ik.decompose import substitute_unevaluated
    used = set()
    for expr in [e for _, e in definitions] + list(values) + list(valid):
        used |= {f for f in sp.sympify(expr).atoms(sp.sin, sp.cos) if f.args[0].is_Symbol}
    if not used:
        return tuple(definitions), tuple(values), tuple(valid)
    pairs: dict = {}      # angle step -> (sin, cos), as expressions of earlier steps
    replace: dict = {}    # sin(theta) / cos(theta) -> its step
    memo: dict = {}
    result = []
    for symbol, expr in definitions:
        expr = substitute_unevaluated(expr, replace, memo)
        result.append((symbol, expr))
        found = _sine_cosine(expr, pairs)
        if found is None:
            continue
        pairs[symbol] = found
        for function, value in zip((sp.sin, sp.cos), found):
            if function(symbol) in used:
                name = f"_{function.__name__}_{symbol.name}"
                if name in taken:
                    raise ValueError(f"the inverse-kinematics step {name} is also a parameter's name")
                taken.add(name)
                replace[function(symbol)] = sp.Symbol(name, real=True)
                result.append((replace[function(symbol)], value))
        pairs[symbol] = tuple(replace.get(f(symbol), v) for f, v in zip((sp.sin, sp.cos), found))
    values = tuple(substitute_unevaluated(v, replace, memo) for v in values)
    valid = tuple(substitute_unevaluated(v, replace, memo) for v in valid)
    return tuple(result), values, valid


def _sine_cosine(expr, pairs: dict):
    """(sin, cos) of the angle ``expr`` without calling sin or cos of a computed angle, or None."""
    if expr in pairs:
        return pairs[expr]
    if expr.is_number:
        return (sp.sin(expr), sp.cos(expr)) if expr.is_real else None
    if isinstance(expr, WrapAngle):
        return _sine_cosine(expr.args[0], pairs)
    if isinstance(expr, sp.atan2):
        # a / r and b / r; at r = 0 atan2's own convention: atan2(+-0, +0) = +-0, atan2(+-0, -0) = +-pi,
        # whose cosine the sign of the zero b gives (1 / b is +inf or -inf)
        a, b = expr.args
        if b.is_number:   # atan2(a, 0) and the like: left to sin and cos (1 / b would be a number's)
            return None
        r = sp.sqrt(a**2 + b**2)
        return (sp.Piecewise((a / r, r > 0), (0, True)),
                sp.Piecewise((b / r, r > 0), (1, 1 / b > 0), (-1, True)))
    if isinstance(expr, sp.acos):
        c = expr.args[0]
        if not isinstance(c, ClampUnit):  # an argument that may leave [-1, 1]: keep acos's own NaN
            return None
        return sp.sqrt((1 - c) * (1 + c)), c
    if isinstance(expr, sp.Piecewise):   # the same choice of the pieces' sines and cosines
        found = [_sine_cosine(piece.expr, pairs) for piece in expr.args]
        if any(pair is None for pair in found):
            return None
        return tuple(sp.Piecewise(*((pair[k], piece.cond) for pair, piece in zip(found, expr.args)),
                                  evaluate=False) for k in (0, 1))
    if isinstance(expr, sp.Mul) and len(expr.args) == 2 and expr.args[0] == -1:
        inner = _sine_cosine(expr.args[1], pairs)
        return None if inner is None else (-inner[0], inner[1])
    if isinstance(expr, sp.Add):
        s, c = sp.S.Zero, sp.S.One
        for term in expr.args:
            pair = _sine_cosine(term, pairs)
            if pair is None:
                return None
            s, c = s * pair[1] + c * pair[0], c * pair[1] - s * pair[0]
        return s, c
    return None


def rates(model: RobotModel):
    """The rate kinematics of ``model`` (:func:`derivations.rates.velocity.rate_kinematics`)."""
    from .rates.velocity import rate_kinematics
    return rate_kinematics(model)


def rate_kernels(model: RobotModel) -> list[SymbolicFunction]:
    """The velocity and acceleration kernels, then the kernels the robot's own module declared."""
    found = model.rates
    return ([] if found is None else list(found.functions)) + list(model.extra_functions)


def dynamics(model: RobotModel):
    """The equations of motion of ``model`` (:func:`derivations.mechanics.dynamics.dynamics`); None without inertials."""
    from .mechanics.dynamics import dynamics as derive
    return derive(model)


install_assembly(sys.modules[__name__])

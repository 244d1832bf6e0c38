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

import sympy as sp

from .chain import REVOLUTE
from .ik.general_6r import equations_function
from .ik.primitives import kernel_form
from .model import Argument, Output, RobotModel, SymbolicFunction, install_assembly, with_program

__all__ = ["robot_kernels", "kinematics_kernels", "ik_kernel", "rate_kernels", "rates", "dynamics"]


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
    # A general 6R (derivations.ik.general_6r): the closed-form equations its ik solves numerically.
    general = equations_function(model)
    return kinematics_kernels(model) + ([model.ik_function()] if model.ik else []) + \
        ([general[0]] if general else []) + model.rate_functions() + model.dynamics_functions()


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
    return tuple(definitions), tuple(values), tuple(valid)


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

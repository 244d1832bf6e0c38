"""The robot model: what a derivation produces and what code generation reads.

A :class:`RobotModel` holds the symbolic kinematics of one robot (frames, tool
pose, geometric Jacobian, task coordinates and their Jacobian, inverse-kinematics
branches) and describes each kernel to generate as a :class:`SymbolicFunction`:
a name, its array arguments (each a vector of symbols) and its outputs (arrays
of SymPy expressions).  Code generation needs nothing else.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import sympy as sp

from .chain import PRISMATIC, REVOLUTE, Chain, derivative, simplify_derivative, simplify_entry, simplify_product
from .ik import kernel_form
from .chain_program import explicit_pays, program_kinematics
from .chain_program import task_jacobian as program_task_jacobian
from .program import inline, needed

__all__ = ["Argument", "Output", "Requirement", "NumericSolve", "SymbolicFunction", "IKBranch", "RobotModel",
           "task_coordinates", "with_program", "APPROACH_NAMES", "TASK_ITEMS", "ANGLE_TASKS", "pitch_joints"]


@dataclass(frozen=True)
class Argument:
    """An array argument ``name`` of shape (..., len(symbols))."""

    name: str
    symbols: tuple[sp.Symbol, ...]
    doc: str = ""


@dataclass(frozen=True)
class Output:
    """An output array: ``values`` flattened row-major, of the given ``shape``.

    ``dtype`` is ``"float"`` or ``"bool"`` (a bool output is a SymPy boolean
    expression per entry).
    """

    name: str
    values: tuple[sp.Basic, ...]
    shape: tuple[int, ...]
    dtype: str = "float"
    doc: str = ""

    @classmethod
    def from_matrix(cls, name: str, matrix, doc: str = "", dtype: str = "float") -> "Output":
        array = sp.Array(matrix)
        return cls(name, tuple(sp.flatten(array.tolist())) if array.shape else (array[()],),
                   tuple(array.shape), dtype, doc)


@dataclass(frozen=True)
class Requirement:
    """A condition the arguments of a kernel must meet for its outputs to exist.

    ``kind`` is ``"unreachable"`` (the target lies outside the workspace) or
    ``"singular"`` (a configuration where the map divides by zero).  The
    generated numpy kernel raises ``ValueError`` (subclasses ``UnreachableError``
    and ``SingularError``) naming ``message``; the C kernel returns a status
    code and writes no output.  Write ``condition`` on the very subexpression the
    outputs use (the argument of ``acos``, the radicand under a denominator):
    conditions and outputs share one CSE, so the test is made on the same
    floating-point value the outputs are computed from.
    """

    condition: sp.Basic
    kind: str
    message: str

    KINDS = ("unreachable", "singular")

    def __post_init__(self):
        if self.kind not in self.KINDS:
            raise ValueError(f"requirement kind must be one of {self.KINDS}, got {self.kind!r}")


@dataclass(frozen=True)
class NumericSolve:
    """A kernel whose outputs come from a small linear system solved at run time.

    The system is the kernel ``system`` of the same model, whose outputs are
    ``A`` (rows x cols), ``b`` (rows; absent when ``kind`` is ``"measure"``),
    ``row_scale`` (rows) and ``col_scale`` (cols): every entry a closed form.
    The generated code normalises ``An = diag(row_scale) A diag(col_scale)``
    (lengths in units of the arm's reference length, so that the test below is
    the same for an arm and for that arm scaled by 10), takes the singular values
    of ``An`` by one-sided Jacobi rotations (C) or LAPACK (numpy), and answers:

    * ``kind == "solution"``: ``x = diag(col_scale) y`` with
      ``y = sum_i s_i / (s_i^2 + lambda^2) (u_i . bn) v_i``: the exact solution
      (square), minimum-norm (wide) or least squares (tall) where the
      configuration is regular, damped least squares where it is singular;
    * ``kind == "measure"``: Yoshikawa's manipulability of ``A`` (the product
      of its singular values, SI units).

    Both also give ``singular``: ``s_min < t = s_max / COND_LIMIT`` on ``An``, where
    an exact solve would lose more than 4 of the 16 digits; there ``lambda^2 =
    (10 t)^2 (1 - (s_min / t)^2)`` (zero at the threshold, so continuous, and 10 t
    at an exact singularity, as the closed forms' ``derivations.damping``), else 0.
    """

    system: str
    rows: int
    cols: int
    kind: str = "solution"

    COND_LIMIT = 1e4
    DAMPING = 10.0  # lambda_max / t


@dataclass(frozen=True)
class SymbolicFunction:
    """One kernel to generate: ``name(arguments..., **params) -> outputs``.

    ``requires`` lists the conditions checked, in order, before any output is
    computed (empty for maps defined everywhere).  With ``solve`` set, the
    outputs carry no expressions: they come from the linear system that the
    kernel ``solve.system`` computes, solved at run time (:class:`NumericSolve`).
    """

    name: str
    arguments: tuple[Argument, ...]
    outputs: tuple[Output, ...]
    doc: str = ""
    requires: tuple[Requirement, ...] = ()
    solve: NumericSolve | None = None
    # A straight-line program the outputs are written in: ordered (symbol, expression), each
    # expression in the arguments, the parameters and the symbols defined before it.  The
    # automatic inverse kinematics is emitted this way, step by step, rather than as trees
    # whose shared parts a CSE would have to find again (minutes for a six-joint arm).
    definitions: tuple[tuple[sp.Symbol, sp.Expr], ...] = ()


@dataclass(frozen=True)
class IKBranch:
    """One closed-form inverse-kinematics branch.

    ``solution`` holds one expression per joint in the task symbols and the
    parameters; ``condition`` is the SymPy condition under which the branch
    exists (``True`` when it always does).  ``steps``, where a derivation has
    them, are the same solution as the paper or textbook writes it: ordered
    definitions ``(symbol, expression)``, each expression in the task symbols,
    the parameters and the symbols defined before it, the joint symbols q_i
    among them; substituting them in order (``derivations.ik.substitute_steps``)
    gives ``solution``.  ``step_cites``, if given, names the paper's equation of
    each step (``"Kumar Eq.~(h)"``, ``""`` for none), one per step, for the LaTeX tags.
    """

    name: str
    solution: tuple[sp.Expr, ...]
    condition: sp.Basic = sp.true
    doc: str = ""
    steps: tuple[tuple[sp.Symbol, sp.Expr], ...] = ()
    step_cites: tuple[str, ...] = ()
    # The condition in the step symbols (``condition`` is it with the steps substituted), for
    # a kernel emitted step by step (RobotModel.ik_function); None: emitted from ``solution``.
    step_condition: sp.Basic | None = None

    def __post_init__(self):
        if self.step_cites and len(self.step_cites) != len(self.steps):
            raise ValueError(f"{self.name}: {len(self.step_cites)} step cites for {len(self.steps)} steps")


def with_program(functions: list[SymbolicFunction], steps) -> list[SymbolicFunction]:
    """``functions`` with the steps of the program ``steps`` that each one reads put in front of
    its own definitions (in program order), so that each kernel carries just what it computes."""
    if not steps:
        return list(functions)
    out = []
    for f in functions:
        reads = [e for o in f.outputs for e in o.values] + [r.condition for r in f.requires]
        reads += [e for _, e in f.definitions]
        out.append(replace(f, definitions=needed(steps, reads) + tuple(f.definitions)))
    return out


POSE_NAMES = ("x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33")
# The tool's z axis in the base frame (the third column of its rotation): the task item "approach".
APPROACH_NAMES = ("ax", "ay", "az")
# The items a task may list, and the coordinates among them that are angles (wrapped in residuals).
TASK_ITEMS = ("x", "y", "z", "phi", "pitch", "roll", "approach", "pose")
TASK_ITEMS_TEXT = "x, y, z, phi, pitch, roll, approach or pose"
ANGLE_TASKS = ("phi", "pitch", "roll")


class TaskError(ValueError):
    """A task coordinate this chain does not have (``pitch`` without parallel pitch joints, ...)."""


def pitch_joints(chain: Chain) -> list[tuple[int, sp.Expr]]:
    """The joints whose turns make the task coordinate ``pitch``: the first run of two or more
    consecutive revolute joints with parallel axes (a 4- or 5-joint arm's shoulder, elbow and wrist
    pitch), each with its sign ``h_i . h_first`` (+-1).  Empty if the chain has no such run.
    Parallel axes stay parallel at every q (the run's own joints turn them about their common
    direction; earlier joints turn them together), so the run is read at q = 0."""
    from .ik.structure import cross, dot, is_zero, tidy  # the ik package imports this module
    zero = [sp.S.Zero] * chain.n
    axes = [sp.Matrix(h).applyfunc(tidy) for h, _ in chain.joint_axes(chain.link_frames(zero))]
    kinds = [j.type for j in chain.joints]

    def parallel(i, j):
        return all(is_zero(e) for e in cross(axes[i], axes[j]))
    for first in range(chain.n - 1):
        if kinds[first] != REVOLUTE:
            continue
        run = [first]
        while run[-1] + 1 < chain.n and kinds[run[-1] + 1] == REVOLUTE and parallel(first, run[-1] + 1):
            run.append(run[-1] + 1)
        if len(run) >= 2:
            norm2 = tidy(dot(axes[first], axes[first]))
            return [(i, sp.sign(tidy(dot(axes[i], axes[first]) / norm2))) for i in run]
    return []


def joint_angle_task(item: str, chain: Chain, q) -> sp.Expr:
    """The task coordinates ``pitch`` and ``roll``, exact linear forms in the joint angles.

    ``pitch``: the tool's turn about the common direction of the first run of parallel revolute
    axes (:func:`pitch_joints`), relative to q = 0: ``sum s_i q_i`` over the run.  For an arm of a
    base turn and parallel pitch joints (``R(q) = Rot(h1, q1) Rot(h2, pitch) R(0)``, the AL5D, the
    SO-101) it is the angle the gripper is tipped by in the arm's plane.  ``roll``: the turn of
    the last joint, a revolute one about the tool's own axis (the wrist roll of a 5-joint arm)."""
    if item == "roll":
        if chain.joints[-1].type != REVOLUTE:
            raise TaskError("task coordinate 'roll' needs the last joint revolute (a wrist roll)")
        return q[-1]
    run = pitch_joints(chain)
    if not run:
        raise TaskError("task coordinate 'pitch' needs two or more consecutive revolute joints with parallel "
                         "axes (an arm's shoulder, elbow and wrist pitch)")
    return sum((s * q[i] for i, s in run), sp.S.Zero)


def task_coordinates(spec: Sequence[str], chain: Chain, q, fk: sp.Matrix, link_frames) -> tuple[list[str], sp.Matrix]:
    """Task coordinates named in ``spec`` as exact expressions in ``q``.

    ``x, y, z``: the tool point; ``pose``: the tool point followed by the nine
    entries of the tool rotation, row by row; ``phi``: the planar orientation of
    the tool (rotation about the base z axis), for chains whose revolute axes
    are all parallel to base z.  ``phi`` is derived as the exact linear form
    ``phi0 + sum(s_i q_i)`` with ``s_i = z_i . e_z = +-1``, and checked against
    the rotation block: ``R(q) = Rz(phi - phi0) R(0)``.
    """
    names: list[str] = []
    values: list[sp.Expr] = []
    for item in spec:
        if item in ("x", "y", "z"):
            names.append(item)
            values.append(fk["xyz".index(item), 3])
        elif item == "pose":
            names.extend(POSE_NAMES)
            values.extend([fk[0, 3], fk[1, 3], fk[2, 3]] + [fk[r, c] for r in range(3) for c in range(3)])
        elif item == "phi":
            names.append(item)
            values.append(_planar_orientation(chain, q, fk, link_frames))
        elif item == "approach":
            names.extend(APPROACH_NAMES)
            values.extend([fk[0, 2], fk[1, 2], fk[2, 2]])
        elif item in ("pitch", "roll"):
            names.append(item)
            values.append(joint_angle_task(item, chain, q))
        else:
            raise ValueError(f"unknown task coordinate {item!r} (expected {TASK_ITEMS_TEXT})")
    if len(set(names)) != len(names):
        raise ValueError(f"task coordinates repeat a name: {names}")
    return names, sp.Matrix(values)


def _planar_orientation(chain: Chain, q, fk: sp.Matrix, link_frames) -> sp.Expr:
    phi = sp.S.Zero
    for joint, qi, (axis, _) in zip(chain.joints, q, chain.joint_axes(link_frames)):
        if joint.type != REVOLUTE:
            continue
        if axis[0] != 0 or axis[1] != 0 or axis[2] not in (1, -1):
            raise TaskError("task coordinate 'phi' needs every revolute axis parallel to the base z axis")
        phi += axis[2] * qi
    rot0 = fk[:3, :3].subs({qi: 0 for qi in q})
    phi0 = sp.atan2(sp.nsimplify(rot0[1, 0]), sp.nsimplify(rot0[0, 0]))
    if rot0[0, 0] == 0 and rot0[1, 0] == 0:
        phi0 = sp.atan2(-rot0[0, 1], rot0[1, 1])
    angle = phi
    rz = sp.Matrix([[sp.cos(angle), -sp.sin(angle), 0], [sp.sin(angle), sp.cos(angle), 0], [0, 0, 1]])
    residual = (rz * rot0 - fk[:3, :3]).applyfunc(simplify_entry)
    if residual != sp.zeros(3, 3):
        raise TaskError("task coordinate 'phi': the tool rotation is not a rotation about the base z axis")
    return phi + phi0


@dataclass
class RobotModel:
    """Symbolic kinematics of one robot (see DESIGN.md, "Symbolic contract").

    Attributes: ``q`` joint symbols q1..qn; ``params`` {Symbol: default float, SI};
    ``frames`` [T_0 (the base), ..., T_n (the flange)], then the tool frame
    ``T_n * tool`` when the chain has a tool transform; ``fk`` = ``frames[-1]``; ``jacobian`` 6 x n geometric ``[v; w]``;
    ``task`` m x 1; ``task_jacobian`` m x n; ``ik`` list of :class:`IKBranch`;
    ``constants`` {NAME: expression in the parameters}, emitted as module
    constants evaluated at the default parameters.
    """

    name: str
    title: str
    source: str
    joint_types: tuple[str, ...]
    q: tuple[sp.Symbol, ...]
    params: dict[sp.Symbol, float]
    frames: list[sp.Matrix]
    jacobian: sp.Matrix
    task_names: tuple[str, ...]
    task: sp.Matrix
    task_jacobian: sp.Matrix
    limits: tuple[tuple[float, float] | None, ...]
    chain: Chain | None = None
    ik: list[IKBranch] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)
    constants: dict[str, sp.Expr] = field(default_factory=dict)
    # "wrist partition": the rate maps by Paul's partition (derivations/paul.py), which a
    # robot's module asks for (the PUMA 560); None: chosen by size (velocity.closed_form_shape).
    rate_form: str | None = None
    # The automatic inverse kinematics (derivations.ik.decompose.attach): the family and the
    # plan, one line per step, for `kinegen show --what ik`; or why the arm has none.
    ik_plan: tuple[str, ...] = ()
    ik_unsupported: str = ""
    # True where the arm cannot reach its task in full (more task freedoms than joints, or a joint that
    # changes none of it): a task chosen on purpose (``derivations.load(task=...)``) is then refused.
    ik_task_unreachable: bool = False
    # The joint (0-based) a seven-joint arm's ik takes as its argument ``free``; None: no free joint.
    ik_free: int | None = None
    # What ik's joint values range over, as its docstring says it (every robot wraps its revolute
    # joints but the AVR 3000, whose frog leg holds q2 / 2).
    ik_ranges: str = "Revolute joints are wrapped to (-pi, pi]."
    # A general arm's kinematics as a straight-line program (derivations.program): ordered steps
    # (symbol, expression) that ``frames``, ``jacobian``, ``task`` and ``task_jacobian`` are written
    # in.  Empty where those are explicit (expanded and simplified: every paper's robot).
    program: tuple[tuple[sp.Symbol, sp.Expr], ...] = ()
    # The joints' names (a URDF's joint names, or a description's `name` fields) and the names of
    # `frames` (a URDF's link names); empty where the description gives none (see joint_labels).
    joint_names: tuple[str, ...] = ()
    frame_names: tuple[str, ...] = ()
    # Each moving link's inertial parameters (derivations.inertia.Inertial, in frame k) and gravity
    # in the base frame: the arm's equations of motion (derivations.dynamics); empty: none.
    inertials: tuple = ()
    gravity: tuple = ()
    # Each joint's drive (derivations.inertia.Actuator: armature and friction) or None; empty: none.
    actuators: tuple = ()

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def fk(self) -> sp.Matrix:
        return self.frames[-1]

    @property
    def task_symbols(self) -> tuple[sp.Symbol, ...]:
        """Symbols standing for the task coordinates (inputs of the inverse problem)."""
        return tuple(sp.Symbol(name, real=True) for name in self.task_names)

    @property
    def jacobian_tool(self) -> sp.Matrix:
        """The geometric Jacobian in the tool frame: both halves turned by R^T, the tool's rotation."""
        R = self.fk[:3, :3]
        return sp.Matrix.vstack(R.T * self.jacobian[:3, :], R.T * self.jacobian[3:, :])

    @property
    def joint_labels(self) -> tuple[str, ...]:
        """The name of each joint: its own name where the description gives every joint one, else q1..qn."""
        return self.joint_names or tuple(str(s) for s in self.q)

    @property
    def frame_labels(self) -> tuple[str, ...]:
        """The name of each of ``frames``: a URDF's link names, else T_0 .. T_n (then "tool")."""
        if self.frame_names:
            return self.frame_names
        return tuple(f"T_{i}" for i in range(self.n + 1)) + (("tool",) if len(self.frames) > self.n + 1 else ())

    def explicit(self, expr):
        """``expr`` (an expression or a matrix of this model's) in the joint variables and the
        parameters alone: the program's steps substituted (itself when there is no program)."""
        return inline(self.program, expr)

    def joint_unit(self, i: int) -> str:
        return "rad" if self.joint_types[i] == REVOLUTE else "m"

    def functions(self) -> list[SymbolicFunction]:
        """The kernels of the generated-code contract, in a fixed order."""
        n, m = self.n, len(self.task_names)
        q = Argument("q", self.q, f"joint coordinates, shape (..., {n}) ({self._units()})")
        count = len(self.frames)
        frames = sp.Array([list(f) for f in self.frames]).reshape(count, 4, 4)
        kinematics = with_program([
            SymbolicFunction("fk", (q,), (Output.from_matrix("T", self.fk),),
                             "Tool pose: homogeneous transform base -> tool, shape (..., 4, 4); metres."),
            SymbolicFunction("frames", (q,), (Output("frames", tuple(sp.flatten(frames.tolist())), (count, 4, 4)),),
                             f"Frames T_0 (base) .. T_{n} (" + ("flange), then the tool frame" if count > n + 1 else "tool)")
                             + f", shape (..., {count}, 4, 4)."),
            SymbolicFunction("jacobian", (q,), (Output.from_matrix("J", self.jacobian),),
                             f"Geometric Jacobian [v; w] of the tool point in the base frame, shape (..., 6, {n})."),
            SymbolicFunction("jacobian_tool", (q,), (Output.from_matrix("J_tool", self.jacobian_tool),),
                             f"Geometric Jacobian [v; w] of the tool point in the tool frame (the Robotics Toolbox's "
                             f"jacobe, Pinocchio's LOCAL): [R^T v; R^T w], shape (..., 6, {n})."),
            SymbolicFunction("task", (q,), (Output("x", tuple(self.task), (m,)),),
                             f"Task coordinates {', '.join(self.task_names)}, shape (..., {m})."),
            SymbolicFunction("task_jacobian", (q,), (Output.from_matrix("Jx", self.task_jacobian),),
                             f"d task / d q, shape (..., {m}, {n})."),
        ], self.program)
        # A general 6R (derivations.ik.general_6r): the closed-form equations its ik solves numerically.
        from .ik.general_6r import equations_function
        general = equations_function(self)
        return kinematics + ([self.ik_function()] if self.ik else []) + ([general[0]] if general else []) + \
            self.rate_functions() + self.dynamics_functions()

    def ik_function(self) -> SymbolicFunction:
        """The ``ik`` kernel: every branch of ``self.ik`` at once.

        ``Q`` (k, n) holds each branch's joint values (revolute joints wrapped to
        (-pi, pi], see ``derivations.ik.kernel_form``); ``valid`` (k,) is each
        branch's existence condition.  The generated code also marks a branch
        invalid wherever its joint values are not finite (a NaN or inf target).
        """
        k, n = len(self.ik), self.n
        names = ", ".join(b.name for b in self.ik)
        x = Argument("x", self.task_symbols, f"task coordinates {', '.join(self.task_names)}, shape (..., "
                     f"{len(self.task_names)})")
        arguments = (x,)
        if self.ik_free is not None:
            free = self.q[self.ik_free]
            arguments += (Argument("free", (free,), f"the value of the free joint {free} "
                                   f"({self.joint_unit(self.ik_free)}), shape (..., 1), (...) or a number, "
                                   "at most 1e4 in size"),)
        revolute = [t == REVOLUTE for t in self.joint_types]
        definitions: tuple = ()
        if all(b.step_condition is not None for b in self.ik):
            definitions, values, valid = self._ik_program(revolute)
        else:
            values = tuple(kernel_form(e, r) for branch in self.ik for e, r in zip(branch.solution, revolute))
            valid = tuple(sp.sympify(b.condition) for b in self.ik)
        return SymbolicFunction(
            "ik", arguments,
            (Output("Q", values, (k, n), "float", f"joint values of each branch ({names})"),
             Output("valid", valid, (k,), "bool", "whether each branch exists")),
            f"Inverse kinematics, all {k} branches ({names}): Q (..., {k}, {n}), valid (..., {k}).",
            definitions=definitions)

    def _ik_program(self, revolute):
        """The branches' steps as one straight-line program: a step that several branches share
        (the same definition in the same earlier steps) once, each other step renamed
        ``ik_<name>_b<k>`` after the first branch k that defines it."""
        from .ik.decompose import substitute_unevaluated
        taken = {str(s) for s in self.params} | {str(s) for s in self.task_symbols}
        definitions, known = [], {}
        values, valid = [], []
        for k, branch in enumerate(self.ik):
            rename: dict = {}
            memo: dict = {}
            for symbol, expr in branch.steps:
                expr = substitute_unevaluated(expr, rename, memo)
                key = (symbol.name, expr)
                if key not in known:
                    name = f"ik_{symbol.name}_b{k}"
                    if name in taken:
                        raise ValueError(f"{self.name}: the inverse-kinematics step {name} is also a parameter's name")
                    taken.add(name)
                    known[key] = sp.Symbol(name, real=True)
                    definitions.append((known[key], expr))
                rename[symbol] = known[key]
            values.extend(kernel_form(rename.get(q, q), r) for q, r in zip(self.q, revolute))  # q: a free joint
            valid.append(substitute_unevaluated(branch.step_condition, rename, memo))
        return tuple(definitions), tuple(values), tuple(valid)

    @property
    def rates(self):
        """Rate kinematics (derivations.velocity.RateKinematics), derived on first use and cached; None
        for a model without a DH chain."""
        from .velocity import rate_kinematics
        return rate_kinematics(self)

    @property
    def singularities(self):
        """Singular configurations (derivations.velocity.Singularities): factored determinant, conditions."""
        return None if self.rates is None else self.rates.singularities

    @property
    def dynamics(self):
        """The equations of motion (derivations.dynamics.Dynamics), derived on first use and cached;
        None for an arm without inertial parameters."""
        from .dynamics import dynamics
        return dynamics(self)

    def dynamics_functions(self) -> list[SymbolicFunction]:
        """The dynamics kernels (derivations/dynamics.py); none for an arm without inertials."""
        return [] if self.dynamics is None else list(self.dynamics.functions)

    def rate_functions(self) -> list[SymbolicFunction]:
        """The velocity and acceleration kernels (derivations/velocity.py)."""
        return [] if self.rates is None else list(self.rates.functions)

    def _units(self) -> str:
        units = ["rad" if t == REVOLUTE else "m" for t in self.joint_types]
        return ", ".join(f"{s}: {u}" for s, u in zip(self.q, units))


def build_chain_model(name: str, title: str, source: str, chain: Chain, q, params: dict,
                      task_spec: Sequence[str], limits) -> RobotModel:
    """Derive every kinematic quantity of a chain (the slow symbolic step).

    An exact chain whose frames stay short gets them expanded and simplified (every paper's
    robot, the UR and KUKA arms); any other (a number as a file wrote it, seven joints, frames
    that do not cancel) gets its kinematics as a straight-line program
    (:mod:`derivations.chain_program`), whose size grows with the chain, not with its expansion.
    """
    link_frames = explicit_pays(chain, q)
    if link_frames is None:
        return _program_model(name, title, source, chain, q, params, task_spec, limits)
    tool = chain.tool
    frames = list(link_frames)
    if tool != sp.eye(4):  # the flange frame stays; the tool frame follows it
        frames.append((frames[-1] * tool).applyfunc(simplify_product))
    fk = frames[-1]
    jacobian = chain.geometric_jacobian(link_frames, fk[:3, 3], q)
    task_names, task = task_coordinates(task_spec, chain, q, fk, link_frames)
    task_jacobian = sp.Matrix(len(task), len(q),
                              lambda i, j: simplify_derivative(derivative(task[i], q[j])))
    return RobotModel(
        name=name, title=title, source=source,
        joint_types=tuple(j.type for j in chain.joints), q=tuple(q), params=dict(params),
        frames=frames, jacobian=jacobian, task_names=tuple(task_names), task=task,
        task_jacobian=task_jacobian, limits=tuple(limits), chain=chain,
    )


def _program_model(name, title, source, chain: Chain, q, params, task_spec, limits) -> RobotModel:
    derived = program_kinematics(chain, q, {str(s) for s in params})
    program, frames, jacobian = derived["program"], derived["frames"], derived["jacobian"]
    fk = frames[-1]
    task_names, values = [], []
    for item in task_spec:
        if item == "phi":  # a planar arm's angle, read off its explicit frames (a few joints)
            link_frames = chain.link_frames(q)
            explicit_fk = (link_frames[-1] * chain.tool).applyfunc(simplify_product)
            task_names.append(item)
            values.append(_planar_orientation(chain, q, explicit_fk, link_frames))
        else:
            names, entries = task_coordinates([item], chain, q, fk, None)
            task_names.extend(names)
            values.extend(entries)
    if len(set(task_names)) != len(task_names):
        raise ValueError(f"task coordinates repeat a name: {task_names}")
    task = sp.Matrix(values)
    joint_types = tuple(j.type for j in chain.joints)
    task_jacobian = program_task_jacobian(program, task_names, task, jacobian, fk, derived["axes"], joint_types,
                                          q, derived["coupled"])
    return RobotModel(
        name=name, title=title, source=source, joint_types=joint_types, q=tuple(q), params=dict(params),
        frames=frames, jacobian=jacobian, task_names=tuple(task_names), task=task,
        task_jacobian=task_jacobian, limits=tuple(limits), chain=chain, program=tuple(program.steps),
    )


__all__ += ["build_chain_model", "REVOLUTE", "PRISMATIC"]

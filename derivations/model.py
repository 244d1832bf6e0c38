"""The robot model: what a derivation produces and what code generation reads.

A :class:`RobotModel` holds the symbolic kinematics of one robot (frames, tool
pose, geometric Jacobian, task coordinates and their Jacobian, inverse-kinematics
branches) and describes each kernel to generate as a :class:`SymbolicFunction`:
a name, its array arguments (each a vector of symbols) and its outputs (arrays
of SymPy expressions).  Code generation needs nothing else.

The model is data: this module imports the chain's joint types and the program's
substitution, and nothing that derives.  What is derived from a model is elsewhere:
its kinematics in :mod:`derivations.kinematics`, its inverse kinematics in
:mod:`derivations.ik`, its rates in :mod:`derivations.rates.velocity`, its equations of motion in
:mod:`derivations.mechanics.dynamics`, and its list of kernels in :mod:`derivations.assembly`.
``RobotModel.functions()``, ``.rates``, ``.dynamics`` and the like keep the names of the
public contract and hand over to that module, which installs itself here when it is
imported (``install_assembly``; ``import derivations`` does it), so that the imports
run one way: the assembly imports the model, never the reverse.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace

import sympy as sp

from .chain import PRISMATIC, REVOLUTE, Chain
from .program import inline, needed

__all__ = ["Argument", "Output", "Requirement", "NumericSolve", "SymbolicFunction", "IKBranch", "SubstitutedSteps", "RobotModel",
           "with_program", "APPROACH_NAMES", "POSE_NAMES", "TASK_ITEMS", "TASK_ITEMS_TEXT", "ANGLE_TASKS",
           "TaskError", "install_assembly", "REVOLUTE", "PRISMATIC"]


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
    at an exact singularity, as the closed forms' ``derivations.rates.damping``), else 0.
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
    # How the code generator finds common subexpressions: "full" (SymPy's cse, which also finds
    # shared parts of sums and products), or "tree" (repeated subtrees only) for a kernel that is a
    # straight-line program through and through, as the Newton-Euler equations are: there the search
    # for shared sums took three quarters of the time for 0-9 % fewer operations (a KR 210's
    # dynamics kernels: 2.2 s against 0.6 s, 8,133 operations against 8,484).
    cse: str = "full"


class _SubstitutedOnRead:
    """The ``solution`` and ``condition`` fields of :class:`IKBranch`: a value given as a
    :class:`SubstitutedSteps` is computed when one of them is first read, and kept.

    A derived six- or seven-joint inverse (``derivations.ik.decompose``) is its steps; its kernel is
    emitted from them (``RobotModel.ik_function``), and the steps substituted into one another,
    which SymPy rebuilds with evaluation, asking the assumptions of every fresh node, are read by
    tests and tools only: on the Romeo arm they were half of its model (3 s of CPU).
    """

    def __init__(self, default):
        self.default = default

    def __set_name__(self, owner, name):
        self.name, self.key = name, "_" + name

    def __get__(self, branch, owner=None):
        if branch is None:
            return self.default  # the dataclass's default
        value = branch.__dict__[self.key]
        if isinstance(value, SubstitutedSteps):
            solution, condition = value.substitute(branch)
            branch.__dict__.update(_solution=solution, _condition=condition)
            value = branch.__dict__[self.key]
        return value

    def __set__(self, branch, value):  # the frozen dataclass's __init__ sets each field once
        branch.__dict__[self.key] = value


class SubstitutedSteps:
    """What a branch's ``solution`` and ``condition`` are, to be computed on first read: its
    steps substituted in order.  ``substitute(branch)`` returns (solution, condition)."""

    def substitute(self, branch) -> tuple[tuple[sp.Expr, ...], sp.Basic]:
        raise NotImplementedError


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
    A derivation may give ``solution`` and ``condition`` both as one :class:`SubstitutedSteps`,
    computed when first read (:meth:`renamed` keeps them unread).
    """

    name: str
    solution: tuple[sp.Expr, ...] = _SubstitutedOnRead(None)
    condition: sp.Basic = _SubstitutedOnRead(sp.true)
    doc: str = ""
    steps: tuple[tuple[sp.Symbol, sp.Expr], ...] = ()
    step_cites: tuple[str, ...] = ()
    # The condition in the step symbols (``condition`` is it with the steps substituted), for
    # a kernel emitted step by step (RobotModel.ik_function); None: emitted from ``solution``.
    step_condition: sp.Basic | None = None

    def __post_init__(self):
        if self.step_cites and len(self.step_cites) != len(self.steps):
            raise ValueError(f"{self.name}: {len(self.step_cites)} step cites for {len(self.steps)} steps")
        if self.__dict__["_solution"] is None:
            raise TypeError(f"{self.name}: an IKBranch needs its solution")

    def renamed(self, name: str, doc: str) -> "IKBranch":
        """This branch under another name and doc, a solution not yet substituted left so."""
        branch = copy.copy(self)
        branch.__dict__.update(name=name, doc=doc)
        return branch


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
    # "wrist partition": the rate maps by Paul's partition (derivations/rates/paul.py), which a
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
    # Each moving link's inertial parameters (derivations.mechanics.inertia.Inertial, in frame k) and gravity
    # in the base frame: the arm's equations of motion (derivations.mechanics.dynamics); empty: none.
    inertials: tuple = ()
    gravity: tuple = ()
    # Kernels particular to this robot, declared by its own module under derivations/robots/ (the
    # AdeptThree's tool configuration vector, the R-P arm's Kumar pose): generated after its rates.
    extra_functions: tuple[SymbolicFunction, ...] = ()
    # What each factor of the robot's singular sets means, declared by its own module: {joints the
    # factor involves (("q2",), ...): (name, description)}; empty: named by those joints.
    singular_names: dict[tuple[str, ...], tuple[str, str]] = field(default_factory=dict)
    # Each joint's drive (derivations.mechanics.inertia.Actuator: armature and friction) or None; empty: none.
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
        """The kernels of the generated-code contract, in a fixed order (``assembly.robot_kernels``)."""
        return _assembly().robot_kernels(self)

    def position_functions(self) -> list[SymbolicFunction]:
        """The first of ``functions()``: those that need neither ``rates`` nor ``dynamics``
        (``assembly.position_kernels``)."""
        return _assembly().position_kernels(self)

    def ik_function(self) -> SymbolicFunction:
        """The ``ik`` kernel: every branch of ``self.ik`` at once (``assembly.ik_kernel``)."""
        return _assembly().ik_kernel(self)

    @property
    def rates(self):
        """Rate kinematics (derivations.rates.velocity.RateKinematics), derived on first use and cached;
        None for a model without a DH chain."""
        return _assembly().rates(self)

    @property
    def singularities(self):
        """Singular configurations (derivations.rates.velocity.Singularities): factored determinant, conditions."""
        return None if self.rates is None else self.rates.singularities

    @property
    def dynamics(self):
        """The equations of motion (derivations.mechanics.dynamics.Dynamics), derived on first use and
        cached; None for an arm without inertial parameters."""
        return _assembly().dynamics(self)

    def dynamics_functions(self) -> list[SymbolicFunction]:
        """The dynamics kernels (derivations/mechanics/dynamics.py); none for an arm without inertials."""
        return [] if self.dynamics is None else list(self.dynamics.functions)

    def rate_functions(self) -> list[SymbolicFunction]:
        """The velocity and acceleration kernels (derivations/rates/velocity.py), then the robot's own
        ``extra_functions``."""
        return _assembly().rate_kernels(self)

    def _units(self) -> str:
        units = ["rad" if t == REVOLUTE else "m" for t in self.joint_types]
        return ", ".join(f"{s}: {u}" for s, u in zip(self.q, units))


_ASSEMBLY = None


def install_assembly(module) -> None:
    """Name the module that assembles a model's kernels (``derivations.assembly`` calls this when it is
    imported): the model hands ``functions()``, ``rates`` and ``dynamics`` over to it, without importing it."""
    global _ASSEMBLY
    _ASSEMBLY = module


def _assembly():
    if _ASSEMBLY is None:
        raise RuntimeError("no kernel assembly installed: import derivations (derivations.assembly installs it)")
    return _ASSEMBLY

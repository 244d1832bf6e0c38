"""Coordinate spaces of a robot and the maps between them, at three levels.

Some robots are better described by several coordinate spaces than by one
chain read from joint to tool: the AVR 3000 (Sotirov) has motor, joint, tool
and Cartesian spaces.  A :class:`CoordinateSpace` names the position symbols
of a space and the velocity and acceleration symbols that go with them.  A
:class:`SpaceMap` maps one space into another at one level; only the position
level is written down, the other two are derived from it by differentiation
along a path ``x(t)``:

    y   = f(x)                           position
    y'  = J(x) x'                        J = df/dx
    y'' = J(x) x'' + (d/dx (J x')) x'    the time derivative of J x'

Position maps compose (``compose(g, f)`` is ``g`` after ``f``).  The conditions
a map needs (a reachable target, a non-singular configuration) travel with it
through composition and differentiation, as :class:`~derivations.model.Requirement`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import sympy as sp

from ...model import Argument, Output, Requirement, RobotModel, SymbolicFunction

__all__ = ["LEVELS", "CoordinateSpace", "coordinate_space", "SpaceMap", "position_map", "compose",
           "differentiate", "SpacesModel"]

LEVELS = ("position", "velocity", "acceleration")
_LEVEL_SUFFIX = {"position": "", "velocity": "dot", "acceleration": "ddot"}
_UNIT_SUFFIX = {"position": "", "velocity": "/s", "acceleration": "/s^2"}


@dataclass(frozen=True)
class CoordinateSpace:
    """The coordinates of one space at position, velocity and acceleration level.

    ``units`` are the position units of each coordinate (``"count"``, ``"rad"``,
    ``"m"``); a velocity is in units/s, an acceleration in units/s^2.
    """

    name: str
    position: tuple[sp.Symbol, ...]
    velocity: tuple[sp.Symbol, ...]
    acceleration: tuple[sp.Symbol, ...]
    units: tuple[str, ...]
    doc: str = ""

    def at(self, level: str) -> tuple[sp.Symbol, ...]:
        """The symbols of this space at ``level`` (one of ``LEVELS``)."""
        return {"position": self.position, "velocity": self.velocity, "acceleration": self.acceleration}[level]

    def argument(self, level: str) -> Argument:
        """The kernel argument holding this space's coordinates at ``level``, shape (..., n)."""
        name = self.name if level == "position" else f"{self.name}_{level}"
        units = ", ".join(f"{s}: {u}{_UNIT_SUFFIX[level]}" for s, u in zip(self.at(level), self.units))
        return Argument(name, self.at(level), f"{self.name} {level}, shape (..., {len(self.position)}) ({units})")


def coordinate_space(name: str, names: tuple[str, ...], units: tuple[str, ...], doc: str = "") -> CoordinateSpace:
    """A space whose position symbols are ``names``.

    Velocity and acceleration symbols insert ``dot`` / ``ddot`` before a trailing
    index (``theta1 -> thetadot1``, ``T -> Tdot``), which SymPy's LaTeX printer
    renders as a dot accent.
    """
    def derived(level):
        out = []
        for n in names:
            stem, index = re.fullmatch(r"(.*?)(\d*)", n).groups()
            out.append(sp.Symbol(f"{stem}{_LEVEL_SUFFIX[level]}{index}", real=True))
        return tuple(out)

    if len(names) != len(units):
        raise ValueError(f"space {name}: {len(names)} coordinates but {len(units)} units")
    return CoordinateSpace(name, tuple(sp.Symbol(n, real=True) for n in names), derived("velocity"),
                           derived("acceleration"), tuple(units), doc)


@dataclass(frozen=True)
class SpaceMap:
    """``source -> target`` at one level.

    ``values`` is the target's coordinates at ``level`` (a column) in the
    source's position and, from the velocity level on, its velocity and
    acceleration.  ``requires`` is what the map needs at this level;
    ``derivative_requires`` (position level only) what its velocity and
    acceleration maps need in addition (non-singularity).  ``cite`` names the
    paper's equations the map reproduces.
    """

    source: CoordinateSpace
    target: CoordinateSpace
    level: str
    values: sp.Matrix
    requires: tuple[Requirement, ...] = ()
    derivative_requires: tuple[Requirement, ...] = ()
    cite: str = ""
    doc: str = field(default="", compare=False)
    branch: str = ""  # names a second solution of an inverse map: <from>_to_<to>_<branch>

    @property
    def name(self) -> str:
        """``<from>_to_<to>`` (``_<branch>`` for a named branch), with ``_velocity`` / ``_acceleration``."""
        base = f"{self.source.name}_to_{self.target.name}" + (f"_{self.branch}" if self.branch else "")
        return base if self.level == "position" else f"{base}_{self.level}"

    @property
    def arguments(self) -> tuple[Argument, ...]:
        """Source position, then velocity and acceleration as the level needs them."""
        return tuple(self.source.argument(level) for level in LEVELS[:LEVELS.index(self.level) + 1])

    @property
    def jacobian(self) -> sp.Matrix:
        """d target / d source of a position map (the Matlab script's JMJ, JJT, JMT, JMC, JX)."""
        if self.level != "position":
            raise ValueError(f"{self.name}: the Jacobian is that of the position map")
        return self.values.jacobian(sp.Matrix(self.source.position))

    def function(self) -> SymbolicFunction:
        out = self.target.argument(self.level)
        doc = f"{self.source.name.capitalize()} -> {self.target.name} {self.level}"
        doc += f" ({self.cite})." if self.cite else "."
        if self.doc:
            doc += f" {self.doc}"
        return SymbolicFunction(self.name, self.arguments,
                                (Output(out.name, tuple(self.values), (len(self.values),), doc=out.doc),),
                                doc, self.requires)


def position_map(source: CoordinateSpace, target: CoordinateSpace, values, requires=(), derivative_requires=(),
                 cite: str = "", doc: str = "", branch: str = "") -> SpaceMap:
    values = sp.Matrix(values)
    if values.shape != (len(target.position), 1):
        raise ValueError(f"{source.name} -> {target.name}: expected {len(target.position)} values, got {values.shape}")
    stray = values.free_symbols & (set(source.velocity) | set(source.acceleration) | set(target.position))
    if stray:
        raise ValueError(f"{source.name} -> {target.name}: position map uses {sorted(map(str, stray))}")
    return SpaceMap(source, target, "position", values, tuple(requires), tuple(derivative_requires), cite, doc, branch)


def _substitute(requirements, mapping):
    return tuple(Requirement(r.condition.xreplace(mapping), r.kind, r.message) for r in requirements)


def compose(outer: SpaceMap, inner: SpaceMap, cite: str = "", doc: str = "") -> SpaceMap:
    """``outer`` after ``inner`` (both position maps): source of ``inner`` -> target of ``outer``.

    The composition keeps the branch of either (at most one of them may have one).
    """
    if inner.level != "position" or outer.level != "position":
        raise ValueError("compose() takes position maps; differentiate the composition instead")
    if inner.target != outer.source:
        raise ValueError(f"cannot compose {outer.name} after {inner.name}")
    if inner.branch and outer.branch:
        raise ValueError(f"cannot compose two branches: {outer.name} after {inner.name}")
    mapping = dict(zip(outer.source.position, inner.values))
    return SpaceMap(inner.source, outer.target, "position", outer.values.xreplace(mapping),
                    inner.requires + _substitute(outer.requires, mapping),
                    inner.derivative_requires + _substitute(outer.derivative_requires, mapping), cite, doc,
                    inner.branch or outer.branch)


def differentiate(position: SpaceMap, level: str, cite: str = "") -> SpaceMap:
    """The velocity or acceleration map of a position map, by the chain rule.

    Every ``derivative_requires`` condition must be written on a subexpression
    that the derived map really contains (the radicand of a denominator, say), so
    that the generated code tests the value it divides by; this is checked.
    """
    if position.level != "position" or level not in LEVELS[1:]:
        raise ValueError("differentiate() takes a position map and 'velocity' or 'acceleration'")
    x = sp.Matrix(position.source.position)
    xd = sp.Matrix(position.source.velocity)
    velocity = position.jacobian * xd
    values = velocity
    if level == "acceleration":
        values = position.jacobian * sp.Matrix(position.source.acceleration) + velocity.jacobian(x) * xd
    for requirement in position.derivative_requires:
        condition = requirement.condition
        if isinstance(condition, sp.core.relational.Relational) and not values.has(condition.lhs):
            raise ValueError(f"{position.name}_{level}: the condition {requirement.condition} "
                             "does not test a subexpression of the map")
    return SpaceMap(position.source, position.target, level, values,
                    position.requires + position.derivative_requires, (), cite, position.doc, position.branch)


@dataclass
class SpacesModel(RobotModel):
    """A :class:`~derivations.model.RobotModel` that also holds coordinate spaces and maps.

    The contract attributes (``q``, ``frames``, ``fk``, ``jacobian``, ``task``,
    ``task_jacobian``, ``ik``) keep their meaning; on top, ``spaces`` holds the
    coordinate spaces by name and ``maps`` every :class:`SpaceMap` by kernel
    name (``motor_to_joint``, ``tool_to_joint_velocity``, ...).
    ``sample_ranges`` gives, for a symbol, the interval ``(low, high)`` (SymPy
    expressions in the parameters) the verifier draws its values from, so that
    the sample points of a map lie where the map is defined.  ``space_limits``
    gives, for a space name, the range ``(low, high)`` of each coordinate (SI
    floats, the robot's working ranges), emitted as the module constant
    ``SPACE_LIMITS``.
    """

    spaces: dict[str, CoordinateSpace] = field(default_factory=dict)
    maps: dict[str, SpaceMap] = field(default_factory=dict)
    sample_ranges: dict[sp.Symbol, tuple[sp.Expr, sp.Expr]] = field(default_factory=dict)
    space_limits: dict[str, tuple[tuple[float, float], ...]] = field(default_factory=dict)

    def functions(self) -> list[SymbolicFunction]:
        functions = super().functions()
        if self.ik and "ik" not in {f.name for f in functions}:
            functions.append(self.ik_function())
        return functions + [m.function() for m in self.maps.values()]

    def ik_function(self) -> SymbolicFunction:
        """``ik(x) -> (Q, valid)`` of the DESIGN contract, from ``self.ik``.

        ``acos``/``asin`` arguments are clamped to [-1, 1] so that an unreachable
        target gives finite joint values flagged ``valid = False`` (never a NaN
        or a floating-point warning); inside the workspace the clamp is the identity.
        """
        clamp = {sp.acos: lambda w: sp.acos(sp.Max(-1, sp.Min(1, w))),
                 sp.asin: lambda w: sp.asin(sp.Max(-1, sp.Min(1, w)))}
        values, valid = [], []
        for branch in self.ik:
            for expr in branch.solution:
                for function, clamped in clamp.items():
                    expr = expr.replace(function, clamped)
                values.append(expr)
            valid.append(branch.condition)
        k, n = len(self.ik), self.n
        x = Argument("x", self.task_symbols, f"task coordinates {', '.join(self.task_names)}, shape (..., "
                                             f"{len(self.task_names)})")
        return SymbolicFunction(
            "ik", (x,),
            (Output("Q", tuple(values), (k, n)), Output("valid", tuple(valid), (k,), dtype="bool")),
            f"Inverse kinematics: joint coordinates of each branch ({', '.join(b.name for b in self.ik)}), "
            f"shape (..., {k}, {n}), and whether each exists, shape (..., {k}).")

"""The joint axes of a chain in its zero configuration, and what they share.

Every serial chain, DH or URDF, is a product of exponentials (Brockett):

    T(q) = E_1(q_1) E_2(q_2) ... E_n(q_n) M,    M = T(0),

where ``E_i`` turns by ``q_i`` about the line through ``p_i`` along the unit vector
``h_i`` (revolute) or slides by ``q_i`` along ``h_i`` (prismatic), both read off the
chain at q = 0 in the world frame.  The inverse-kinematics families of
:mod:`derivations.ik.decompose` are recognised from these lines alone: which are
parallel, which meet and where, which joints slide.  Every test is on the parameters
as symbols, so a structure found here holds for every value of the parameters (a KR5's
two lateral offsets, equal by default but separate parameters, are treated as an
offset; an offset that is zero in the table is zero).  :func:`is_zero` decides
"identically zero" without ``simplify``: two seeded random points at 30 digits reject
almost every candidate; what survives is confirmed exactly (expansion, then
sin^2 + cos^2 = 1 for each angle) or, for identities among constants such as
sin(1/10) = 2 sin(1/20) cos(1/20), by three more points at 50 digits (the expressions
are analytic in their symbols, so a non-zero one vanishes only on a set of measure zero).

:func:`check_product_of_exponentials` evaluates both sides at random joint values and
the default parameters, so a sign slip between the chain and this form cannot pass
unseen.
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import sympy as sp

from ..chain import PRISMATIC, REVOLUTE, pythagorean
from ..program import substitute

__all__ = ["Axis", "Structure", "structure_of", "is_zero", "cross", "dot", "rotate", "check_product_of_exponentials"]


def is_zero(expr) -> bool:
    """Exactly zero for every value of the parameters (and of a held joint's angle)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    if expr.is_number:
        return abs(complex(expr.evalf(30))) < 1e-25 and sp.nsimplify(expr) == 0
    if not _vanishes_at_random_points(expr):
        return False  # the common answer, found without simplify (seconds on a held joint's trig terms)
    expanded = sp.expand(expr)
    if expanded == 0 or pythagorean(expanded) == 0:
        return True
    # Zero at two random points, and not by expansion or sin^2 + cos^2 = 1: an identity between
    # constants such as sin(1/10) = 2 sin(1/20) cos(1/20) (an offset of 0.05 rad), where
    # simplify spends minutes.  The expression is analytic in its symbols, so a non-zero one
    # vanishes only on a set of measure zero: three more random points at 50 digits decide.
    return _vanishes_at_random_points(expr, trials=3, digits=50, seed=7, tolerance=1e-40)


def _vanishes_at_random_points(expr, trials: int = 2, digits: int = 30, seed: int = 20261125,
                               tolerance: float = 1e-20) -> bool:
    """``expr`` is within rounding of 0 at ``trials`` seeded random points (each symbol in
    [0.3, 1.7], at ``digits`` digits): a necessary condition for being identically zero."""
    symbols = sorted(expr.free_symbols, key=str)
    rng = random.Random(seed)
    for _ in range(trials):
        point = {s: sp.Float(rng.uniform(0.3, 1.7), digits) for s in symbols}
        value = expr.xreplace(point).evalf(digits)
        if not value.is_number or abs(complex(value)) > tolerance:
            return value.is_number is False  # a value that is no number (a function left over): decide symbolically
    return True


def tidy(expr):
    """A constant of the geometry (parameters only), in a short exact form."""
    expr = sp.sympify(expr)
    if expr.is_Atom:
        return expr
    if expr.has(sp.sin, sp.cos):
        # a held joint's angle, or an offset such as 0.05 rad: simplify's trigsimp takes seconds
        # to minutes here; sin^2 + cos^2 = 1 is the reduction that matters, where it is cheap
        if sp.count_ops(expr) > 400:
            return expr
        return pythagorean(sp.expand(expr))
    return sp.simplify(sp.expand(expr))


def dot(a, b):
    return sum((x * y for x, y in zip(a, b)), sp.S.Zero)


def cross(a, b) -> sp.Matrix:
    return sp.Matrix([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def rotate(h, c, s, v) -> sp.Matrix:
    """``v`` turned about the unit vector ``h`` by the angle whose cosine is ``c`` and sine ``s`` (Rodrigues)."""
    v = sp.Matrix(v)
    along = dot(h, v)
    h = sp.Matrix(h)
    # (1 - c) spelled out, so that a component along h cancels: v_z c + v_z - v_z c = v_z about z
    return v * c + cross(h, v) * s + h * along - h * (along * c)


@dataclass(frozen=True)
class Axis:
    """Joint ``index`` (0-based): its line ``p + t h`` at q = 0, world frame; ``kind`` R or P."""

    index: int
    kind: str
    h: sp.Matrix
    p: sp.Matrix

    @property
    def label(self) -> str:
        return f"{self.index + 1}"


@dataclass
class Structure:
    """The axes of an arm at q = 0 and their exact relations (see the module docstring)."""

    axes: tuple[Axis, ...]
    home: sp.Matrix          # M = T(0), the tool pose at q = 0
    task: tuple[str, ...]
    # the values of held joints (a seven-joint arm's free joint) the axes may carry: symbols that
    # take every value at run time, so a relation must hold for each of them
    held: tuple = ()
    _meets: dict = field(default_factory=dict, repr=False)
    _parallel: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return len(self.axes)

    @property
    def kinds(self) -> str:
        return "".join(a.kind for a in self.axes)

    def parallel(self, i: int, j: int) -> bool:
        """Axes i and j (0-based) have the same or opposite direction."""
        key = (min(i, j), max(i, j))
        if key not in self._parallel:
            self._parallel[key] = all(is_zero(e) for e in cross(self.axes[i].h, self.axes[j].h))
        return self._parallel[key]

    def parallel_to(self, i: int, direction) -> bool:
        """Axis i is along ``direction`` (either sense)."""
        return all(is_zero(e) for e in cross(self.axes[i].h, direction))

    def meet(self, i: int, j: int):
        """The point where revolute axes i and j meet (exact), or None if they do not (or are parallel)."""
        key = (min(i, j), max(i, j))
        if key not in self._meets:
            self._meets[key] = self._meeting_point(*key)
        return self._meets[key]

    def _meeting_point(self, i: int, j: int):
        a, b = self.axes[i], self.axes[j]
        if a.kind != REVOLUTE or b.kind != REVOLUTE or self.parallel(i, j):
            return None
        normal = cross(a.h, b.h)
        if not is_zero(dot(b.p - a.p, normal)):
            return None
        t = dot(cross(b.p - a.p, b.h), normal) / dot(normal, normal)
        point = (a.p + a.h * t).applyfunc(tidy)
        if self.held and any(sp.denom(sp.together(e)).has(*self.held) for e in point):
            # the lines meet for most values of a held joint but are parallel at some (the Panda held at
            # its joint 6: axes 5 and 7 meet at a6 / sin q6): no fixed structure to solve on
            return None
        return point

    def on_axis(self, point, i: int) -> bool:
        a = self.axes[i]
        return all(is_zero(e) for e in cross(point - a.p, a.h))

    def meet_in_one_point(self, i: int, j: int, k: int):
        """The common point of revolute axes i, j, k, or None."""
        point = self.meet(i, j)
        if point is None or self.axes[k].kind != REVOLUTE or not self.on_axis(point, k):
            return None
        return point

    def describe(self) -> list[str]:
        """One line per relation found, for ``kinegen show --what ik``."""
        lines = [f"joints: {self.kinds} (R revolute, P prismatic); task: {', '.join(self.task)}"]
        pairs = []
        for i in range(self.n - 1):
            if self.parallel(i, i + 1):
                pairs.append(f"axes {i + 1} and {i + 2} parallel")
            elif self.meet(i, i + 1) is not None:
                pairs.append(f"axes {i + 1} and {i + 2} meet")
        lines.append("consecutive axes: " + ("; ".join(pairs) if pairs else "no two parallel or meeting"))
        return lines


def structure_of(model) -> Structure:
    """The axes of ``model``'s chain at q = 0 (world frame) and its tool pose there."""
    chain = model.chain
    zero = [sp.S.Zero] * model.n
    frames = chain.link_frames(zero)
    axes = []
    for i, ((h, p), joint) in enumerate(zip(chain.joint_axes(frames), chain.joints)):
        h = sp.Matrix(h).applyfunc(tidy)
        norm2 = tidy(dot(h, h))
        if norm2 != 1:
            h = (h / sp.sqrt(norm2)).applyfunc(tidy)
        axes.append(Axis(i, joint.type, h, sp.Matrix(p).applyfunc(tidy)))
    home = substitute(model.program, model.fk, dict(zip(model.q, zero))).applyfunc(tidy)
    return Structure(tuple(axes), home, tuple(model.task_names))


def _numeric_rotation(h, angle):
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = h
    return [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
            [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
            [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]]


def _matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def check_product_of_exponentials(model, structure: Structure, trials: int = 3) -> float:
    """The largest difference between ``model.fk`` and the product of exponentials at random q,
    relative to the tool's distance from the base (at least 1 m)."""
    defaults = {s: v for s, v in model.params.items()}
    rng = random.Random(20261124)
    worst = 0.0
    numeric_axes = [([float(e.xreplace(defaults)) for e in a.h], [float(e.xreplace(defaults)) for e in a.p], a.kind)
                    for a in structure.axes]
    home = [[float(structure.home[i, j].xreplace(defaults)) for j in range(4)] for i in range(4)]
    def fk(q):  # the model's own fk at q, its program's steps evaluated one by one
        point = {**defaults, **{s: sp.Float(v) for s, v in zip(model.q, q)}}
        return substitute(model.program, model.fk, point).tolist()

    for _ in range(trials):
        q = [rng.uniform(-math.pi, math.pi) for _ in model.q]
        product = [[float(i == j) for j in range(4)] for i in range(4)]
        for (h, p, kind), qi in zip(numeric_axes, q):
            if kind == PRISMATIC:
                step = [[1, 0, 0, h[0] * qi], [0, 1, 0, h[1] * qi], [0, 0, 1, h[2] * qi], [0, 0, 0, 1]]
            else:
                r = _numeric_rotation(h, qi)
                shift = [p[i] - sum(r[i][k] * p[k] for k in range(3)) for i in range(3)]
                step = [r[0] + [shift[0]], r[1] + [shift[1]], r[2] + [shift[2]], [0, 0, 0, 1]]
            product = _matmul(product, step)
        product = _matmul(product, home)
        expected = fk(q)
        # relative to the arm's reach (at least a metre): an arm 6e14 m long rounds to 0.1 m
        scale = max(1.0, max(abs(float(expected[i][3])) for i in range(3)))
        worst = max(worst, max(abs(product[i][j] - float(expected[i][j])) for i in range(3) for j in range(4)) / scale)
    return worst


__all__ += ["tidy", "REVOLUTE", "PRISMATIC"]

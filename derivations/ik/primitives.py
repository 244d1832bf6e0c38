"""Closed-form inverse-kinematics primitives, each derived once and reused by every robot.

Each primitive solves one small trigonometric or linear equation and returns
*every* root as a :class:`Root`: a name, the exact SymPy value, the SymPy
condition under which the root exists, and a line of documentation.  The
robots' inverse kinematics (``derivations/robots/<name>.py``) are compositions
of these roots.

Numerical conventions, stated once here and used by every robot:

* An ``acos`` argument ``c`` is clamped to [-1, 1] inside the solution
  (``acos(min(1, max(-1, c)))``) and the root exists only while
  ``|c| <= 1 + ACOS_TOLERANCE``: a target within rounding of the workspace edge
  still solves, a target beyond it is reported unreachable.  The clamp lives in
  the solution itself (not only in the printed code) because SymPy rewrites
  ``sin(acos(c))`` as ``sqrt(1 - c**2)``, which would otherwise go NaN at the
  edge.
* ``atan2(0, 0)`` is taken as 0 (C99 and numpy agree for +0 arguments): where an
  angle is left free by the geometry, that is the choice.
* Revolute joint values are wrapped to (-pi, pi] by :func:`wrap_angle` only when
  the kernel is built (:func:`kernel_form`); the solutions keep the plain form
  for reading and printing.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy.functions.elementary.piecewise import ExprCondPair

__all__ = ["ACOS_TOLERANCE", "Root", "clamp_unit", "within_unit", "acos_clamped", "atan2_of_sine_cosine", "law_of_cosines",
           "p_cos_q_sin_r", "prismatic_along", "sine_cosine_pair", "two_link", "WrapAngle", "wrap_angle", "kernel_form",
           "substitute_steps", "ClampUnit", "Ramp", "UNIT_SNAP", "WrittenPiecewise",
           "written_piecewise"]

# |c| <= 1 + ACOS_TOLERANCE clamps onto the unit interval; beyond is unreachable.
ACOS_TOLERANCE = sp.Rational(1, 10**12)


@dataclass(frozen=True)
class Root:
    """One solution of a primitive: ``value`` exists where ``condition`` holds."""

    name: str
    value: sp.Expr
    condition: sp.Basic = sp.true
    doc: str = ""


def clamp_unit(c: sp.Expr) -> sp.Expr:
    """``min(1, max(-1, c))``: the argument of acos or asin, clamped."""
    return sp.Min(1, sp.Max(-1, c))


def within_unit(c: sp.Expr) -> sp.Basic:
    """The existence condition of ``acos(c)``: ``|c| <= 1 + ACOS_TOLERANCE``."""
    return sp.Abs(c) <= 1 + ACOS_TOLERANCE


def acos_clamped(c: sp.Expr) -> sp.Expr:
    return sp.acos(clamp_unit(c))


def atan2_of_sine_cosine(sine: sp.Expr, cosine: sp.Expr) -> list[Root]:
    """theta from ``k sin(theta) = sine``, ``k cos(theta) = cosine`` for any k > 0.

    Kumar, Appendix 1: ``atan2(s, c)`` is the one angle in a full turn whose sine
    and cosine have the signs of ``s`` and ``c``; ``asin`` or ``atan`` alone give
    two candidates (or the wrong quadrant).  Predescu and Stroe print the same
    function as a case table of ``arctan(y/x)`` (section 3).  The angle exists
    for every (sine, cosine); at (0, 0) it is free and atan2 gives 0.
    """
    return [Root("atan2", sp.atan2(sine, cosine), sp.true,
                 "atan2 of a sine/cosine pair (Kumar Appendix 1); free at (0, 0), where it gives 0")]


def law_of_cosines(reach_squared: sp.Expr, a: sp.Expr, b: sp.Expr) -> list[Root]:
    """The relative angle theta of a two-link chain with links ``a`` and ``b``.

    ``reach_squared = a**2 + b**2 + 2 a b cos(theta)`` (Rehiara Eqs. 15-17;
    Predescu and Stroe Eq. 3.3): theta = 0 is the stretched chain.  Two roots,
    ``positive`` (theta in [0, pi]) and ``negative`` (theta in [-pi, 0]); both
    exist while ``(a - b)**2 <= reach_squared <= (a + b)**2`` (within the acos
    tolerance).
    """
    c = (reach_squared - a**2 - b**2) / (2 * a * b)
    exists = within_unit(c)
    return [
        Root("positive", acos_clamped(c), exists, "theta = +acos((r^2 - a^2 - b^2) / (2 a b))"),
        Root("negative", -acos_clamped(c), exists, "theta = -acos((r^2 - a^2 - b^2) / (2 a b))"),
    ]


def p_cos_q_sin_r(P: sp.Expr, Q: sp.Expr, R: sp.Expr) -> list[Root]:
    """Both roots of ``P cos(theta) + Q sin(theta) + R = 0`` (Kumar Appendix 2).

    With ``gamma = atan2(Q, P)`` the equation reads
    ``cos(theta - gamma) = -R / sqrt(P**2 + Q**2)``, so
    ``theta = gamma + sigma acos(-R / sqrt(P**2 + Q**2))``, ``sigma = +1, -1``
    (roots ``sigma_plus``, ``sigma_minus``).  They exist while
    ``P**2 + Q**2 >= R**2`` (within the acos tolerance) and ``P**2 + Q**2 > 0``;
    they coincide where ``P**2 + Q**2 = R**2``.
    """
    norm = sp.sqrt(P**2 + Q**2)
    c = -R / norm
    gamma = sp.atan2(Q, P)
    exists = sp.And(P**2 + Q**2 > 0, within_unit(c))
    return [
        Root("sigma_plus", gamma + acos_clamped(c), exists, "theta = atan2(Q, P) + acos(-R / sqrt(P^2 + Q^2))"),
        Root("sigma_minus", gamma - acos_clamped(c), exists, "theta = atan2(Q, P) - acos(-R / sqrt(P^2 + Q^2))"),
    ]


def prismatic_along(target, origin, direction) -> list[Root]:
    """The displacement d of a prismatic joint: ``target = origin + d * direction``.

    ``target``, ``origin`` and ``direction`` are scalars or column matrices of
    the same size; the direction need not be a unit vector.  The component of
    ``target - origin`` along ``direction`` is the one solution; the remaining
    components must be met by the other joints.
    """
    target, origin, direction = (sp.Matrix([v]) if not isinstance(v, sp.MatrixBase) else v
                                 for v in (target, origin, direction))
    d = (target - origin).dot(direction) / direction.dot(direction)
    return [Root("slide", sp.simplify(d), sp.true, "d = (target - origin) . u / |u|^2")]


def sine_cosine_pair(A: sp.Expr, B: sp.Expr, u: sp.Expr, v: sp.Expr) -> list[Root]:
    """theta from the simultaneous pair ``u = A cos - B sin``, ``v = A sin + B cos``.

    The pair says ``(u, v)`` is ``(A, B)`` turned by theta, so
    ``cos(theta) = (A u + B v) / (A**2 + B**2)`` and
    ``sin(theta) = (A v - B u) / (A**2 + B**2)``: one root,
    ``atan2(A v - B u, A u + B v)``, wherever ``A**2 + B**2 > 0`` (and the
    lengths agree, which the caller's other equations ensure).
    """
    return [Root("atan2", sp.atan2(A * v - B * u, A * u + B * v), A**2 + B**2 > 0,
                 "theta = atan2(A v - B u, A u + B v)")]


class WrapAngle(sp.Function):
    """``WrapAngle(theta)``: theta wrapped to (-pi, pi], ``theta + 2 pi floor((pi - theta) / (2 pi))``.

    A function of its own (not the floor expression) so that common-subexpression
    elimination keeps theta whole: the generated code computes theta once and
    wraps that number (``_runtime.wrap_angle`` in numpy, ``kinegen_wrap_angle``
    in C), which keeps the result inside [-pi, pi] as doubles, where a wrap spread
    over the terms of theta could land an ulp outside.
    """

    nargs = 1

    @classmethod
    def eval(cls, theta):
        if theta.is_number:  # a number or an exact constant expression such as 3*pi/2
            return cls.formula(theta)
        return None

    @staticmethod
    def formula(theta):
        return theta + 2 * sp.pi * sp.floor((sp.pi - theta) / (2 * sp.pi))

    def _eval_evalf(self, prec):
        theta = self.args[0]._eval_evalf(prec)
        if theta is None or not theta.is_Number:
            return None
        return self.formula(theta)._eval_evalf(prec)

    def _eval_is_real(self):
        return self.args[0].is_real

    def fdiff(self, argindex=1):
        # The wrap shifts theta by constant multiples of 2 pi: its slope is 1
        # wherever it is differentiable (joint rates along a path need this).
        return sp.S.One


class _WrittenPiecewise(sp.Piecewise):
    """A ``Piecewise`` built, rebuilt and unpickled as written (:func:`written_piecewise`).

    SymPy's constructor folds a condition that holds another ``Piecewise`` (``piecewise_fold``,
    then ``as_set`` through solveset): seconds per piece on a derived inverse, where a later root's
    free case (``subproblems.FREE_ANGLE``) reads an earlier root that has one of its own, and again
    on every load from the derivation cache (the Romeo arm's model: 3.7 s to 38 s of CPU).
    """

    def __reduce_ex__(self, protocol):
        return written_piecewise, tuple(tuple(piece) for piece in self.args)


# Named Piecewise for the printers: SymPy's dispatch skips the print methods of a renamed subclass
# of a Function (Printer._print), and this one prints as the Piecewise it is.
_WrittenPiecewise.__name__ = _WrittenPiecewise.__qualname__ = "Piecewise"
WrittenPiecewise = _WrittenPiecewise


def written_piecewise(*pieces) -> WrittenPiecewise:
    """``Piecewise((expr, cond), ...)`` as written: no folding, no evaluation of the conditions."""
    return sp.Basic.__new__(WrittenPiecewise, *(sp.Basic.__new__(ExprCondPair, sp.sympify(e), c) for e, c in pieces))


class _NumbersOnly(sp.Function):
    """A one-argument function that SymPy evaluates only on a number (``_value``).

    ``Min(1, Max(-1, c))`` makes SymPy compare ``c`` with the bounds when it is built
    and again on every substitution; on the long arguments of a derived six-joint
    inverse (thousands of operations) one such comparison takes minutes.  The clips
    below stand in for it, and each backend prints them (numpy, C) or leaves them out
    (the LaTeX of an acos argument).
    """

    nargs = 1

    @classmethod
    def eval(cls, x):
        if x.is_Number:
            return cls._value(x)
        return None

    @classmethod
    def _value(cls, x):
        raise NotImplementedError

    def _eval_evalf(self, prec):
        x = self.args[0]._eval_evalf(prec)
        if x is None or not x.is_Number:
            return None
        return self._value(x)

    def _eval_is_real(self):
        return self.args[0].is_real


class Ramp(_NumbersOnly):
    """``Ramp(x)`` = ``max(x, 0)``, the argument of a square root."""

    @classmethod
    def _value(cls, x):
        return x if x > 0 else sp.S.Zero

    def as_min_max(self) -> sp.Expr:
        """The same clip as SymPy's (unevaluated) ``Max``, for the printers."""
        return sp.Max(self.args[0], 0, evaluate=False)


class ClampUnit(_NumbersOnly):
    """``ClampUnit(c)``: the argument of an ``acos`` clipped to [-1, 1], and taken as exactly +-1
    within ``UNIT_SNAP`` of it.

    A double root of ``P cos + Q sin + R = 0`` (a shoulder or an elbow at its singular pose)
    has ``c = +-1`` exactly; rounded data give ``c = 1 - 1e-16`` and ``acos(c) = 1.5e-8``
    where the root is 0: half the digits gone, and an error that later steps of a
    decomposition can carry into the pose.  Snapping moves a root by at most
    ``acos(1 - UNIT_SNAP)`` = 1.4e-6 rad and leaves a residual of ``UNIT_SNAP`` times the
    equation's scale, far below the accuracy the ``ik`` kernels promise, while the double
    root itself comes out exact.
    """

    @classmethod
    def _value(cls, c):
        if c >= 1 - UNIT_SNAP:
            return sp.S.One
        if c <= -1 + UNIT_SNAP:
            return sp.S.NegativeOne
        return c


# ClampUnit's snap: |c| >= 1 - UNIT_SNAP is taken as +-1.
UNIT_SNAP = sp.Rational(1, 10**12)


def wrap_angle(theta: sp.Expr) -> sp.Expr:
    """theta wrapped to (-pi, pi] (see :class:`WrapAngle`)."""
    return WrapAngle(theta)


def kernel_form(value: sp.Expr, revolute: bool) -> sp.Expr:
    """What the generated ``ik`` kernel computes for one joint of one branch.

    Revolute joint values are wrapped to (-pi, pi]; prismatic ones are left as
    they are.
    """
    value = sp.sympify(value)
    return wrap_angle(value) if revolute else value


def two_link(x: sp.Expr, y: sp.Expr, a: sp.Expr, b: sp.Expr, method: str = "algebraic"):
    """Both solutions of the planar two-link chain ``(x, y) = a e(t1) + b e(t1 + t2)``.

    Returns ``[(name, t1, t2, condition), ...]`` for ``name`` in ``positive``
    (t2 in [0, pi]) and ``negative`` (t2 in [-pi, 0]).  t2 comes from the law of
    cosines (Rehiara Eqs. 15-18, 26-27).  t1 by either of Rehiara's methods:

    * ``geometric`` (Eqs. 19-21): ``t1 = alpha - beta`` with ``alpha`` the
      direction of the target and ``beta = atan2(b sin t2, a + b cos t2)`` the
      angle between the first link and the target;
    * ``algebraic`` (Eqs. 28-34): expanding ``cos(t1 + t2)`` gives the pair
      ``x = k1 c1 - k2 s1``, ``y = k1 s1 + k2 c1`` with ``k1 = a + b c2`` and
      ``k2 = b s2``, solved by :func:`sine_cosine_pair`.

    Both are written with atan2; Rehiara prints them with arctan(y/x) and
    arcsin, which lose the quadrant (see the tests and the README errata).
    """
    if method not in ("geometric", "algebraic"):
        raise ValueError(f"two_link: method must be 'geometric' or 'algebraic', got {method!r}")
    solutions = []
    for elbow in law_of_cosines(x**2 + y**2, a, b):
        t2 = elbow.value
        if method == "geometric":
            alpha = atan2_of_sine_cosine(y, x)[0].value
            beta = atan2_of_sine_cosine(b * sp.sin(t2), a + b * sp.cos(t2))[0].value
            t1 = alpha - beta
        else:
            t1 = sine_cosine_pair(a + b * sp.cos(t2), b * sp.sin(t2), x, y)[0].value
        solutions.append((elbow.name, t1, t2, elbow.condition))
    return solutions


def substitute_steps(expr: sp.Expr, steps) -> sp.Expr:
    """``expr`` with the step symbols replaced by their definitions, latest first.

    ``steps`` is an ordered sequence of ``(symbol, expression)`` in which each
    expression uses only symbols defined before it, so one pass from the last
    step back to the first leaves none of the step symbols.
    """
    expr = sp.sympify(expr)
    for symbol, definition in reversed(tuple(steps)):
        expr = expr.xreplace({symbol: definition})
    return expr

"""Solving ``J x = b`` in closed form, and what to do where ``J`` is singular.

Away from singularities the inverse maps use the exact closed-form inverse
``J^-1 = adj(J) / det J`` (the slides' IVM of the 2R arm, Kumar Eq. 12).  Near a
singularity they switch to damped least squares with a variable damping factor
(Nakamura and Hanafusa 1986; Chiaverini 1997), which never divides by zero:

    q_dot = J^T (J J^T + lambda^2 I)^-1 b              (J square or wide)
    q_dot = (J^T J + lambda^2 I)^-1 J^T b              (J tall)
    lambda^2 = lambda_max^2 (1 - (mu / mu_0)^2)   where mu < mu_0, else 0

Units.  A Jacobian mixes metres and radians (the 3R arm's rows x, y are metres,
phi is radians; a prismatic column is metres per metre), so "small" needs a
scale.  Every length is measured in units of the robot's reference length ``L``
(:func:`reference_length`: the sum of its constant DH lengths and tool offset,
an upper bound on its reach; 1 m for a robot without any): the normalised
Jacobian is ``Jn = S_x^-1 J S_q`` with ``S_x = diag(L)`` on length rows and 1 on
angle rows, ``S_q = diag(L)`` on prismatic columns and 1 on revolute ones.  It is
dimensionless, and so is the measure

    mu = |det Jn| = |det J| / L^k        (square; k = length rows - prismatic columns)
    mu = sqrt(det(Jn Jn^T))              (wide; sqrt(det(Jn^T Jn)) when tall)

which is Yoshikawa's manipulability of ``Jn``.  A configuration is flagged
*singular* when ``mu < mu_0 = SINGULAR_MEASURE``; only there does damping act,
with ``lambda_max = MAX_DAMPING`` (dimensionless, on ``Jn``).  At ``mu = mu_0``
the damping is zero, so the damped answer meets the exact one continuously.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import sympy as sp

from ..chain import PRISMATIC, Chain, simplify_product

__all__ = ["SINGULAR_MEASURE", "MAX_DAMPING", "Scaling", "ClosedFormInverse", "RegularisedSolve",
           "Minors", "reference_length", "factored", "closed_form_inverse", "regularised_solve",
           "measure_squared", "damped_least_squares", "singular_flag", "damping_factor"]

# mu_0: below this normalised manipulability a configuration counts as singular.  With the
# largest singular value of Jn of order one, mu < 1e-4 means the smallest is below about
# 1e-4: an exact solve would lose more than 4 of the 16 digits (the rule of the run-time
# solves, derivations.model.NumericSolve, which test cond(Jn) > 1e4 directly).  Until
# issue #14 this was 1e-3, which flagged a KR5-size arm at condition numbers of 30.  A
# threshold much lower would not do: any damping that falls to zero at the threshold
# rises from it with a slope of lambda_max^2 / mu_0, and its answer then swings with the
# rounding of the configuration (at 1e-8, O(1) changes for 1e-16 ones).
SINGULAR_MEASURE = sp.Rational(1, 10**4)
# lambda_max: the damping at an exact singularity (on the normalised Jacobian): ten times
# the threshold, as before (1e-2 against 1e-3), so that the damped answer is continuous at
# mu_0 and an exact singularity amplifies rounding by at most eps / lambda_max^2 = 1e-10.
MAX_DAMPING = sp.Rational(1, 10**3)


def reference_length(chain: Chain | None) -> sp.Expr:
    """``L``: the sum of the chain's constant lengths (|a_i|, |d_i| of revolute joints,
    |offset_i| of prismatic ones; for a URDF chain the coordinates of each fixed offset)
    and of the tool offset; 1 (metre) when that is 0.

    An expression in the robot parameters, so the singularity threshold scales
    with the arm when a kernel is called with other parameters.
    """
    if chain is None:
        return sp.S.One
    total = sp.S.Zero
    for joint in chain.joints:
        if chain.convention == "urdf":  # the fixed offsets along the chain
            for fixed in (joint.origin, joint.after):
                # (constants only: a mimic joint folded into a transform moves its offsets)
                total += 0 if fixed is None else sum(sp.Abs(e) for e in sp.Matrix(fixed)[:3, 3] if not e.free_symbols)
            total += sp.Abs(joint.offset) if joint.type == PRISMATIC else 0
            continue
        total += sp.Abs(joint.a)
        total += sp.Abs(joint.offset) if joint.type == PRISMATIC else sp.Abs(joint.d)
    offset = chain.tool[:3, 3]
    if offset != sp.zeros(3, 1):
        total += sp.sqrt(sum(e**2 for e in offset))
    return total if total != 0 else sp.S.One


@dataclass(frozen=True)
class Scaling:
    """How to make a Jacobian dimensionless: ``Jn = diag(L^-rows) J diag(L^columns)``.

    ``rows[i]`` is 1 when row i is a length (m) and 0 when it is an angle or a
    direction cosine; ``columns[j]`` is 1 for a prismatic joint, 0 for a revolute one.
    """

    length: sp.Expr
    rows: tuple[int, ...]
    columns: tuple[int, ...]

    @property
    def power(self) -> int:
        """``k``: the length dimension of ``det J`` (square ``J``)."""
        return sum(self.rows) - sum(self.columns)

    def normalise(self, J: sp.Matrix) -> sp.Matrix:
        L = self.length
        return sp.Matrix(J.rows, J.cols, lambda i, j: J[i, j] * L**(self.columns[j] - self.rows[i]))

    def normalise_rows(self, b: sp.Matrix) -> sp.Matrix:
        return sp.Matrix([b[i] * self.length**(-self.rows[i]) for i in range(b.rows)])

    def restore_columns(self, x: sp.Matrix) -> sp.Matrix:
        return sp.Matrix([x[j] * self.length**self.columns[j] for j in range(x.rows)])


@dataclass(frozen=True)
class ClosedFormInverse:
    """``J^-1 = adjugate / determinant``, each entry simplified, the determinant factored."""

    adjugate: sp.Matrix
    determinant: sp.Expr

    @property
    def inverse(self) -> sp.Matrix:
        return self.adjugate / self.determinant


def factored(expr: sp.Expr) -> sp.Expr:
    """``expr`` expanded, simplified and factored (whichever order gives more factors).

    ``factor`` then simplifying each factor finds the SCORBOT's reach factor
    ``a1 + a2 c2 + a3 c23 + d5 c234`` that the other order misses; simplifying then
    ``factor`` gives the PUMA's shoulder and elbow factors.  The simplification is
    :func:`derivations.chain.simplify_product` (``trigsimp`` gave the same factors for
    every registered robot at 10 times the time: 9 s for a Lynxmotion AL5D's minors).
    A factor whose terms are mostly negative gives its sign to the coefficient.
    """
    expanded = sp.expand(expr)
    if not expanded.has(sp.sin, sp.cos):
        return sp.factor(expanded)
    by_factor = sp.Mul(*[simplify_product(base)**power
                         for base, power in (f.as_base_exp() for f in sp.Mul.make_args(sp.factor(expanded)))])
    candidates = [sp.factor(simplify_product(expanded)), by_factor]

    def rank(candidate):
        return (-len(sp.Mul.make_args(candidate)), sp.count_ops(candidate))

    sign, factors = 1, []
    for f in sp.Mul.make_args(min(candidates, key=rank)):
        base, power = f.as_base_exp()
        if base.is_Add and base.could_extract_minus_sign():
            base = -base
            sign = -sign if power % 2 else sign
        factors.append(base**power)
    return sign * sp.Mul(*factors)


def closed_form_inverse(J: sp.Matrix) -> ClosedFormInverse:
    """The adjugate and factored determinant of a square symbolic matrix.

    The adjugate's entries go through :func:`derivations.chain.simplify_product`, not
    ``trigsimp``: the same entries for the planar arms and the AdeptThree, fewer
    operations for the PUMA's arm block (365 against 408), at 1/20 of the time.

    The determinant is expanded and trig-simplified before factoring (Kumar
    Eq. 13: the 3R arm's ``det J`` simplifies to ``l1 l2 sin(theta2)``).
    """
    if not J.is_square:
        raise ValueError(f"closed_form_inverse needs a square matrix, got {J.rows} x {J.cols}")
    determinant = factored(J.det(method="berkowitz"))
    adjugate = J.adjugate(method="berkowitz").applyfunc(simplify_product)
    return ClosedFormInverse(adjugate, determinant)


@dataclass(frozen=True)
class RegularisedSolve:
    """The answer of :func:`regularised_solve`: ``solution`` (column) and ``singular`` (boolean)."""

    solution: sp.Matrix
    singular: sp.Basic
    damping: sp.Expr  # lambda^2 as a function of the configuration


def singular_flag(measure_squared: sp.Expr) -> sp.Basic:
    """``mu < mu_0``, written without a square root."""
    return sp.StrictLessThan(measure_squared, SINGULAR_MEASURE**2)


def damping_factor(measure_squared: sp.Expr) -> sp.Expr:
    """``lambda^2 = lambda_max^2 max(0, 1 - mu^2 / mu_0^2)`` (zero wherever mu >= mu_0)."""
    return MAX_DAMPING**2 * sp.Max(0, 1 - measure_squared / SINGULAR_MEASURE**2)


class Minors:
    """The minors ``det J[R, C]`` of one matrix, computed on demand, simplified and memoised.

    A minor is ``simplify_product`` of its determinant (``factored`` for the maximal
    ones, which carry the singularities): small exact expressions keep their
    accuracy where the rows are nearly dependent.

    ``known`` supplies minors already derived (the factored determinant of a square
    ``J``, the factored maximal minors of a wide one), keyed by ``(rows, columns)``.
    """

    def __init__(self, J: sp.Matrix, known: dict | None = None):
        self.J = J
        self.table: dict[tuple[tuple[int, ...], tuple[int, ...]], sp.Expr] = dict(known or {})

    def __call__(self, rows: tuple[int, ...], columns: tuple[int, ...]) -> sp.Expr:
        key = (tuple(rows), tuple(columns))
        if key not in self.table:
            if not rows:
                value = sp.S.One
            elif len(rows) == 1:
                value = self.J[rows[0], columns[0]]
            else:
                determinant = self.J.extract(list(rows), list(columns)).det(method="berkowitz")
                value = factored(determinant) if len(rows) == min(self.J.shape) else simplify_product(determinant)
            self.table[key] = value
        return self.table[key]

    @classmethod
    def of_square(cls, J: sp.Matrix, inverse: ClosedFormInverse) -> "Minors":
        """The minors of a square ``J`` with its closed-form inverse: the determinant is the
        full minor, and the adjugate holds the others of size n - 1 (``adj_ij`` is
        ``(-1)^(i+j)`` times the minor without row j and column i)."""
        full = tuple(range(J.rows))
        known = {(full, full): inverse.determinant}
        if J.rows > 1:
            for i in full:
                for j in full:
                    rows = tuple(r for r in full if r != j)
                    columns = tuple(c for c in full if c != i)
                    known[(rows, columns)] = (-1)**(i + j) * inverse.adjugate[i, j]
        return cls(J, known)

    def maximal(self) -> dict[tuple[tuple[int, ...], tuple[int, ...]], sp.Expr]:
        """Every minor of full size ``min(rows, columns)``."""
        m, n = self.J.shape
        if m <= n:
            keys = [(tuple(range(m)), c) for c in itertools.combinations(range(n), m)]
        else:
            keys = [(r, tuple(range(n))) for r in itertools.combinations(range(m), n)]
        return {key: self(*key) for key in keys}


def measure_squared(minors: Minors, scaling: Scaling) -> sp.Expr:
    """``mu^2 = det(Jn Jn^T)`` (or ``det(Jn^T Jn)`` when tall), by Cauchy-Binet: the sum of
    the squared maximal minors of the normalised Jacobian."""
    total = sp.S.Zero
    for (rows, columns), minor in minors.maximal().items():
        total += (minor * _minor_scale(scaling, rows, columns))**2
    return total


def _minor_scale(scaling: Scaling, rows, columns) -> sp.Expr:
    """``det Jn[R, C] = det J[R, C] L^(sum of column powers - sum of row powers)``."""
    return scaling.length**(sum(scaling.columns[c] for c in columns) - sum(scaling.rows[r] for r in rows))


def _gram_inverse(minor, m: int, n: int, t: sp.Expr) -> tuple[sp.Matrix, sp.Expr]:
    """``adj(K K^T + t I)`` and ``det(K K^T + t I)`` of an m x n matrix K (m <= n), from K's minors.

    ``K K^T`` is never formed: rounding its entries would lose the small singular
    values (an error of cond(K)^2 eps).  Expanding in ``t`` over principal row sets S
    and applying Cauchy-Binet to each term,

        det(K K^T + t I)    = sum_S t^(m-|S|) sum_C det K[S, C]^2
        adj(K K^T + t I)_ij = sum_{S containing i, j} t^(m-|S|) (-1)^(pos_S(i) + pos_S(j))
                              sum_C det K[S - j, C] det K[S - i, C]      (|C| = |S| - 1)

    which costs cond(K) eps, like the closed-form inverse itself.
    """
    determinant = sp.S.Zero
    for size in range(m + 1):
        for S in itertools.combinations(range(m), size):
            squares = sum((minor(S, C)**2 for C in itertools.combinations(range(n), size)), sp.S.Zero)
            determinant += t**(m - size) * squares
    adjugate = sp.zeros(m, m)
    for i in range(m):
        for j in range(i, m):
            entry = sp.S.Zero
            for size in range(1, m + 1):
                for S in itertools.combinations(range(m), size):
                    if i not in S or j not in S:
                        continue
                    without_i = tuple(r for r in S if r != i)
                    without_j = tuple(r for r in S if r != j)
                    products = sum((minor(without_j, C) * minor(without_i, C)
                                    for C in itertools.combinations(range(n), size - 1)), sp.S.Zero)
                    entry += t**(m - size) * (-1)**(S.index(i) + S.index(j)) * products
            adjugate[i, j] = adjugate[j, i] = entry
    return adjugate, determinant


def damped_least_squares(J: sp.Matrix, b: sp.Matrix, scaling: Scaling, damping: sp.Expr,
                         minors: Minors | None = None) -> sp.Matrix:
    """``J^T (J J^T + lambda^2 I)^-1 b`` on the normalised Jacobian; ``(J^T J + lambda^2 I)^-1 J^T b`` when tall."""
    minors = minors or Minors(J)
    Jn = scaling.normalise(J)
    bn = scaling.normalise_rows(b)
    if Jn.rows <= Jn.cols:
        def minor(rows, columns):
            return minors(rows, columns) * _minor_scale(scaling, rows, columns)
        adjugate, determinant = _gram_inverse(minor, Jn.rows, Jn.cols, damping)
        xn = Jn.T * (adjugate * bn) / determinant
    else:
        def minor(rows, columns):  # of K = Jn^T
            return minors(columns, rows) * _minor_scale(scaling, columns, rows)
        adjugate, determinant = _gram_inverse(minor, Jn.cols, Jn.rows, damping)
        xn = adjugate * (Jn.T * bn) / determinant
    return scaling.restore_columns(xn)


def regularised_solve(J: sp.Matrix, b: sp.Matrix, scaling: Scaling, minors: Minors,
                      inverse: ClosedFormInverse | None = None) -> RegularisedSolve:
    """Solve ``J x = b``: exactly where the configuration is regular, damped where singular.

    ``minors`` are those of ``J`` (give the factored determinant as a known minor).
    With a closed-form ``inverse`` (square ``J``) the regular branch is
    ``adj(J) b / det J``, guarded so that no branch ever divides by zero (numpy
    evaluates both branches of a selection); without one (wide or tall ``J``) the
    damped least-squares formula is used everywhere, which with zero damping is
    the minimum-norm (wide) or least-squares (tall) solution in normalised units.
    """
    measure = measure_squared(minors, scaling)
    singular = singular_flag(measure)
    damping = damping_factor(measure)
    damped = damped_least_squares(J, b, scaling, damping, minors)
    if inverse is None:
        return RegularisedSolve(damped, singular, damping)
    # adj(J) b / det J, written as adj(J) b det J / max(det J^2, floor): identical wherever the
    # configuration is regular (there det J^2 >= floor), and finite everywhere, because numpy
    # evaluates both branches of the selection below.  (A Piecewise guard would not do:
    # SymPy moves 1/Piecewise inside the branches.)
    determinant = inverse.determinant
    floor = SINGULAR_MEASURE**2 * scaling.length**(2 * scaling.power)  # (mu_0 L^k)^2
    exact = inverse.adjugate * b * determinant / sp.Max(determinant**2, floor)
    solution = sp.Matrix([sp.Piecewise((d, singular), (e, True)) for d, e in zip(damped, exact)])
    return RegularisedSolve(solution, singular, damping)

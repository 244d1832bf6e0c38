"""The determinant of a square Jacobian, its singular set and the inverse rate map.

Which Jacobian: the task Jacobian ``d task / d q`` when it is square (Kumar
Eq. 11, the slides' 2R example, Rehiara's AdeptThree), else the 6 x 6 geometric
Jacobian of a six-joint arm (its determinant does not depend on the reference
point or the frame it is written in).  Other shapes have no determinant.

The determinant is put into a product of short trigonometric factors
(``l1 l2 sin(q2)``, Kumar Eq. 13), because that product *is* the singular set:
each factor that depends on the joints, set to zero, is one family of singular
configurations.  Two exact routes to the factors are tried and the first whose
product equals the determinant identically is kept:

* tangent half-angle: ``sin q = 2t/(1+t^2)``, ``cos q = (1-t^2)/(1+t^2)`` turns
  the determinant into a rational function, which factors uniquely; a factor of
  degree <= 2 in each ``t`` maps back to ``{1, cos q, sin q}`` exactly;
* polynomial: ``sin``/``cos`` as symbols reduced by ``s^2 + c^2 = 1``, factored.

A block-triangular 6 x 6 Jacobian (``J_v`` of the wrist joints zero at a wrist
centre, Paul's wrist-partitioned model in the velocity slides) is split into
``det A det D`` first, which keeps the Puma's determinant to a second.
"""
from __future__ import annotations

import random
from dataclasses import dataclass

import sympy as sp

from ..support.budget import BudgetExceeded, budget, degraded
from ..support.cache import cached
from ..chain import PRISMATIC, simplify_entry, simplify_product
from .velocity import MAX_CLOSED_FORM

__all__ = ["FACTOR_LIMIT", "JacobianDeterminant", "square_jacobian", "jacobian_determinant", "trig_factor", "inverse_rate_map"]

# A symbolic adjugate of a larger Jacobian is pages long and buys the reader nothing: the
# same bound as the rate kernels' closed-form inverse.
MAX_INVERSE_SIZE = MAX_CLOSED_FORM
# Factoring is tried on a block's determinant only while it has at most this many operations
# as the Berkowitz algorithm gives it (unexpanded).  The PUMA 560's blocks have 281 and 96; a
# UR5's 6 x 6 determinant 29106, whose factoring took 4 minutes.  Only the LaTeX reads the
# factors (the kernels flag singular configurations numerically), so a larger determinant is
# reported as not factored rather than holding up the kernels.  A count, not a clock: the
# fragment is the same on any machine.
FACTOR_LIMIT = 2000
# A safety net behind FACTOR_LIMIT: factoring that still runs longer than this stops.
FACTOR_BUDGET = 30.0


@dataclass(frozen=True)
class JacobianDeterminant:
    """``det J`` of the square Jacobian ``which`` (``"task_jacobian"`` or ``"jacobian"``).

    ``factors`` multiply to ``value``; ``singular`` lists, for each factor that
    depends on the joints, the factor and the joint values that zero it (an
    empty tuple when it has no closed form here: the condition is ``factor = 0``).
    """

    which: str
    value: sp.Expr | None
    factors: tuple[sp.Expr, ...]
    singular: tuple[tuple[sp.Expr, tuple[sp.Eq, ...]], ...]
    # False when the determinant was too large to factor (see FACTOR_LIMIT): then ``value``
    # is None, ``factors`` and ``singular`` are empty, and ``size`` is a lower bound of its
    # operation count (above FACTOR_LIMIT).
    factored: bool = True
    size: int = 0


def square_jacobian(model) -> tuple[str, sp.Matrix] | None:
    """The Jacobian whose determinant decides singularity, or ``None`` (also for a model written as a
    program, whose determinant in its steps would say nothing about the joints)."""
    if model.program:
        return None
    if model.task_jacobian.shape == (model.n, model.n):
        return "task_jacobian", model.task_jacobian
    if model.n == 6:
        return "jacobian", model.jacobian
    return None


def jacobian_determinant(model) -> JacobianDeterminant | None:
    """``det J`` as a product of short factors, with the singular set (cached on disk, and on the model)."""
    if "_jacobian_determinant" in model.__dict__:
        return model.__dict__["_jacobian_determinant"]
    chosen = square_jacobian(model)
    if chosen is None:
        return None
    which, J = chosen
    key = sp.srepr((J, tuple(model.q))).encode()
    result = cached(f"determinant-{model.name}", key, lambda: _determinant(which, J, model.q, model.joint_types))
    model.__dict__["_jacobian_determinant"] = result
    return result


def _determinant(which: str, J: sp.Matrix, q, joint_types) -> JacobianDeterminant:
    n = J.shape[0]
    half = n // 2
    if n % 2 == 0 and n >= 4 and all(_vanishes(e) for e in J[:half, half:]):
        # [A 0; C D]: det J = det A det D (wrist-partitioned, velocity slides)
        blocks = [J[:half, :half], J[half:, half:]]
    else:
        blocks = [J]
    determinants = [block.det(method="berkowitz") for block in blocks]
    size = _operations_within(determinants, FACTOR_LIMIT)
    if size > FACTOR_LIMIT:
        return JacobianDeterminant(which, None, (), (), factored=False, size=size)
    factors: list[sp.Expr] = []
    try:
        with budget(FACTOR_BUDGET, f"factoring det {which}"):
            for determinant in determinants:
                factors.extend(sp.Mul.make_args(trig_factor(determinant, q)))
    except BudgetExceeded:
        degraded(f"factoring det {which}")  # a wall-clock verdict: not to be cached
        return JacobianDeterminant(which, None, (), (), factored=False, size=size)
    coefficient = sp.Mul(*[f for f in factors if f.is_number])
    factors = [f for f in factors if not f.is_number]
    for k, f in enumerate(factors):
        # -a2 c2 - a3 c23 + d4 s23 -> -(a2 c2 + a3 c23 - d4 s23): fewer minus signs to read
        terms = sp.Add.make_args(f)
        if len(terms) > 1 and 2 * sum(t.could_extract_minus_sign() for t in terms) > len(terms):
            factors[k] = sp.expand(-f)
            coefficient = -coefficient
    if coefficient != 1:
        factors.insert(0, coefficient)
    value = sp.Mul(*factors)
    singular = tuple((f, _zeros(f, q, joint_types)) for f in factors if f.free_symbols & set(q))
    return JacobianDeterminant(which, value, tuple(factors), singular)


def trig_factor(expr: sp.Expr, q) -> sp.Expr:
    """``expr`` (polynomial in sin/cos of the joints) as a product of short factors.

    The result equals ``expr`` identically (checked); when no route factors it,
    ``expr`` comes back simplified but whole.
    """
    expr = sp.expand(sp.expand_trig(sp.expand(expr)))
    for route in (_half_angle_factor, _polynomial_factor):
        product = route(expr, q)
        if product is not None and _identical(product, expr):
            return product
    return simplify_entry(expr)


def _operations_within(exprs, limit: int) -> int:
    """``sum(count_ops(e))`` where it is at most ``limit``; otherwise a lower bound above it.

    ``count_ops`` walks the whole expression tree, and an unexpanded Berkowitz determinant
    of a general 6R is a tree of some 10^5 nodes (1.4 s to count for the Jaco).  No
    operation brings more than four nodes (``x/y`` is five nodes, ``Mul(x, Pow(y, -1))``,
    and one division), so a tree of more than ``4 * limit + 1`` nodes has more than
    ``limit`` operations: the walk stops there.
    """
    total = 0
    cap = 4 * limit + 1
    for expr in exprs:
        nodes, stack = 0, [expr]
        while stack and nodes <= cap:
            nodes += 1
            stack.extend(stack.pop().args)
        if nodes > cap:
            return max(limit + 1, total + (nodes - 1) // 4)
        total += int(sp.count_ops(expr))
    return total


def _vanishes(expr: sp.Expr) -> bool:
    """``expr == 0`` identically, for a Jacobian entry: a nonzero value at one random point
    settles "no" at once (``trigsimp`` of a general 6R's 3x3 block took 7 s to say so);
    otherwise :func:`derivations.chain.simplify_product` must reduce it to 0."""
    if expr == 0:
        return True
    rng = random.Random(20261124)
    point = {s: sp.Rational(rng.randint(-10**6, 10**6), 10**6) for s in sorted(expr.free_symbols, key=str)}
    if abs(expr.xreplace(point).evalf(30)) > 1e-20:
        return False
    return simplify_product(expr) == 0


def _identical(a: sp.Expr, b: sp.Expr) -> bool:
    """``a == b`` identically: symbolically when expanding settles it, else at random points.

    Where the expanded difference does not cancel term by term (trig identities left
    over), it is evaluated at 8 random rational points at 60 digits; a nonzero
    trigonometric polynomial vanishes at such points with probability zero, and a
    difference below 1e-40 of the terms' size is taken as cancellation.  ``simplify``
    did the same job symbolically in 13 s for a KUKA KR5's determinant.
    """
    difference = sp.expand(sp.expand_trig(sp.expand(a - b)))
    if difference == 0:
        return True
    symbols = sorted(difference.free_symbols, key=str)
    rng = random.Random(20261123)
    for _ in range(8):
        point = {s: sp.Rational(rng.randint(-10**6, 10**6), 10**6) for s in symbols}
        value = abs(difference.xreplace(point).evalf(60))
        scale = max([abs(t.xreplace(point).evalf(60)) for t in sp.Add.make_args(difference)] + [sp.S.One])
        if value > scale * sp.Float("1e-40", 60):
            return False
    return True


def _half_angle_factor(expr: sp.Expr, q) -> sp.Expr | None:
    t = {qi: sp.Dummy(f"t_{qi}") for qi in q if expr.has(qi)}
    if not t:
        return sp.factor(expr)
    if any(not _is_trig_polynomial(expr, qi) for qi in t):
        return None
    sub = {}
    for qi, ti in t.items():
        sub[sp.sin(qi)] = 2 * ti / (1 + ti**2)
        sub[sp.cos(qi)] = (1 - ti**2) / (1 + ti**2)
    numerator, denominator = sp.fraction(sp.factor(sp.together(expr.xreplace(sub))))
    # Each t_i must come as (1 + t_i^2)^k in the denominator and degree 2k in the numerator
    # spread over factors of even degree: then every factor maps back to sin/cos exactly.
    budget = {ti: sp.degree(denominator, ti) // 2 if denominator.has(ti) else 0 for ti in t.values()}
    out = []
    for factor in sp.Mul.make_args(numerator):
        base, power = factor.as_base_exp()
        if not power.is_Integer or power < 1:
            return None
        degrees = {ti: sp.degree(base, ti) for ti in t.values() if base.has(ti)}
        if any(d != 2 for d in degrees.values()):
            return None
        for ti in degrees:
            budget[ti] -= int(power)
        trig = _from_half_angle(sp.Poly(base, *degrees.keys()).as_expr(), list(degrees.keys()),
                                {ti: qi for qi, ti in t.items()}) if degrees else base
        out.append(simplify_entry(trig) ** power)
    if any(b != 0 for b in budget.values()):
        return None
    return sp.Mul(*out)


def _from_half_angle(poly: sp.Expr, variables, angle_of) -> sp.Expr:
    """Map a polynomial of degree 2 in each t = tan(q/2) back to {1, cos q, sin q}.

    ``a(1+t^2) + b(1-t^2) + 2ct`` has coefficients (a+b, 2c, a-b) in (1, t, t^2):
    the exact change of basis, variable by variable.
    """
    if not variables:
        return poly
    ti, rest = variables[0], variables[1:]
    p = sp.Poly(poly, ti)
    p0, p1, p2 = (p.coeff_monomial(ti**k) for k in range(3))
    angle = angle_of[ti]
    return (_from_half_angle(sp.expand((p0 + p2) / 2), rest, angle_of)
            + _from_half_angle(sp.expand((p0 - p2) / 2), rest, angle_of) * sp.cos(angle)
            + _from_half_angle(sp.expand(p1 / 2), rest, angle_of) * sp.sin(angle))


def _is_trig_polynomial(expr: sp.Expr, qi: sp.Symbol) -> bool:
    """``qi`` occurs only as sin(qi) and cos(qi)."""
    stripped = expr.xreplace({sp.sin(qi): sp.Dummy(), sp.cos(qi): sp.Dummy()})
    return not stripped.has(qi)


def _polynomial_factor(expr: sp.Expr, q) -> sp.Expr:
    s = {qi: sp.Dummy(f"s_{qi}") for qi in q}
    c = {qi: sp.Dummy(f"c_{qi}") for qi in q}
    poly = sp.expand(expr.xreplace({sp.sin(qi): s[qi] for qi in q}).xreplace({sp.cos(qi): c[qi] for qi in q}))
    used = [qi for qi in q if poly.has(s[qi]) or poly.has(c[qi])]
    if used:
        relations = [s[qi]**2 + c[qi]**2 - 1 for qi in used]
        _, poly = sp.reduced(poly, relations, *([s[qi] for qi in used] + [c[qi] for qi in used]), order="lex")
    back = {**{s[qi]: sp.sin(qi) for qi in q}, **{c[qi]: sp.cos(qi) for qi in q}}
    out = []
    for factor in sp.Mul.make_args(sp.factor(poly)):
        base, power = factor.as_base_exp()
        out.append(simplify_entry(base.xreplace(back)) ** power)
    return sp.Mul(*out)


def _zeros(factor: sp.Expr, q, joint_types) -> tuple[sp.Eq, ...]:
    """Joint values at which ``factor`` vanishes, when it is simple enough to say.

    ``sin(q_i)`` -> q_i in {0, pi}; ``cos(q_i)`` -> q_i in {-pi/2, pi/2} (one turn,
    -pi < q_i <= pi); a factor linear in a prismatic variable -> that value.
    Anything else: empty (the condition is the equation ``factor = 0``).
    """
    base = factor.as_base_exp()[0]
    if base.could_extract_minus_sign():
        base = -base
    joints = sorted(base.free_symbols & set(q), key=lambda s: q.index(s))
    if len(joints) != 1:
        return ()
    qi = joints[0]
    kind = joint_types[q.index(qi)]
    if isinstance(base, sp.sin) and base.args[0] == qi:
        return (sp.Eq(qi, 0), sp.Eq(qi, sp.pi))
    if isinstance(base, sp.cos) and base.args[0] == qi:
        return (sp.Eq(qi, -sp.pi / 2), sp.Eq(qi, sp.pi / 2))
    if kind == PRISMATIC and sp.Poly(base, qi).degree() == 1:
        return tuple(sp.Eq(qi, root) for root in sp.solve(base, qi))
    return ()


def inverse_rate_map(model, determinant: JacobianDeterminant | None = None):
    """``(adj J, det J)`` of the square task Jacobian (n <= 4), else ``None``.

    ``J^{-1} = adj(J) / det J``: the adjugate entries simplified through
    ``expand + trigsimp``, the determinant factored.  The map holds away from
    the singular set, which the caller states beside it.
    """
    determinant = determinant or jacobian_determinant(model)
    if determinant is None or determinant.which != "task_jacobian" or model.n > MAX_INVERSE_SIZE:
        return None
    if not determinant.factored or determinant.value == 0:
        return None
    rates = model.rates
    if rates is not None and rates.strategy == "square":
        # The rate kernels' closed form (damping.closed_form_inverse) already holds this adjugate.
        return rates.inverse.adjugate, determinant.value
    J = model.task_jacobian
    key = sp.srepr((J, determinant.value)).encode()
    adjugate = cached(f"adjugate-{model.name}", key,
                      lambda: J.adjugate(method="berkowitz").applyfunc(simplify_entry))
    return adjugate, determinant.value

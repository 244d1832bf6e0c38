"""The operation count of a kernel: ``sympy.count_ops``'s number, without its cost.

Each kernel reports how many operations its temporaries and outputs take after CSE (the C's
header comments, ``OPERATIONS``, the choice of a batch layout, the split of the C into parts).
``sympy.count_ops`` was a fifth of a kernel's preparation (a KR 210 with its dynamics: 1.4 of
6.1 s): at every negative product it builds the negated product, and at every product it
builds its numerator and denominator, to walk them.  :func:`operation_count` follows the same
rules on the expression's own nodes, builds none of those, and remembers each node's count
(a kernel's entries share most of their nodes).  It gives the same number as ``count_ops``
(tested over every kernel of several arms, and random expressions); a node whose rules it does
not follow (an ``exp``, a power of a number or of a product, a relation at the top) is counted
by ``count_ops`` itself.
"""
from __future__ import annotations

import functools

import sympy as sp
from sympy.core.operations import LatticeOp

__all__ = ["operation_count"]


def operation_count(expr) -> int:
    """``int(sympy.count_ops(expr))`` for a SymPy expression."""
    if not isinstance(expr, sp.Expr) or expr.is_Relational:
        return int(sp.count_ops(expr))
    try:
        return _node_count(expr)
    except _Unhandled:
        return int(sp.count_ops(expr))


class _Unhandled(Exception):
    """A node whose count operation_count does not follow (``count_ops`` counts it)."""


class _Product(tuple):
    """The factors (at least two) of a product ``count_ops`` builds on the way, a negated product,
    a numerator or a denominator, as the ``Mul`` they would make, without making it."""


class _Power(tuple):
    """(base, exponent) of a denominator's power ``Pow(base, -e)`` of a factor ``base**e`` with e < 0."""

    is_Integer = is_Number = is_Add = False


@functools.lru_cache(maxsize=1 << 16)
def _node_count(node) -> int:
    return _count(node)


def _count(node) -> int:
    """``count_ops``'s count of ``node`` and everything under it: the body of its loop for one item
    taken off its stack, and the items it pushes, counted the same way."""
    if isinstance(node, _Power):
        base, exponent = node
        return 1 + _node_count(base) + _node_count(exponent)
    if isinstance(node, _Product):
        return _product_count(node)
    if node.is_Rational:
        return 0 if node is sp.S.One else (node.p < 0) + (node.q != 1)
    if node.is_Mul:
        if node.is_commutative is False:
            raise _Unhandled
        return _product_count(node.args)
    if node.is_Add:
        total, negatives = 0, 0
        for i, term in enumerate(node.args):
            if _negative_coefficient(term):
                negatives += 1
                total += (i > 0) + _count(_negated(term))
            else:
                total += (i > 0) + _node_count(term)
        return total + (negatives == len(node.args))  # -x - y: a NEG as well; -x + y: a SUB for the ADD
    return _generic_count(node)


def _negative_coefficient(term) -> bool:
    """sympy.core.function._coeff_isneg."""
    if term.is_Mul:
        term = term.args[0]
    return bool(term.is_Number and term.is_extended_negative)


def _negated(term):
    """``-term`` for a negative number or a product with a negative coefficient, as count_ops makes
    it: the coefficient negated, or dropped where it was -1 (``as_two_terms``)."""
    if term.is_Number:
        return -term
    coefficient, rest = term.args[0], term.args[1:]
    if coefficient is not sp.S.NegativeOne:
        return _Product((-coefficient,) + rest)
    return rest[0] if len(rest) == 1 else _Product(rest)


def _product_count(factors) -> int:
    """The count of a product with these factors: count_ops's branch for a Mul."""
    ops = 0
    if factors[0].is_Number and factors[0].is_extended_negative:
        ops += 1  # NEG, and the product without its sign goes on
        if factors[0] is sp.S.NegativeOne:
            factors = factors[1:]
        else:
            factors = (-factors[0],) + tuple(factors[1:])
    numer, denom = _fraction(factors)
    if not numer or (len(numer) == 1 and numer[0].is_Integer):  # 1/d, 3/d: a DIV and d
        return ops + 1 + (1 if numer and numer[0].is_extended_negative else 0) + _count(_made(denom))
    if denom:  # n/d: a DIV, n and d (an integer d counts nothing)
        d = _made(denom)
        return ops + 1 + (0 if len(denom) == 1 and denom[0].is_Integer else _count(d)) + _count(_made(numer))
    if len(factors) == 1:  # what is left of -x: x, past count_ops's first branches
        return ops + _generic_count(factors[0])
    return ops + len(factors) - 1 + sum(_node_count(f) for f in factors)


def _fraction(factors) -> tuple[tuple, tuple]:
    """(numerator, denominator) factors of a product, as sympy.simplify.fraction splits them."""
    numer, denom = [], []
    for term in factors:
        if isinstance(term, _Power):  # in a denominator counted on its own
            numer.append(term)
        elif term.is_Pow:
            base, exponent = term.args
            if not exponent.is_Number or base.is_Number or base.is_Pow or base.is_Mul or base is sp.S.Exp1:
                raise _Unhandled  # powers that evaluate or combine when rebuilt
            if exponent.is_extended_negative:
                denom.append(base if exponent is sp.S.NegativeOne else _Power((base, -exponent)))
            else:
                numer.append(term)
        elif term.is_Rational and not term.is_Integer:
            if term.p != 1:
                numer.append(sp.Integer(term.p))
            denom.append(sp.Integer(term.q))
        else:
            numer.append(term)
    return tuple(numer), tuple(denom)


def _made(factors):
    """The product of ``factors`` as ``Mul(*factors)`` evaluates it: one, the factor, or the product;
    a number times one sum (which Mul would distribute) is left to count_ops."""
    if not factors:
        return sp.S.One
    if len(factors) == 1:
        return factors[0]
    if len(factors) == 2 and any(f.is_Number for f in factors) and any(f.is_Add for f in factors):
        raise _Unhandled
    return _Product(factors)


def _generic_count(node) -> int:
    """count_ops's last branches: a reciprocal, an n-ary product or lattice operation, a power or
    function, then the arguments."""
    if node.is_Pow and node.exp is sp.S.NegativeOne:
        return 1 + _node_count(node.base)
    if node is sp.S.Exp1 or (node.is_Pow and node.base is sp.S.Exp1) or node.is_Matrix:
        raise _Unhandled
    ops = 0
    if node.is_Mul or isinstance(node, LatticeOp):
        ops += len(node.args) - 1
    elif node.args and (node.is_Pow or node.is_Function
                        or isinstance(node, (sp.Derivative, sp.Integral, sp.Sum))):
        ops += 1
    if not node.is_Symbol:
        ops += sum(_node_count(a) for a in node.args)
    return ops

"""Straight-line programs: kinematics as a sequence of small definitions.

A general arm (every twist and offset an arbitrary number, or seven joints) has
frames whose expanded entries nothing cancels in: each one a sum of hundreds of
products, its Jacobian and their rates larger still, and every later step (the
derivatives, the common subexpressions, the printing) pays for that size.  The
arm's kinematics is a short program all the same: each frame is the one before it
times one link transform, twelve entries of three products each.  A
:class:`Program` keeps it in that form, as ordered steps ``(symbol, expression)``,
each expression in the joint variables, the parameters and the symbols of earlier
steps, which is also the form the generated C ends up in.

Derivatives stay programs too (forward mode): ``d s / d x`` of a step ``s = e`` is
the step ``sum_u (d e / d u) (d u / d x)`` over what ``e`` reads, written once per
step and variable and zero where ``s`` does not depend on ``x``.  The time
derivative along joint rates is the same walk with ``d q_k / d t = qd_k``.  So a
seven-joint arm's Jacobian and its rate are a few hundred steps of a few
operations each, derived in a fraction of a second.

:func:`needed` picks the steps a set of expressions reads (in program order), and
:func:`inline` substitutes them back into an explicit expression where a caller
needs one (a lambdified reference, the tool pose at q = 0).
"""
from __future__ import annotations

from typing import Iterable, Mapping, Sequence

import sympy as sp

from .chain import derivative

__all__ = ["Program", "needed", "inline", "substitute", "evaluate", "evaluator", "evaluate_arrays"]

Steps = tuple[tuple[sp.Symbol, sp.Expr], ...]


def _trivial(expr: sp.Expr) -> bool:
    """Not worth a step of its own: a number, a symbol, or minus one of those."""
    if expr.is_Atom:
        return True
    return expr.is_Mul and len(expr.args) == 2 and expr.args[0] == -1 and expr.args[1].is_Atom


class Program:
    """Ordered steps, each defined once (the same expression twice is one step).

    ``taken`` holds names the steps must not use (the parameters, the kernels'
    arguments); every step name is checked against them and against the others.
    """

    def __init__(self, steps: Iterable[tuple[sp.Symbol, sp.Expr]] = (), taken: Iterable[str] = ()):
        self.steps: list[tuple[sp.Symbol, sp.Expr]] = []
        self.value: dict[sp.Symbol, sp.Expr] = {}
        self._by_expression: dict[sp.Expr, sp.Symbol] = {}
        self._reads: dict[sp.Symbol, frozenset] = {}  # the variables (non-step symbols) each step depends on
        self._taken = set(taken)
        self._derivatives: dict[tuple, sp.Expr] = {}
        for symbol, expr in steps:
            self._append(symbol, expr)

    def __len__(self) -> int:
        return len(self.steps)

    def _append(self, symbol: sp.Symbol, expr: sp.Expr) -> None:
        if symbol.name in self._taken:
            raise ValueError(f"the program step {symbol.name} is also the name of a parameter or an argument")
        self._taken.add(symbol.name)
        self.steps.append((symbol, expr))
        self.value[symbol] = expr
        self._by_expression[expr] = symbol
        self._reads[symbol] = self.depends(expr)

    def define(self, name: str, expr) -> sp.Expr:
        """A step ``name = expr``, or ``expr`` itself where a step would not pay (a number, a symbol),
        or the earlier step of the same expression."""
        expr = sp.sympify(expr)
        if _trivial(expr):
            return expr
        known = self._by_expression.get(expr)
        if known is not None:
            return known
        symbol = sp.Symbol(name, real=True)
        self._append(symbol, expr)
        return symbol

    def depends(self, expr) -> frozenset:
        """The variables (symbols that are not steps) ``expr`` depends on, through the steps it reads."""
        found: set = set()
        for s in sp.sympify(expr).free_symbols:
            reads = self._reads.get(s)
            if reads is None:
                found.add(s)
            else:
                found |= reads
        return frozenset(found)

    def derivative(self, expr, x: sp.Symbol) -> sp.Expr:
        """``d expr / d x``, as an expression in steps (new ones for the steps' own derivatives)."""
        expr = sp.sympify(expr)
        terms = [derivative(expr, x)] if expr.has(x) else []
        for u in sorted(expr.free_symbols & self.value.keys(), key=sp.default_sort_key):
            if x in self._reads[u]:
                du = self._step_derivative(u, x)
                if du != 0:
                    terms.append(derivative(expr, u) * du)
        return sp.Add(*terms)

    def _step_derivative(self, u: sp.Symbol, x: sp.Symbol) -> sp.Expr:
        key = (u, x)
        if key not in self._derivatives:
            self._derivatives[key] = self.define(f"{u.name}_d{x.name}", self.derivative(self.value[u], x))
        return self._derivatives[key]

    def time_derivative(self, expr, rates: Mapping[sp.Symbol, sp.Symbol]) -> sp.Expr:
        """``d expr / dt`` where each variable ``v`` of ``rates`` moves at ``rates[v]`` (a joint at its rate)."""
        expr = sp.sympify(expr)
        terms = [derivative(expr, v) * rate for v, rate in rates.items() if expr.has(v)]
        for u in sorted(expr.free_symbols & self.value.keys(), key=sp.default_sort_key):
            if self._reads[u] & rates.keys():
                du = self._step_rate(u, rates)
                if du != 0:
                    terms.append(derivative(expr, u) * du)
        return sp.Add(*terms)

    def _step_rate(self, u: sp.Symbol, rates) -> sp.Expr:
        key = (u, "dt", tuple(rates.items()))
        if key not in self._derivatives:
            self._derivatives[key] = self.define(f"{u.name}_dt", self.time_derivative(self.value[u], rates))
        return self._derivatives[key]


def needed(steps: Sequence[tuple[sp.Symbol, sp.Expr]], exprs: Iterable) -> Steps:
    """The steps that ``exprs`` read, directly or through other steps, in program order."""
    value = dict(steps)
    wanted: set = set()
    pending = [s for e in exprs for s in sp.sympify(e).free_symbols if s in value]
    while pending:
        symbol = pending.pop()
        if symbol not in wanted:
            wanted.add(symbol)
            pending.extend(s for s in value[symbol].free_symbols if s in value and s not in wanted)
    return tuple((s, e) for s, e in steps if s in wanted)


def inline(steps: Sequence[tuple[sp.Symbol, sp.Expr]], expr):
    """``expr`` (an expression or a matrix) with the steps substituted: explicit in the variables."""
    if not steps:
        return expr
    values: dict = {}
    for symbol, value in needed(steps, sp.Matrix([expr]).values() if isinstance(expr, sp.MatrixBase) else [expr]):
        values[symbol] = value.xreplace(values)
    return expr.xreplace(values)


def substitute(steps: Sequence[tuple[sp.Symbol, sp.Expr]], expr, values: Mapping):
    """``expr`` (an expression or a matrix) with ``values`` ({symbol: value}) put in and the steps
    substituted, exactly: each step once, in order (inlining first and substituting after would
    walk the unfolded tree, which grows as the product of the steps' fan-outs)."""
    known = dict(values)
    entries = sp.Matrix([expr]).values() if isinstance(expr, sp.MatrixBase) else [expr]
    for symbol, value in needed(steps, entries):
        known[symbol] = value.xreplace(known)
    return expr.xreplace(known)


def evaluate(steps: Sequence[tuple[sp.Symbol, sp.Expr]], exprs: Sequence, point: Mapping, digits: int = 30) -> list:
    """``exprs`` at ``point`` ({symbol: number}), the steps they read evaluated one by one with ``evalf``."""
    known: dict = {s: sp.sympify(v) for s, v in point.items()}
    for symbol, value in needed(steps, exprs):
        known[symbol] = value.xreplace(known).evalf(digits)
    return [sp.sympify(e).xreplace(known).evalf(digits) for e in exprs]


class _Arithmetic:
    """How :func:`_walk` computes in one number system: ``number(e)`` of a SymPy number, ``total``
    and ``product`` of a list, ``power(base, exponent expression, walk)``, the functions by SymPy
    class, and ``other(e, known)`` for anything else (or an error)."""

    def __init__(self, number, total, product, power, functions, other):
        self.number, self.total, self.product, self.power = number, total, product, power
        self.functions, self.other = functions, other


def _walk(e, known: dict, arithmetic: _Arithmetic):
    """The value of ``e`` in ``arithmetic``, the symbols it reads taken from ``known``."""
    if e in known:
        return known[e]
    if e.is_Number or e.is_NumberSymbol:
        return arithmetic.number(e)
    if e.is_Add:
        return arithmetic.total([_walk(a, known, arithmetic) for a in e.args])
    if e.is_Mul:
        return arithmetic.product([_walk(a, known, arithmetic) for a in e.args])
    if e.is_Pow:
        return arithmetic.power(_walk(e.base, known, arithmetic), e.exp, lambda x: _walk(x, known, arithmetic))
    if e.func in arithmetic.functions:
        return arithmetic.functions[e.func](*(_walk(a, known, arithmetic) for a in e.args))
    return arithmetic.other(e, known)


def _run(steps, exprs, known: dict, arithmetic: _Arithmetic) -> list:
    """``exprs`` with the steps they read evaluated once each, in order, in ``arithmetic``."""
    exprs = [sp.sympify(e) for e in exprs]
    for symbol, expr in needed(steps, exprs):
        known[symbol] = _walk(sp.sympify(expr), known, arithmetic)
    return [_walk(e, known, arithmetic) for e in exprs]


def evaluator(steps: Sequence[tuple[sp.Symbol, sp.Expr]], exprs: Sequence, args: Sequence[sp.Symbol]):
    """A function of ``args`` (numbers mpmath takes) that gives ``exprs`` (which read ``steps``) as
    mpmath numbers at mpmath's working precision (``mpmath.workdps``), each step evaluated once by a
    walk of its tree in mpmath arithmetic.  Where one program is evaluated at a few points this is
    many times faster than :func:`evaluate`, whose SymPy arithmetic (``xreplace`` and ``evalf`` per
    step) was most of the singularity check of a seven-joint arm's mass matrix (2.5 s for three points)."""
    import mpmath

    def number(e):
        return mpmath.mpf(e.p) / e.q if e.is_Rational else mpmath.mpf(str(e.evalf(mpmath.mp.dps + 5)))

    def other(e, known):
        return mpmath.mpf(str(e.xreplace({s: sp.Float(str(known[s]), mpmath.mp.dps) for s in e.free_symbols})
                              .evalf(mpmath.mp.dps)))
    arithmetic = _Arithmetic(
        number, mpmath.fsum, mpmath.fprod,
        lambda base, exponent, walk: base ** (int(exponent) if exponent.is_Integer else walk(exponent)),
        {sp.sin: mpmath.sin, sp.cos: mpmath.cos, sp.tan: mpmath.tan, sp.atan2: mpmath.atan2, sp.asin: mpmath.asin,
         sp.acos: mpmath.acos, sp.exp: mpmath.exp, sp.log: mpmath.log, sp.sign: mpmath.sign, sp.Abs: abs}, other)
    body, exprs = needed(steps, exprs), [sp.sympify(e) for e in exprs]  # once, for every point
    return lambda *values: _run(body, exprs, dict(zip(args, values)), arithmetic)


# The functions a program's steps use, in numpy (a dynamics program reads sines, cosines and signs).
_NUMPY_FUNCTIONS = {sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.sign: "sign", sp.Abs: "abs", sp.exp: "exp",
                    sp.log: "log", sp.asin: "arcsin", sp.acos: "arccos", sp.atan: "arctan", sp.atan2: "arctan2"}


def evaluate_arrays(steps: Sequence[tuple[sp.Symbol, sp.Expr]], exprs: Sequence, point: Mapping) -> list:
    """``exprs`` in double precision at ``point`` ({symbol: float or array}, arrays broadcasting
    together), the steps they read evaluated one by one over the whole batch: a walk of each
    step's expression tree with numpy (:func:`_walk`, as :func:`evaluator` in mpmath), so that a program
    of thousands of steps is evaluated at many points in a fraction of a second (where :func:`evaluate`
    takes 30 digits, one point at a time)."""
    import numpy as np

    def product(values):
        out = values[0]
        for v in values[1:]:
            out = out * v
        return out

    def power(base, exponent, walk):
        exponent = walk(exponent)
        return 1.0 / base if exponent == -1 else np.sqrt(base) if exponent == 0.5 else base ** exponent

    def other(e, known):
        if e.is_Symbol:
            raise ValueError(f"no value for {e}")
        raise ValueError(f"cannot evaluate {e.func.__name__} in double precision")
    arithmetic = _Arithmetic(float, lambda values: sum(values[1:], values[0]), product, power,
                             {f: getattr(np, name) for f, name in _NUMPY_FUNCTIONS.items()}, other)
    return _run(steps, exprs, {s: np.asarray(v, dtype=float) for s, v in point.items()}, arithmetic)

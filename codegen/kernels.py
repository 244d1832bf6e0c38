"""Preparing a symbolic function for printing: one CSE pass over all its outputs.

Every backend prints the same :class:`PreparedFunction`: the arguments it
unpacks, the parameters it reads, the temporaries of a single common
subexpression elimination run over all outputs together (so a sine shared by
the pose and the Jacobian is computed once), and each output entry.
"""
from __future__ import annotations

import functools

from dataclasses import dataclass

import sympy as sp
from sympy.simplify.cse_main import tree_cse

from derivations.model import SymbolicFunction

from .operations import operation_count

__all__ = ["PreparedFunction", "PreparedOutput", "PreparedCheck", "prepare", "canonical", "exact_floats",
           "bounded_numbers", "free_symbols", "STATUS_CODES", "EXACT_INTEGER_LIMIT"]

TEMPORARY_PREFIX = "_t"
# A kernel of at least this many steps and outputs (a straight-line program: the unsnapped iCub arm's
# Coriolis matrix has 1,734 steps and its regressor 2,121) gets the tree part of SymPy's CSE alone,
# without opt_cse's search for shared parts of sums and products: that search is 60-75 % of its CSE
# there (coriolis 3.0 -> 1.2 s, regressor 2.7 -> 0.6 s) for 12-16 % fewer operations, on kernels
# that are programs already.  The papers' robots' kernels are far below it, and so are the snapped
# iCub arm's (its Coriolis matrix: 1,011).
TREE_CSE_ONLY = 1500
# Status returned by a C kernel whose requirement fails (0 is success); also named in each header.
STATUS_CODES = {"unreachable": 1, "singular": 2}


def name_of(symbol: sp.Basic) -> str:
    """``str(symbol)``: a plain Symbol's name read directly (``str`` builds a SymPy printer each time,
    which was 7 % of a KR 210's kernel preparation), anything else (a Dummy prints as ``_name``) printed."""
    return symbol.name if type(symbol) is sp.Symbol else str(symbol)


@dataclass(frozen=True)
class PreparedOutput:
    name: str
    shape: tuple[int, ...]
    dtype: str
    entries: tuple[sp.Basic, ...]  # after CSE, row-major
    doc: str

    @property
    def size(self) -> int:
        size = 1
        for n in self.shape:
            size *= n
        return size


@dataclass(frozen=True)
class PreparedCheck:
    """A requirement as printed: the temporaries it needs, computed just before it, and its condition."""

    temporaries: tuple[tuple[str, sp.Basic], ...]
    condition: sp.Basic
    kind: str
    code: int
    message: str


@dataclass(frozen=True)
class PreparedFunction:
    name: str
    doc: str
    arguments: tuple[tuple[str, tuple[str, ...], str], ...]  # (name, symbol names, doc)
    params_used: tuple[str, ...]
    temporaries: tuple[tuple[str, sp.Basic], ...]
    outputs: tuple[PreparedOutput, ...]
    operations: int
    checks: tuple[PreparedCheck, ...] = ()  # in order, before ``temporaries``

    @property
    def arguments_used(self) -> frozenset[str]:
        used = set()
        for _, expr in self.temporaries + tuple(t for c in self.checks for t in c.temporaries):
            used |= {name_of(s) for s in expr.free_symbols}
        for check in self.checks:
            used |= {name_of(s) for s in check.condition.free_symbols}
        for out in self.outputs:
            for expr in out.entries:
                used |= {name_of(s) for s in getattr(expr, "free_symbols", ())}
        return frozenset(used)


def _kept_coefficient(expr: sp.Basic) -> bool:
    """A number times a sum kept as a product, which an evaluated Mul distributes."""
    return expr.is_Mul and len(expr.args) == 2 and expr.args[0].is_Number and expr.args[1].is_Add


@functools.lru_cache(maxsize=8192)
def canonical(expr: sp.Basic) -> sp.Basic:
    """``expr`` with every number times a sum rebuilt as SymPy builds it (distributed).

    SymPy's ``factor_terms`` keeps ``-(a + b)/10`` as the product ``Mul(-1/10, a + b)``,
    which no evaluated Mul is; ``sympy.cse`` then took terms of such products for each
    other's: a planar 2R with a pose task and its tool across the last link got a
    joint_acceleration off by 0.13 rad/s^2 in both backends, and the verification, which
    evaluates through ``cse`` too, agreed with it.  An unpickled model is rebuilt on
    loading, which is why the same description generated right from the cache and wrong
    when derived afresh (found by tests/test_random_descriptions.py).
    """
    memo: dict = {}

    def visit(e):  # over the distinct subexpressions only: a rate kernel unfolds to 10^5 nodes
        if not e.args:
            return e
        done = memo.get(e)
        if done is None:
            args = tuple(visit(a) for a in e.args)
            if _kept_coefficient(e):
                done = sp.Mul(*args)
            else:
                done = e if all(a is b for a, b in zip(args, e.args)) else e.func(*args)
            memo[e] = done
        return done
    return visit(expr)


_PI_AS_FLOAT = sp.Float(sp.pi.evalf(40), 40)


def _fold(expr: sp.Basic, leaf, combine):
    """A value of ``expr`` from its subexpressions', each distinct one visited once (SymPy's own walks
    go down every path through the subtrees an expression shares), children first, without recursion
    (under --memory-limit a deep stack may not grow): ``leaf(e)`` gives e's value, or None to look
    inside e, whose value is then ``combine(e, [its arguments' values])``."""
    memo: dict = {}
    todo = [(expr, False)]
    while todo:
        e, expanded = todo.pop()
        if e in memo:
            continue
        if expanded:
            memo[e] = combine(e, [memo[a] for a in e.args])
            continue
        value = leaf(e)
        if value is not None:
            memo[e] = value
        else:
            todo.append((e, True))
            todo.extend((a, False) for a in e.args if a not in memo)
    return memo[expr]


def _rebuilt(e: sp.Basic, args: list) -> sp.Basic:
    return e if all(a is b for a, b in zip(args, e.args)) else e.func(*args)


@functools.lru_cache(maxsize=8192)
def exact_floats(expr: sp.Basic) -> sp.Basic:
    """Fold exact constants (pi, rationals times pi) so they print as one double: what
    ``expr.xreplace({pi: Float(pi, 40)})`` gives, each distinct subexpression visited once.

    Remembered: the kernels of a robot share most of their entries (fk's are task's and
    frames' too).  SymPy's ``has`` and ``xreplace`` walk every path through the subtrees an
    expression shares (a rate kernel unfolds to 10^5 nodes): with them this was a quarter of a
    kernel's preparation (the papers' robots' render: 2.2 of 18 s of CPU)."""
    return _fold(expr, lambda e: _PI_AS_FLOAT if e is sp.pi else (e if not e.args else None), _rebuilt)


def free_symbols(expr: sp.Basic) -> set:
    """``expr.free_symbols``, each distinct subexpression visited once (SymPy's walks every path
    through shared subtrees again, and builds a set at every node: 4.3 of 18 s of CPU of the
    papers' robots' kernel preparation).  A node that binds symbols of its own (Derivative,
    Lambda, Subs: :func:`_free_symbols_are_the_arguments`) is asked its own."""
    return _fold(expr, lambda e: e.free_symbols if not e.args or not _free_symbols_are_the_arguments(type(e)) else None,
                 lambda e, values: set().union(*values))


# The largest integer every double holds exactly, and every integer below it.
EXACT_INTEGER_LIMIT = 2**53


def _beyond_double(number: sp.Rational) -> bool:
    return abs(number.p) > EXACT_INTEGER_LIMIT or number.q > EXACT_INTEGER_LIMIT


def _holds_beyond_double(expr: sp.Basic) -> bool:
    """Whether ``expr`` holds a rational beyond 2**53: each distinct subexpression visited once
    (``expr.atoms(Rational)`` walked every path through a program's shared steps: a second of
    Romeo's ik kernel), without recursion."""
    return _fold(expr, lambda e: bool(e.is_Rational and _beyond_double(e)) if not e.args else None,
                 lambda e, values: any(values))


@functools.lru_cache(maxsize=None)
def _free_symbols_are_the_arguments(kind: type) -> bool:
    """Whether ``kind`` keeps SymPy's free_symbols of a node that binds none (Basic's: the union of
    its arguments'), rather than its own (Symbol; Derivative, Lambda, Subs, which bind symbols).
    Read from the class's MRO: a function class's metaclass has a free_symbols of its own."""
    return next(k for k in kind.__mro__ if "free_symbols" in vars(k)) is sp.Basic


@functools.lru_cache(maxsize=8192)
def bounded_numbers(expr: sp.Basic) -> sp.Basic:
    """``expr`` with every constant that reads an integer or rational beyond 2**53 folded into one
    correctly rounded double.

    Exact arithmetic on the decimals a file writes can grow such numbers (a product of normalised
    15-digit axes, ``sqrt(3519564161475607455144369219509)`` in a KUKA KR 210's inverse); C has no
    integer constant for them, and a double cannot hold them exactly anyway.  The largest constant
    subexpression that holds one is evaluated at 30 digits and rounded once, so the printed double
    is the nearest to the exact value, not a rounding of a rounding.  A rational on its own already
    prints as its nearest double (1/10**18 as 1e-18) and stays as it is."""
    if not _holds_beyond_double(expr):
        return expr
    memo: dict = {}
    facts: dict = {}

    def fact(e):
        """(e has free symbols, e holds a rational beyond 2**53), each distinct node once: asking
        ``e.free_symbols`` and ``e.atoms`` of every node walked its whole subtree again (7 of the
        11 s of the PUMA's render)."""
        known = facts.get(e)
        if known is None:
            if not e.args:
                known = (bool(e.free_symbols), bool(e.is_Rational and _beyond_double(e)))
            else:
                parts = [fact(a) for a in e.args]
                free = any(p[0] for p in parts) if _free_symbols_are_the_arguments(type(e)) else bool(e.free_symbols)
                known = (free, any(p[1] for p in parts))
            facts[e] = known
        return known

    def visit(e):
        done = memo.get(e)
        if done is not None:
            return done
        if e.is_Rational and not e.is_Integer:
            done = e
        elif isinstance(e, sp.Expr) and fact(e) == (False, True):
            value = e.evalf(30)
            done = sp.Float(value, 30) if value.is_real and value.is_finite else e
        elif not e.args:
            done = e
        else:
            args = tuple(visit(a) for a in e.args)
            done = e if all(a is b for a, b in zip(args, e.args)) else e.func(*args)
        memo[e] = done
        return done
    return visit(expr)


def prepare(function: SymbolicFunction, param_names: tuple[str, ...]) -> PreparedFunction:
    """Flatten all outputs of ``function``, run one CSE over them, unflatten.

    The conditions of ``function.requires`` join the same CSE, so that a
    condition and the outputs read one temporary for a shared subexpression;
    each condition is then printed after the temporaries it needs (and before
    the rest), so nothing that could fail is computed before its check.
    """
    flat: list[sp.Basic] = []
    for out in function.outputs:
        flat.extend(out.values)
    flat.extend(r.condition for r in function.requires)
    flat = [bounded_numbers(exact_floats(canonical(sp.sympify(e)))) for e in flat]
    definitions = function.definitions
    flat = [bounded_numbers(exact_floats(canonical(sp.sympify(e)))) for _, e in definitions] + flat
    symbols = sp.numbered_symbols(TEMPORARY_PREFIX, real=True)
    # order="none": the temporaries in the order CSE finds them.  "canonical" sorts the
    # expressions by node count first, which was most of the time for the big rate
    # kernels (an IRB 140's joint_acceleration: 3.0 s against 0.22 s, the same 233
    # temporaries); the text is as deterministic (the same across hash seeds, tested).
    if len(flat) < TREE_CSE_ONLY and function.cse != "tree":
        replacements, reduced = sp.cse(flat, symbols=symbols, order="none")
    else:  # a long program, or one through and through (SymbolicFunction.cse): repeated subtrees only
        replacements, reduced = tree_cse(flat, symbols, {}, "none", ())
    if definitions:
        replacements = _program_order(replacements, [(s, e) for (s, _), e in zip(definitions, reduced)],
                                      reduced[len(definitions):])
        reduced = reduced[len(definitions):]
    conditions = reduced[len(reduced) - len(function.requires):]
    reduced = reduced[:len(reduced) - len(function.requires)]
    checks, replacements = _stage_checks(function, replacements, conditions)
    outputs = []
    start = 0
    for out in function.outputs:
        entries = tuple(reduced[start:start + len(out.values)])
        start += len(out.values)
        outputs.append(PreparedOutput(out.name, out.shape, out.dtype, entries, out.doc))
    free = {name_of(s) for s in free_symbols(sp.Tuple(*flat))} if flat else set()
    params_used = tuple(p for p in param_names if p in free)
    operations = sum(operation_count(e) for _, e in replacements) + sum(operation_count(e) for e in reduced)
    operations += sum(operation_count(e) for c in checks for _, e in c.temporaries)
    operations += sum(operation_count(c.condition) for c in checks)
    arguments = tuple((a.name, tuple(name_of(s) for s in a.symbols), a.doc) for a in function.arguments)
    return PreparedFunction(function.name, function.doc, arguments, params_used,
                            tuple((name_of(s), e) for s, e in replacements), tuple(outputs), int(operations),
                            tuple(checks))


def _program_order(temporaries, definitions, results):
    """The CSE temporaries and a function's own definitions that the results need, as one
    sequence in which every symbol is defined before its first use (each preceded by what it
    reads, earlier definitions and temporaries first)."""
    body = dict(temporaries)
    body.update(definitions)
    rank = {s: i for i, (s, _) in enumerate(list(definitions) + list(temporaries))}
    done: set = set()
    program = []

    def emit(root):
        stack = [(root, False)]
        while stack:
            symbol, expanded = stack.pop()
            if symbol in done:
                continue
            if expanded:
                done.add(symbol)
                program.append((symbol, body[symbol]))
                continue
            stack.append((symbol, True))
            needs = sorted((d for d in body[symbol].free_symbols if d in body and d not in done),
                           key=rank.__getitem__, reverse=True)
            stack.extend((d, False) for d in needs)

    for result in results:  # a definition no result needs is left out (-Werror=unused-variable)
        for symbol in sorted((d for d in sp.sympify(result).free_symbols if d in body), key=rank.__getitem__):
            emit(symbol)
    return program


def _stage_checks(function: SymbolicFunction, replacements, conditions):
    """Split the CSE temporaries: those each check needs (in order), then the rest."""
    if not function.requires:
        return [], replacements
    definitions = dict(replacements)
    emitted: set[sp.Symbol] = set()
    checks = []
    for requirement, condition in zip(function.requires, conditions):
        needed: set[sp.Symbol] = set()
        pending = [s for s in condition.free_symbols if s in definitions]
        while pending:
            symbol = pending.pop()
            if symbol not in needed and symbol not in emitted:
                needed.add(symbol)
                pending.extend(s for s in definitions[symbol].free_symbols if s in definitions)
        stage = tuple((name_of(s), e) for s, e in replacements if s in needed)  # CSE order is a topological order
        emitted |= needed
        checks.append(PreparedCheck(stage, condition, requirement.kind, STATUS_CODES[requirement.kind],
                                    requirement.message))
    return checks, [(s, e) for s, e in replacements if s not in emitted]

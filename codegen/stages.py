"""Laying out a prepared kernel in stages that a compiler can vectorise.

A batched kernel is fast when its loops vectorise, and the sines and cosines
are most of its cost: one scalar ``sin``/``cos`` pair costs about as much as a
hundred multiplications, while glibc's vector math library (libmvec) computes
four or eight of them at once for a fraction of that.  GCC calls the vector
versions only from a loop that holds nothing it cannot vectorise, and it fuses
``sin(x)`` and ``cos(x)`` of the same angle into a ``sincos`` call, which it
does not vectorise.  So :func:`stage` rewrites the CSE output of a kernel:

* every distinct ``sin(a)`` and ``cos(a)`` becomes a variable (``_s0``, ``_c0``;
  the same angle ``a`` shares one index), computed in a loop of its own;
* a compound angle (``q2 + q3``) becomes a variable ``_a0`` of its own;
* what depends on the parameters only goes to a prologue, computed once per call;
* the rest is arithmetic (and ``sqrt``, ``atan2`` ... which vectorise in place),
  split into stages: stage k computes what needs the sines and cosines of
  stages before it, then the angles of stage k go through their sine and cosine
  loops.  Forward kinematics and Jacobians need one stage of angles and one of
  arithmetic; a chain of angles that depend on earlier sines (inverse
  kinematics) needs more.

The single-point entry point is printed from the same rewritten expressions, so
the batched and single-point results are bit-identical in a plain C99 build.
A value lives in a per-block array (``double name[BLOCK]``) when a later loop
reads it; otherwise it is a local of the loop that computes it.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .kernels import PreparedFunction, name_of

__all__ = ["Call", "Stage", "StagedFunction", "stage"]

TRIG = {sp.sin: "sin", sp.cos: "cos"}
# Other functions with vector versions in libmvec (glibc 2.35 on), taken out of the arithmetic
# the same way, so that the single point can call them for a stage's arguments at once.
CALLS = {sp.atan2: "atan2", sp.acos: "acos", sp.asin: "asin"}
ANGLE_PREFIX, SIN_PREFIX, COS_PREFIX, CALL_PREFIX = "_a", "_s", "_c", "_f"


@dataclass(frozen=True)
class Call:
    """``name = function(*arguments)`` for every item of a block, in a loop of its own."""

    name: str
    function: str
    arguments: tuple[str, ...]

    @property
    def argument(self) -> str:
        return self.arguments[0]


@dataclass(frozen=True)
class Stage:
    """One loop of arithmetic (``body``), then the loops of its calls (sin, cos, atan2 ...)."""

    body: tuple[tuple[str, sp.Basic], ...]
    calls: tuple[Call, ...]


@dataclass(frozen=True)
class StagedFunction:
    prologue: tuple[tuple[str, sp.Basic], ...]  # what depends on the parameters only: once per call
    stages: tuple[Stage, ...]  # the outputs are computed in the body loop of the last stage
    outputs: tuple[tuple[sp.Basic, ...], ...]  # per output, its entries (row-major)
    arrays: frozenset[str]  # names that need a per-block array (read by a later loop)


class _Rewriter:
    """Replaces each sin/cos and each call of CALLS by a variable, naming compound arguments."""

    def __init__(self):
        self.named: dict[sp.Basic, sp.Symbol] = {}  # compound argument -> _aK
        self.angles: list[sp.Symbol] = []  # the angle of each sin/cos index
        self.angle_index: dict[sp.Symbol, int] = {}
        self.calls: dict[tuple, Call] = {}  # (function, argument names) -> call
        self.temporaries: list[tuple[str, sp.Basic]] = []

    def _name(self, argument):
        if isinstance(argument, sp.Symbol):
            return argument
        if argument not in self.named:
            symbol = sp.Symbol(f"{ANGLE_PREFIX}{len(self.named)}", real=True)
            self.named[argument] = symbol
            self.temporaries.append((symbol.name, argument))
        return self.named[argument]

    def __call__(self, expr):
        if expr.is_Atom:
            return expr
        args = tuple(self(a) for a in expr.args)
        if expr.func in TRIG:
            angle = self._name(args[0])
            if angle not in self.angle_index:
                self.angle_index[angle] = len(self.angles)
                self.angles.append(angle)
            prefix = SIN_PREFIX if expr.func is sp.sin else COS_PREFIX
            return sp.Symbol(f"{prefix}{self.angle_index[angle]}", real=True)
        if expr.func in CALLS:
            names = tuple(self._name(a).name for a in args)
            key = (CALLS[expr.func], names)
            if key not in self.calls:
                self.calls[key] = Call(f"{CALL_PREFIX}{len(self.calls)}", CALLS[expr.func], names)
            return sp.Symbol(self.calls[key].name, real=True)
        if args == expr.args:
            return expr
        return expr.func(*args)


def stage(prepared: PreparedFunction) -> StagedFunction:
    """The stages of ``prepared`` (see the module docstring)."""
    rewriter = _Rewriter()
    temporaries = rewriter.temporaries
    aliases: dict[sp.Symbol, sp.Symbol] = {}  # a temporary that was just sin(x) is now _s0

    def rewrite(expr):
        if aliases:
            expr = expr.xreplace(aliases) if not expr.is_Atom else aliases.get(expr, expr)
        return rewriter(expr)

    for name, expr in prepared.temporaries:
        rewritten = rewrite(expr)
        if isinstance(rewritten, sp.Symbol):
            aliases[sp.Symbol(name, real=True)] = rewritten
        else:
            temporaries.append((name, rewritten))
    outputs = tuple(tuple(rewrite(e) for e in out.entries) for out in prepared.outputs)

    used: set[str] = set()
    for _, expr in temporaries:
        used |= {name_of(s) for s in getattr(expr, "free_symbols", ())}
    for entries in outputs:
        for expr in entries:
            used |= {name_of(s) for s in getattr(expr, "free_symbols", ())}
    calls = []
    for index, angle in enumerate(rewriter.angles):
        for prefix, function in ((SIN_PREFIX, "sin"), (COS_PREFIX, "cos")):
            if f"{prefix}{index}" in used:
                calls.append(Call(f"{prefix}{index}", function, (angle.name,)))
    calls += [c for c in rewriter.calls.values() if c.name in used]

    # What does not depend on the inputs (parameters only) is computed once, before any loop.
    inputs = {name for argument in prepared.arguments for name in argument[1]}
    # The temporaries of the requirement checks are computed before the stages (and the checks
    # of a failing item stop before them): what reads one varies from item to item.
    inputs |= {name for check in prepared.checks for name, _ in check.temporaries}
    call_of = {c.name: c for c in calls}
    variable = set(inputs)

    def varies(name: str) -> bool:
        if name in call_of:  # a call's argument may be another call's result (sin of an atan2)
            return any(varies(a) for a in call_of[name].arguments)
        return name in variable

    for name, expr in temporaries:
        if any(varies(name_of(s)) for s in getattr(expr, "free_symbols", ())):
            variable.add(name)
    prologue: list[tuple[str, sp.Basic]] = []
    emitted: set[str] = set()

    def emit_calls(expr):
        for s in sorted(getattr(expr, "free_symbols", ()), key=str):
            name = name_of(s)
            if name in call_of and name not in emitted and not varies(name):
                call = call_of[name]
                function = {"sin": sp.sin, "cos": sp.cos, **{v: k for k, v in CALLS.items()}}[call.function]
                prologue.append((name, function(*(sp.Symbol(a, real=True) for a in call.arguments))))
                emitted.add(name)

    for name, expr in temporaries:
        if name not in variable:
            emit_calls(expr)
            prologue.append((name, expr))
            emitted.add(name)
    for expr in [e for _, e in temporaries] + [e for entries in outputs for e in entries]:
        emit_calls(expr)
    temporaries = [(n, e) for n, e in temporaries if n in variable]
    calls = [c for c in calls if varies(c.name)]

    # Level: how many sine/cosine loops a value waits for.  Temporaries are in
    # dependency order, and the angle of a call is defined before the call is read.
    call_of = {c.name: c for c in calls}
    level: dict[str, int] = {}

    def call_level(call: Call) -> int:
        return max(call_level(call_of[a]) if a in call_of else level.get(a, 0) for a in call.arguments) + 1

    def level_of(expr) -> int:
        result = 0
        for s in getattr(expr, "free_symbols", ()):
            name = name_of(s)
            result = max(result, call_level(call_of[name]) if name in call_of else level.get(name, 0))
        return result

    pending = dict(temporaries)
    for name, expr in temporaries:
        level[name] = level_of(expr)
    for c in calls:
        level[c.name] = call_level(c)
    last = max((level[c.name] for c in calls), default=0)
    for entries in outputs:
        for expr in entries:
            last = max(last, level_of(expr))

    # Each temporary goes to the earliest stage that reads it (never before its level).
    reads: dict[str, set[int]] = {name: set() for name in pending}
    stage_of: dict[str, int] = {}
    call_reads: set[str] = {a for c in calls for a in c.arguments}
    for entries in outputs:
        for expr in entries:
            for s in getattr(expr, "free_symbols", ()):
                if name_of(s) in reads:
                    reads[name_of(s)].add(last)
    for c in calls:
        for a in c.arguments:
            if a in reads:
                reads[a].add(level[c.name] - 1)
    for name, expr in reversed(temporaries):
        stage_of[name] = min(reads[name], default=last)
        for s in getattr(expr, "free_symbols", ()):
            if name_of(s) in reads:
                reads[name_of(s)].add(stage_of[name])

    arrays = set(call_of) | {a for a in call_reads if varies(a)}  # a constant argument is a scalar of the prologue
    for name in pending:
        if any(r != stage_of[name] for r in reads[name]):
            arrays.add(name)

    stages = []
    for k in range(last + 1):
        body = tuple((n, e) for n, e in temporaries if stage_of[n] == k)
        stage_calls = tuple(c for c in calls if level[c.name] == k + 1)
        stages.append(Stage(body, stage_calls))
    return StagedFunction(tuple(prologue), tuple(stages), outputs, frozenset(arrays))

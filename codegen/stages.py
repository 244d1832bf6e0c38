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

from .kernels import PreparedFunction

__all__ = ["Call", "Stage", "StagedFunction", "stage"]

TRIG = {sp.sin: "sin", sp.cos: "cos"}
ANGLE_PREFIX, SIN_PREFIX, COS_PREFIX = "_a", "_s", "_c"


@dataclass(frozen=True)
class Call:
    """``name = function(argument)`` for every item of a block, in a loop of its own."""

    name: str
    function: str
    argument: str


@dataclass(frozen=True)
class Stage:
    """One loop of arithmetic (``body``), then the sine and cosine loops of its angles."""

    body: tuple[tuple[str, sp.Basic], ...]
    calls: tuple[Call, ...]


@dataclass(frozen=True)
class StagedFunction:
    stages: tuple[Stage, ...]  # the outputs are computed in the body loop of the last stage
    outputs: tuple[tuple[sp.Basic, ...], ...]  # per output, its entries (row-major)
    arrays: frozenset[str]  # names that need a per-block array (read by a later loop)


def _rewrite(expr, angles: dict, order: list, temporaries: list, counter: list):
    """``expr`` with each sin/cos replaced by its variable (new angles appended)."""
    if expr.is_Atom:
        return expr
    args = tuple(_rewrite(a, angles, order, temporaries, counter) for a in expr.args)
    if expr.func in TRIG:
        (angle,) = args
        if not isinstance(angle, sp.Symbol):
            key = ("expr", angle)
            if key not in angles:
                name = f"{ANGLE_PREFIX}{counter[0]}"
                counter[0] += 1
                angles[key] = sp.Symbol(name, real=True)
                temporaries.append((name, angle))
            angle = angles[key]
        index = angles.setdefault(("index", angle), len(order))
        if index == len(order):
            order.append(angle)
        prefix = SIN_PREFIX if expr.func is sp.sin else COS_PREFIX
        return sp.Symbol(f"{prefix}{index}", real=True)
    if args == expr.args:
        return expr
    return expr.func(*args)


def stage(prepared: PreparedFunction) -> StagedFunction:
    """The stages of ``prepared`` (see the module docstring)."""
    angles: dict = {}
    order: list[sp.Symbol] = []  # angle variable of each sin/cos index
    counter = [0]
    temporaries: list[tuple[str, sp.Basic]] = []
    aliases: dict[sp.Symbol, sp.Symbol] = {}  # a temporary that was just sin(x) is now _s0

    def rewrite(expr):
        expr = _rewrite(expr, angles, order, temporaries, counter)
        return expr.xreplace(aliases) if aliases and not expr.is_Atom else aliases.get(expr, expr)

    for name, expr in prepared.temporaries:
        rewritten = rewrite(expr)
        if isinstance(rewritten, sp.Symbol):
            aliases[sp.Symbol(name, real=True)] = rewritten
        else:
            temporaries.append((name, rewritten))
    outputs = tuple(tuple(rewrite(e) for e in out.entries) for out in prepared.outputs)

    used_trig: set[str] = set()
    for _, expr in temporaries:
        used_trig |= {str(s) for s in getattr(expr, "free_symbols", ())}
    for entries in outputs:
        for expr in entries:
            used_trig |= {str(s) for s in getattr(expr, "free_symbols", ())}
    calls = []
    for index, angle in enumerate(order):
        for prefix, function in ((SIN_PREFIX, "sin"), (COS_PREFIX, "cos")):
            if f"{prefix}{index}" in used_trig:
                calls.append(Call(f"{prefix}{index}", function, str(angle)))

    # Level: how many sine/cosine loops a value waits for.  Temporaries are in
    # dependency order, and the angle of a call is defined before the call is read.
    call_of = {c.name: c for c in calls}
    level: dict[str, int] = {}

    def level_of(expr) -> int:
        result = 0
        for s in getattr(expr, "free_symbols", ()):
            name = str(s)
            if name in call_of:
                result = max(result, level.get(call_of[name].argument, 0) + 1)
            else:
                result = max(result, level.get(name, 0))
        return result

    pending = dict(temporaries)
    for name, expr in temporaries:
        level[name] = level_of(expr)
    for c in calls:
        level[c.name] = level.get(c.argument, 0) + 1
    last = max((level[c.name] for c in calls), default=0)
    for entries in outputs:
        for expr in entries:
            last = max(last, level_of(expr))

    # Each temporary goes to the earliest stage that reads it (never before its level).
    reads: dict[str, set[int]] = {name: set() for name in pending}
    stage_of: dict[str, int] = {}
    call_reads: set[str] = {c.argument for c in calls}
    for entries in outputs:
        for expr in entries:
            for s in getattr(expr, "free_symbols", ()):
                if str(s) in reads:
                    reads[str(s)].add(last)
    for c in calls:
        if c.argument in reads:
            reads[c.argument].add(level[c.argument])
    for name, expr in reversed(temporaries):
        stage_of[name] = min(reads[name], default=last)
        for s in getattr(expr, "free_symbols", ()):
            if str(s) in reads:
                reads[str(s)].add(stage_of[name])

    arrays = set(call_of) | call_reads
    for name in pending:
        if any(r != stage_of[name] for r in reads[name]):
            arrays.add(name)

    stages = []
    for k in range(last + 1):
        body = tuple((n, e) for n, e in temporaries if stage_of[n] == k)
        stage_calls = tuple(c for c in calls if level[c.name] == k + 1)
        stages.append(Stage(body, stage_calls))
    return StagedFunction(tuple(stages), outputs, frozenset(arrays))

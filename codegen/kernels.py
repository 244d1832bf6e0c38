"""Preparing a symbolic function for printing: one CSE pass over all its outputs.

Every backend prints the same :class:`PreparedFunction`: the arguments it
unpacks, the parameters it reads, the temporaries of a single common
subexpression elimination run over all outputs together (so a sine shared by
the pose and the Jacobian is computed once), and each output entry.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from derivations.model import SymbolicFunction

__all__ = ["PreparedFunction", "PreparedOutput", "prepare", "exact_floats"]

TEMPORARY_PREFIX = "_t"


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
class PreparedFunction:
    name: str
    doc: str
    arguments: tuple[tuple[str, tuple[str, ...], str], ...]  # (name, symbol names, doc)
    params_used: tuple[str, ...]
    temporaries: tuple[tuple[str, sp.Basic], ...]
    outputs: tuple[PreparedOutput, ...]
    operations: int

    @property
    def arguments_used(self) -> frozenset[str]:
        used = set()
        for _, expr in self.temporaries:
            used |= {str(s) for s in expr.free_symbols}
        for out in self.outputs:
            for expr in out.entries:
                used |= {str(s) for s in getattr(expr, "free_symbols", ())}
        return frozenset(used)


def exact_floats(expr: sp.Basic) -> sp.Basic:
    """Fold exact constants (pi, rationals times pi) so they print as one double."""
    return expr.xreplace({sp.pi: sp.Float(sp.pi.evalf(40), 40)}) if expr.has(sp.pi) else expr


def prepare(function: SymbolicFunction, param_names: tuple[str, ...]) -> PreparedFunction:
    """Flatten all outputs of ``function``, run one CSE over them, unflatten."""
    flat: list[sp.Basic] = []
    for out in function.outputs:
        flat.extend(out.values)
    flat = [exact_floats(sp.sympify(e)) for e in flat]
    symbols = sp.numbered_symbols(TEMPORARY_PREFIX, real=True)
    replacements, reduced = sp.cse(flat, symbols=symbols, order="canonical")
    outputs = []
    start = 0
    for out in function.outputs:
        entries = tuple(reduced[start:start + len(out.values)])
        start += len(out.values)
        outputs.append(PreparedOutput(out.name, out.shape, out.dtype, entries, out.doc))
    free = set()
    for e in flat:
        free |= {str(s) for s in e.free_symbols}
    params_used = tuple(p for p in param_names if p in free)
    operations = sum(sp.count_ops(e) for _, e in replacements) + sum(sp.count_ops(e) for e in reduced)
    arguments = tuple((a.name, tuple(str(s) for s in a.symbols), a.doc) for a in function.arguments)
    return PreparedFunction(function.name, function.doc, arguments, params_used,
                            tuple((str(s), e) for s, e in replacements), tuple(outputs), int(operations))

"""Pickles of SymPy expressions that load without evaluating them again.

SymPy pickles an expression as its class and arguments, and loading calls the class on them:
every sum and product is flattened, sorted and combined once more, every power and function
evaluated, although what was pickled was already in that form.  That made loading a result
several times as costly as deriving parts of it: the KUKA KR 210's equations of motion took
0.30 s to load from their 224 kB pickle, and the kernels that worker processes prepare took
1.4 s to load in the parent of a `kinegen generate` (2026-11-26).

:func:`dumps` writes sums and products as ``cls._from_args(args)`` and powers and function
applications as ``cls(*args, evaluate=False)``: the same objects (the same classes with the same
arguments, equal and of equal hash), built without evaluation, in a quarter of the time (the
KR 210's equations: 0.30 -> 0.08 s); relations too (``Lt(a, b)`` asks the assumptions of ``a - b``
when built: 70 of them took most of the 0.6 s a KR 210's model took to load), and the pairs of a
``Piecewise`` are built from their two arguments as they are.  Anything else pickles as before.  ``pickle.loads`` reads them.

Only the derivation cache (signed, :mod:`derivations.support.cache`) and the pipes between
`kinegen`'s own processes carry these pickles; loading one runs the two functions below, as
loading any pickle runs what its bytes name.
"""
from __future__ import annotations

import io
import pickle

import sympy as sp
from sympy.core.function import AppliedUndef, Application
from sympy.core.relational import Relational
from sympy.functions.elementary.piecewise import ExprCondPair

__all__ = ["dumps"]


def _assoc(cls, args):
    """A sum or product of ``args``, in the order given (:func:`dumps`)."""
    return cls._from_args(args)


def _built(cls, args):
    """``cls`` of ``args`` as they are, no constructor of its own run (:func:`dumps`)."""
    return sp.Basic.__new__(cls, *args)


def _unevaluated(cls, args):
    """``cls(*args)`` without evaluation (:func:`dumps`); evaluated where the class takes no
    ``evaluate`` (as SymPy's own pickles are)."""
    try:
        return cls(*args, evaluate=False)
    except TypeError:
        return cls(*args)


class _Pickler(pickle.Pickler):
    def reducer_override(self, obj):
        cls = type(obj)
        if cls is sp.Add or cls is sp.Mul:
            return _assoc, (cls, obj.args)
        if cls.__reduce_ex__ is not _BASIC_REDUCE:  # a class that pickles in its own way
            return NotImplemented
        if cls is sp.Pow or isinstance(obj, Relational) or (isinstance(obj, Application)
                                                            and not isinstance(obj, AppliedUndef)):
            return _unevaluated, (cls, obj.args)
        if cls is ExprCondPair:  # (its constructor folds a condition that holds a Piecewise)
            return _built, (cls, obj.args)
        return NotImplemented


_BASIC_REDUCE = sp.Basic.__reduce_ex__


def dumps(value) -> bytes:
    """``pickle.dumps(value)`` at the highest protocol, SymPy's sums, products, powers and
    functions written to load as they are (the module's notes)."""
    buffer = io.BytesIO()
    _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(value)
    return buffer.getvalue()

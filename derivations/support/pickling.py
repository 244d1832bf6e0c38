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
KR 210's equations: 0.30 -> 0.08 s).  Anything else pickles as before.  ``pickle.loads`` reads them.

Only the derivation cache (signed, :mod:`derivations.support.cache`) and the pipes between
`kinegen`'s own processes carry these pickles; loading one runs the two functions below, as
loading any pickle runs what its bytes name.
"""
from __future__ import annotations

import io
import pickle

import sympy as sp
from sympy.core.function import AppliedUndef, Application

__all__ = ["dumps"]


def _assoc(cls, args):
    """A sum or product of ``args``, in the order given (:func:`dumps`)."""
    return cls._from_args(args)


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
        if ((cls is sp.Pow or (isinstance(obj, Application) and not isinstance(obj, AppliedUndef)))
                and cls.__reduce_ex__ is _BASIC_REDUCE):  # not a class that pickles in its own way
            return _unevaluated, (cls, obj.args)
        return NotImplemented


_BASIC_REDUCE = sp.Basic.__reduce_ex__


def dumps(value) -> bytes:
    """``pickle.dumps(value)`` at the highest protocol, SymPy's sums, products, powers and
    functions written to load as they are (the module's notes)."""
    buffer = io.BytesIO()
    _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(value)
    return buffer.getvalue()

"""Code-generation backends: one module per target language (printer + templates).

A backend is a SymPy printer subclass that overrides only what differs from
SymPy's own, and a ``render`` function that fills its jinja2 templates in
``templates/``.  Everything above the printer (CSE, the kernel list, file
writing) is shared in ``codegen.kernels`` and ``codegen.generate``.
"""
from __future__ import annotations

import contextlib
import functools
import importlib

import jinja2
import sympy as sp
from sympy.printing.precedence import PRECEDENCE, precedence

TEMPLATES = jinja2.Environment(
    loader=jinja2.PackageLoader("codegen.backends", "templates"),
    undefined=jinja2.StrictUndefined,
    keep_trailing_newline=True,
    trim_blocks=True,
    lstrip_blocks=True,
)


class _CompiledTemplates(jinja2.BytecodeCache):
    """Compiled templates kept in memory, by jinja's key for each (its name and file): what
    :func:`compile_templates` records, and what :func:`adopt_templates` hands to TEMPLATES.  jinja
    checks each against its template's source (a checksum) before it uses it."""

    def __init__(self, code=None):
        self.code = dict(code or {})

    def load_bytecode(self, bucket):
        if bucket.key in self.code:
            bucket.bytecode_from_string(self.code[bucket.key])

    def dump_bytecode(self, bucket):
        self.code[bucket.key] = bucket.bytecode_to_string()


def compile_templates() -> dict[str, bytes]:
    """Every template compiled (jinja's parse and Python's compile: 0.4-0.6 s, 2026-11-26), as
    jinja's bytecode: for a process forked while its parent derives an arm to hand over
    (:func:`adopt_templates`), so that the parent renders without compiling them."""
    recorded = _CompiledTemplates()
    environment = TEMPLATES.overlay(bytecode_cache=recorded, cache_size=0)
    for name in TEMPLATES.list_templates():
        environment.get_template(name)
    return recorded.code


def adopt_templates(code: dict[str, bytes]) -> None:
    """TEMPLATES takes each template's compiled code from ``code`` (:func:`compile_templates` of a
    process of ours) where it matches the template's source, and compiles the rest itself."""
    TEMPLATES.bytecode_cache = _CompiledTemplates(code)


def float_literal(value) -> str:
    """Shortest decimal that round-trips to the nearest double of ``value``."""
    text = repr(float(value))
    if text in ("inf", "-inf", "nan"):
        raise ValueError(f"cannot print the non-finite constant {value}")
    return text


# Integer powers up to this print as products (the manipulability thresholds need L**6).
MAX_PRODUCT_POWER = 8

@functools.lru_cache(maxsize=1 << 16)
def _terms_in_order(expr, order) -> tuple:
    """The terms of a sum in the order the printers print them, SymPy's own (``as_ordered_terms``),
    remembered for every printer of the process: it was a third of a kernel's printing, and the
    numpy, C and blocked-C printers order the same sums."""
    return tuple(expr.as_ordered_terms(order=order))


@functools.lru_cache(maxsize=1 << 17)
def _remembered_precedence(item):
    return precedence(item)


def _precedence(item):
    """SymPy's ``precedence``, remembered per expression: it is asked of a node by the node's own
    printing and by its parent's (``parenthesize``), by each printer, and for a product it negates
    the product to see whether a minus sign comes out (a third of a kernel's printing)."""
    try:
        return _remembered_precedence(item)
    except TypeError:  # not hashable
        return precedence(item)


# The SymPy printing modules that call ``precedence`` by their own name for it.
_PRECEDENCE_USERS = tuple(importlib.import_module(f"sympy.printing.{name}") for name in ("str", "codeprinter", "c", "pycode"))


@contextlib.contextmanager
def remembered_precedence():
    """Within: those modules' ``precedence`` is :func:`_precedence` (the same values); restored after."""
    saved = [module.precedence for module in _PRECEDENCE_USERS]
    for module in _PRECEDENCE_USERS:
        module.precedence = _precedence
    try:
        yield
    finally:
        for module, original in zip(_PRECEDENCE_USERS, saved):
            module.precedence = original


class ExactArithmeticMixin:
    """Printer methods shared by the numpy and C printers.

    Exact constants print as one correctly rounded double; small integer powers
    print as products (``x*x``), which is faster than ``pow`` and exact in the
    same way; ``x**(1/2)`` prints as ``sqrt`` and ``x**(k/2)`` as a product
    with one ``sqrt``.
    """

    _sqrt_name = "sqrt"

    def _as_ordered_terms(self, expr, order=None):
        order = order or self.order
        if order in ("old", "none"):  # orders of the printer itself (Printer._as_ordered_terms)
            return super()._as_ordered_terms(expr, order)
        return list(_terms_in_order(expr, order))

    def _handle_UnevaluatedExpr(self, expr):
        # SymPy's CodePrinter rewrites re(...) around UnevaluatedExpr with a replace over the whole
        # expression, a tenth of printing; a kernel's expressions hold no re(...) to rewrite.
        return super()._handle_UnevaluatedExpr(expr) if expr.has(sp.re) else expr

    def _print_Float(self, expr):
        return float_literal(expr)

    def _print_Rational(self, expr):
        return float_literal(expr)

    def _print_Integer(self, expr):
        # Beyond 2**53 (codegen.kernels.bounded_numbers folds every such constant before printing;
        # this is the last guard): a double literal, never an integer constant C cannot hold.
        return str(int(expr)) if abs(int(expr)) <= 2**53 else float_literal(expr)

    def _print_Pow(self, expr, rational=False):
        base, exponent = expr.base, expr.exp
        if exponent.is_Integer and 1 <= abs(int(exponent)) <= MAX_PRODUCT_POWER:
            k = abs(int(exponent))
            factor = self.parenthesize(base, PRECEDENCE["Mul"], strict=True)
            if k == 1:
                return factor if exponent > 0 else f"1.0/{factor}"
            # Parenthesised: the product must bind like a power inside y/x**2.
            product = "(" + "*".join([factor] * k) + ")"
            return product if exponent > 0 else f"1.0/{product}"
        if exponent == sp.S.Half:
            return f"{self._sqrt_name}({self._print(base)})"
        if exponent == -sp.S.Half:
            return f"1.0/{self._sqrt_name}({self._print(base)})"
        if exponent.is_Rational and exponent.q == 2 and abs(exponent.p) <= 7:
            # x**(k/2) = x*...*x*sqrt(x): derivatives of sqrt and acos give (1 - u**2)**(-3/2).
            factor = self.parenthesize(base, PRECEDENCE["Mul"], strict=True)
            whole = (abs(int(exponent.p)) - 1) // 2
            product = "(" + "*".join([factor] * whole + [f"{self._sqrt_name}({self._print(base)})"]) + ")"
            return product if exponent > 0 else f"1.0/{product}"
        if rational:
            return super()._print_Pow(expr, rational=rational)
        return super()._print_Pow(expr)

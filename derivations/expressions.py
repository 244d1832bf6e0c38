"""A small, safe parser for the expressions that robot descriptions may hold.

A DH entry or a parameter default in a description file may be a number, a
parameter name, ``pi``, or an arithmetic expression of those with ``+ - * / **``
and a few functions (``sin cos tan sqrt`` and ``deg(x) = x*pi/180``).  The text is
parsed with Python's ``ast`` module and converted node by node into SymPy; it is
never evaluated, so a description file cannot run code.

Decimal literals become exact rationals (``0.4318`` -> ``2159/5000``) so that the
symbolic side stays exact; the generated code prints them back as the same
decimal.
"""
from __future__ import annotations

import ast
import builtins
import keyword
import math
import sys
from pathlib import Path
from typing import Mapping

import sympy as sp

__all__ = ["ExpressionError", "parse_expression", "to_exact", "is_identifier"]


class ExpressionError(ValueError):
    """An expression in a robot description is malformed or uses a forbidden name."""


_FUNCTIONS = {
    "sin": sp.sin,
    "cos": sp.cos,
    "tan": sp.tan,
    "sqrt": sp.sqrt,
    "deg": lambda x: x * sp.pi / 180,
}
_BINARY = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: lambda a, b: a**b,
}

# Words that are valid Python identifiers but must not name a parameter: they
# would collide with the printed code (C keywords, numpy/C math names) or with
# the names the generated kernels use themselves.
RESERVED = frozenset(
    """
    auto break case char const continue default do double else enum extern float for goto
    if inline int long register restrict return short signed sizeof static struct switch
    typedef union unsigned void volatile while _Bool _Complex _Imaginary
    and as assert async await class def del elif except finally from global import in is
    lambda nonlocal not or pass raise try with yield None True False
    pi e E I oo nan inf sin cos tan sqrt deg atan2 acos asin exp log abs
    numpy np math out params count q qd qdd x xd xdd t valid
    y z phi r11 r12 r13 r21 r22 r23 r31 r32 r33
    twist singular manipulability Jx_dot J_dot w_tool Jw
    """.split()
) | frozenset(
    # What the generated C declares for itself: kernel outputs (a parameter named J
    # would be redeclared beside jacobian's output J) and the locals of the batch
    # loops, ik and ik_numeric (a parameter named k would be shadowed inside a block, silently).
    # tests/formats/test_description.py holds this list to what generated/*.c declares.
    """
    T J J_tool Jx Q frames angle argument0 argument1 sine cosine found i k n s inside refused result start stream turn
    valid_branches batch pointer status failed
    tau M g C c Y wrench
    q0 S v j item iteration step trial blocked converged solved cost cost_trial damping e_trial factor
    growth left norm predicted rho scale sign size size_trial
    """.split()
)


# Names the generated code's languages and libraries define: every Python keyword and builtin
# (a parameter named range or ValueError would shadow it in the numpy module), the C library
# names the templates use or C99 defines as macros, and the upper-case names of the generated
# modules and C (CHUNK, PARAMS, ...).  Any name starting with kinegen_ or KINEGEN_ is the
# templates' own (checked in is_identifier).
RESERVED = RESERVED | frozenset(keyword.kwlist) | frozenset(dir(builtins)) | frozenset(
    """
    NULL NAN INFINITY HUGE_VAL EOF EDOM ERANGE errno size_t ptrdiff_t uintptr_t intptr_t bool true false
    fabs floor ceil fmod fmax fmin hypot isfinite isnan isinf sinh cosh tanh log10 log2 exp2 pow cbrt
    round trunc signbit copysign assert stdin stdout stderr main
    CHUNK PARAMS JOINTS JOINT_TYPES TASK BRANCHES LIMITS SPACE_LIMITS OPERATIONS STATUS TWO_PI
    ffi lib np numpy sympy cffi
    """.split()
)


# Every macro the C headers of a generated package define (M_PI, INT_MAX, Py_None, NPY_MAXDIMS,
# isnan, errno, ...): a parameter named like one would be replaced by the preprocessor and break
# the compile.  The list is what codegen.build.header_macros reads off the compiler;
# tests/formats/test_description.py holds it to this machine's headers.
C_MACROS = frozenset(line for line in (Path(__file__).parent / "c_macros.txt").read_text().split()
                     if not line.startswith("#") and line.isidentifier())
RESERVED = RESERVED | C_MACROS


def is_identifier(name: str) -> bool:
    """True when ``name`` is safe as a C and Python identifier in generated code.

    ASCII letters, digits and underscores, not starting with a digit, at most 63
    characters, not a reserved word and not starting with an underscore (those
    names belong to the generated code).
    """
    return (
        isinstance(name, str)
        and 0 < len(name) <= 63
        and name.isascii()
        and name.isidentifier()
        and not name.startswith("_")
        and not name.lower().startswith("kinegen")
        and name not in RESERVED
    )


# A robot's name is the name of its generated package: one that shadows a module of Python's
# standard library (a robot named json or typing) would break any Python started beside it.
PROJECT_PACKAGES = frozenset({"derivations", "codegen", "generated", "tests", "benchmarks", "report", "docs"})
# A package folder holds <name>.h and is on the include path of its own C: a robot named after a
# header the C includes with <...> (stddef, stdint, ...) would be included in its place.
C_HEADERS = frozenset("""assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal stdalign
    stdarg stdatomic stdbool stddef stdint stdio stdlib stdnoreturn string tgmath threads time uchar wchar wctype
    emmintrin xmmintrin immintrin Python""".split())


def is_package_name(name: str) -> bool:
    """True when ``name`` can name a generated package: an identifier (:func:`is_identifier`) that
    is neither a standard-library module nor one of this project's packages."""
    return (is_identifier(name) and name not in sys.stdlib_module_names and name not in PROJECT_PACKAGES
            and name not in C_HEADERS)


def to_exact(value: float | int) -> sp.Expr:
    """A Python number as an exact SymPy number (floats through their shortest repr)."""
    if isinstance(value, bool):
        raise ExpressionError(f"expected a number, got the boolean {value!r}")
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ExpressionError(f"expected a finite number, got {value!r}")
        return sp.Rational(repr(value))
    raise ExpressionError(f"expected a number, got {type(value).__name__} {value!r}")


def parse_expression(text: str | int | float, names: Mapping[str, sp.Symbol]) -> sp.Expr:
    """Parse ``text`` into a SymPy expression over the symbols in ``names``.

    ``names`` maps each allowed parameter name to its symbol; ``pi`` is always
    allowed.  Raises :class:`ExpressionError` naming the offending piece.
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return to_exact(text)
    if not isinstance(text, str):
        raise ExpressionError(
            f"expected a number or an expression string, got {type(text).__name__} {text!r}"
        )
    if len(text) > 500:
        raise ExpressionError("expression longer than 500 characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError) as exc:
        raise ExpressionError(f"cannot parse {text!r}: {getattr(exc, 'msg', None) or type(exc).__name__}") from None
    nodes = list(ast.walk(tree.body))
    calls = sum(isinstance(n, ast.Call) for n in nodes)
    if len(nodes) > MAX_NODES or calls > MAX_CALLS or _depth(tree.body) > MAX_DEPTH:
        raise ExpressionError(f"in {text[:60]!r}: more than {MAX_NODES} terms, {MAX_CALLS} function calls "
                              f"or {MAX_DEPTH} levels of nesting (an expression a robot's dimension needs is shorter)")
    expr = _convert(tree.body, names, text)
    terms = _expanded_terms(expr)
    if terms > MAX_EXPANDED_TERMS:
        raise ExpressionError(f"in {text[:60]!r}: {terms if terms < 10**9 else 'more than 10^9'} terms once "
                              f"expanded, more than {MAX_EXPANDED_TERMS} (the derivation expands products of the "
                              "fields: a robot's dimension needs a short expression)")
    return expr


def _expanded_terms(expr: sp.Expr, cap: int = 10**9) -> int:
    """An upper bound on the terms of ``expr`` expanded (a sum of six lengths to the 64th power:
    C(69, 5) = 11 million), computed without expanding: sums add, products multiply, an integer
    power n of a sum of t terms has at most C(t + n - 1, n); a function's argument is bounded
    on its own.  Capped at ``cap``."""
    if expr.is_Atom:
        return 1
    if isinstance(expr, sp.Function):  # one term outside; its argument too long is too long all the same
        inner = max((_expanded_terms(a, cap) for a in expr.args), default=1)
        return inner if inner > MAX_EXPANDED_TERMS else 1
    parts = [_expanded_terms(a, cap) for a in expr.args]
    if expr.is_Add:
        return min(cap, sum(parts))
    if expr.is_Mul:
        return min(cap, math.prod(parts))
    if expr.is_Pow and expr.exp.is_Integer and expr.exp > 0:
        return min(cap, math.comb(parts[0] + int(expr.exp) - 1, int(expr.exp)))
    return min(cap, max(parts))


# The size of what a field may hold, checked before anything is evaluated (issue #17: 80 nested
# sin() calls, 10**10**10**10).  A power's exponent, where it is a number, is at most
# MAX_EXPONENT in size, and a numeric power at most 10^300 (a double's range) in magnitude.
MAX_NODES = 200
MAX_CALLS = 20
MAX_DEPTH = 24
MAX_EXPONENT = 64
# Terms of a field once expanded (_expanded_terms): the derivation multiplies and expands the
# fields of a chain's links, and a field of more terms than this makes that product run to its
# time budget; the zoo's longest field has 3.
MAX_EXPANDED_TERMS = 100


def _depth(node: ast.AST) -> int:
    children = list(ast.iter_child_nodes(node))
    return 1 + (max(_depth(c) for c in children) if children else 0)


def _power(base: sp.Expr, exponent: sp.Expr, text: str) -> sp.Expr:
    """``base ** exponent``, refused (before computing it) when it could not be a length or an angle."""
    if exponent.is_number:
        size = abs(complex(exponent.evalf(15)))
        if size > MAX_EXPONENT:
            raise ExpressionError(f"in {text[:60]!r}: an exponent of {float(size):.3g}, more than {MAX_EXPONENT}")
        if base.is_number:
            magnitude = abs(complex(base.evalf(15)))
            if magnitude == 0 and complex(exponent.evalf(15)).real < 0:
                raise ExpressionError(f"in {text[:60]!r}: zero to a negative power")
            if magnitude > 0 and abs(math.log10(magnitude)) * size > 300:
                raise ExpressionError(f"in {text[:60]!r}: a power beyond a double's range (10^300)")
    return base**exponent


def _convert(node: ast.AST, names: Mapping[str, sp.Symbol], text: str) -> sp.Expr:
    if isinstance(node, ast.Constant):
        if isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
            return to_exact(node.value)
        raise ExpressionError(f"in {text!r}: only numbers are allowed as literals, got {node.value!r}")
    if isinstance(node, ast.Name):
        if node.id == "pi":
            return sp.pi
        if node.id in names:
            return names[node.id]
        known = ", ".join(sorted(names)) or "none"
        raise ExpressionError(f"in {text!r}: unknown name {node.id!r} (parameters: {known}; also pi)")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        left = _convert(node.left, names, text)
        right = _convert(node.right, names, text)
        if isinstance(node.op, ast.Div) and right == 0:
            raise ExpressionError(f"in {text!r}: division by zero")
        if isinstance(node.op, ast.Pow):
            return _power(left, right, text)
        return _BINARY[type(node.op)](left, right)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
        operand = _convert(node.operand, names, text)
        return -operand if isinstance(node.op, ast.USub) else operand
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in _FUNCTIONS:
            allowed = ", ".join(sorted(_FUNCTIONS))
            raise ExpressionError(f"in {text!r}: only the functions {allowed} may be called")
        if node.keywords or len(node.args) != 1:
            raise ExpressionError(f"in {text!r}: {node.func.id}() takes exactly one argument")
        return _FUNCTIONS[node.func.id](_convert(node.args[0], names, text))
    raise ExpressionError(
        f"in {text!r}: {type(node).__name__} is not allowed "
        "(use numbers, parameter names, pi, + - * / ** and sin cos tan sqrt deg)"
    )

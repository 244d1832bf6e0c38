"""The C99 backend: a C99CodePrinter subclass, the header/source templates and a cffi binding."""
from __future__ import annotations

import collections
import re

import sympy as sp
from sympy.printing.c import C99CodePrinter

from derivations.model import ANGLE_TASKS

from . import TEMPLATES, ExactArithmeticMixin, remembered_precedence

__all__ = ["CKernelPrinter", "render", "prune_helpers", "general_6r_function", "c_parts", "STRICT_FLAGS",
           "EXTRA_WARNINGS"]

# What every generated C file must compile cleanly with (checked by `make build`).
STRICT_FLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic")
# And with these besides, under gcc and clang (checked by tests/generation/test_c_compilers.py, not by the
# build): no implicit conversion that may change a value or its sign, no shadowed name, no
# float silently promoted to double.
EXTRA_WARNINGS = ("-Wconversion", "-Wshadow", "-Wdouble-promotion")


# Scalar calls of these C library functions go to the file's own helper (robot.c.j2): kinegen_atan2 is
# within 2 ulps at half the time of glibc's correctly rounded atan2.  Vector calls (KINEGEN_SIMD) keep
# the C library's, which libmvec vectorises.
SCALAR_CALLS = {"atan2": "kinegen_atan2"}


class CKernelPrinter(ExactArithmeticMixin, C99CodePrinter):
    """Prints C99 expressions; constants as correctly rounded double literals."""

    def __init__(self, indexed=frozenset(), memo: dict | None = None):
        # No M_PI-style macros: they are POSIX, not C99 (pi is folded to a literal anyway).
        super().__init__({"math_macros": {}, "allow_unknown_functions": False})
        self._indexed = frozenset(indexed)
        self._memo = {} if memo is None else memo

    def doprint(self, expr, assign_to=None):
        """``C99CodePrinter.doprint``, remembered in the memo this printer shares with its
        :meth:`indexed` printers (keyed by the indexed names and the expression): the blocked
        layouts print each expression of a stage again (with and without streaming stores), a
        third of the C time, and a render's worker processes print ahead (generate.prepared_functions)."""
        if assign_to is not None:
            return super().doprint(expr, assign_to)
        key = (self._indexed, expr)
        text = self._memo.get(key)
        if text is None:
            with remembered_precedence():
                text = self._memo[key] = super().doprint(expr)
        return text

    def indexed(self, names) -> "CKernelPrinter":
        """A printer that reads the variables ``names`` as ``name[i]`` (per-block arrays)."""
        return CKernelPrinter(names, self._memo)

    def _print_Symbol(self, expr):
        text = super()._print_Symbol(expr)
        return f"{text}[i]" if expr.name in self._indexed else text

    def _nested(self, function, args):
        text = self._print(args[0])
        for other in args[1:]:
            text = f"{function}({text}, {self._print(other)})"
        return text

    def _print_Min(self, expr):
        # Not C99's fmin, which drops a NaN and is not vectorised without -ffinite-math-only.
        return self._nested("kinegen_min", expr.args)

    def _print_Max(self, expr):
        return self._nested("kinegen_max", expr.args)

    def _print_ClampUnit(self, expr):
        return f"kinegen_snap_unit({self._print(expr.args[0])})"

    def _print_Ramp(self, expr):
        return self._print(expr.as_min_max())

    def _print_atan2(self, expr):
        return f"{SCALAR_CALLS['atan2']}({self._print(expr.args[0])}, {self._print(expr.args[1])})"

    def _print_WrapAngle(self, expr):
        return f"kinegen_wrap_angle({self._print(expr.args[0])})"

    def _print_BooleanTrue(self, expr):
        return "1"

    def _print_BooleanFalse(self, expr):
        return "0"


def prototypes(context: dict, suffix: str = "") -> list[str]:
    """The declaration of each kernel's single and batched entry point."""
    name = context["name"]
    lines = []
    for f in context["functions"]:
        inputs = "".join(f"const double *{a[0]}, " for a in f["arguments"])
        outputs = "".join(f", {'double' if o['dtype'] == 'float' else 'int'} *{o['name']}" for o in f["outputs"])
        sizes = ", ".join(f"{a[0]}[{len(a[1])}]" for a in f["arguments"])
        out_sizes = ", ".join(f"{o['name']}[{o['size']}]" for o in f["outputs"])
        lines.append(f"/* {f['name']}: {sizes} -> {out_sizes} (row-major). {f['doc']} */")
        if f["checks"]:  # returns a status code; the batch counts failures and may record each item's status
            lines.append(f"int {name}_{f['name']}({inputs}const {name}_params *params{outputs});")
            lines.append(f"size_t {name}_{f['name']}_batch(size_t count, {inputs}const {name}_params *params{outputs}, "
                         "int *status);")
            continue
        if f["is_ik"]:
            refused = ", or -1 when x is not a rigid transform" if context["pose_task"] else ""
            lines.append(f"/* Returns the number of valid branches{refused}; the batch returns their total "
                         f"(-1 if any item was refused). */")
        single, batch = ("int", "long") if f["is_ik"] else ("void", "void")
        lines.append(f"{single} {name}_{f['name']}({inputs}const {name}_params *params{outputs});")
        lines.append(f"{batch} {name}_{f['name']}_batch(size_t count, {inputs}const {name}_params *params{outputs});")
    n = len(context["joints"])
    if not n:  # a kernel set has no joints to check
        return lines
    numeric = context.get("numeric_ik")
    if numeric:
        m, x_name = len(context["task"]), "x"
        refused = ", -1 when x is a finite pose that is not a rigid transform" if context["pose_task"] else ""
        lines.append(f"/* ik_numeric: x[{m}], q0[{n}] -> q[{n}], converged[1] (row-major). Inverse kinematics by "
                     f"Levenberg-Marquardt (damped least squares) from the seed q0, each joint kept within its "
                     f"limits: converged where the largest residual ({numeric['residual']}) is at most "
                     f"{name.upper()}_IK_NUMERIC_TOLERANCE after at most {name.upper()}_IK_NUMERIC_ITERATIONS steps. "
                     f"Returns converged[0] (1 or 0){refused}; the batch returns how many items converged"
                     f"{' (-1 if it refused any)' if context['pose_task'] else ''}. */")
        lines.append(f"int {name}_ik_numeric(const double *{x_name}, const double *q0, const {name}_params *params, "
                     "double *q, int *converged);")
        lines.append(f"long {name}_ik_numeric_batch(size_t count, const double *{x_name}, const double *q0, "
                     f"const {name}_params *params, double *q, int *converged);")
    lines.append(f"/* within_limits: q[{n}] -> 1 when every joint lies within its limits "
                 "(revolute joints modulo 2 pi), else 0. */")
    lines.append(f"int {name}_within_limits(const double *q);")
    lines.append(f"void {name}_within_limits_batch(size_t count, const double *q, int *inside);")
    return lines


def checked_prototypes(context: dict) -> list[str]:
    """The cffi module's own entry points (build_c.py.j2): a kernel of ``count`` items, inputs checked."""
    name = context["name"]
    lines = []
    for f in context["functions"]:
        inputs = "".join(f"const double *{a[0]}, " for a in f["arguments"])
        outputs = "".join(f", {'double' if o['dtype'] == 'float' else 'int'} *{o['name']}" for o in f["outputs"])
        status = ", int *status" if f["checks"] else ""  # each item's requirement status code
        lines.append(f"int {name}_{f['name']}_checked(size_t count, {inputs}const {name}_params *params{outputs}{status})")
    return lines


def declarations(context: dict, for_cffi: bool) -> str:
    name = context["name"]
    fields = " ".join(f"double {p[0]};" for p in context["params"]) or "double unused;"
    lines = [f"/* Robot parameters (SI units). */", f"typedef struct {name}_params {{ {fields} }} {name}_params;"]
    if not for_cffi:
        lines.append(f"extern const {name}_params {name}_default_params;")
    elif context["status_codes"]:  # the header's status codes, for callers through cffi
        lines.extend(f"#define {name.upper()}_{kind.upper()} {code}" for kind, code in context["status_codes"])
    lines.append("")
    lines.extend(prototypes(context))
    if for_cffi:
        lines.extend(f"{p};" for p in checked_prototypes(context))
    return "\n".join(lines)


_HELPER = re.compile(r"^@@helper (?P<name>\w+)@@\n(?P<body>.*?)^@@end@@\n", re.S | re.M)


_UNIT = re.compile(r"^#if !defined\(KINEGEN_PART\) \|\| KINEGEN_PART == (?P<part>\d+)$", re.M)
_WORD = re.compile(r"\w+")


def prune_helpers(text: str) -> str:
    """The C text with each static helper kept only where something else in it calls it.

    The templates write every helper they may need between the lines ``@@helper NAME@@``
    and ``@@end@@``.  A helper whose name appears nowhere outside its own block is
    dropped (repeatedly, since a dropped helper may have been another's only caller),
    and the marker lines go: a ``static`` function nobody calls would stop the build
    under ``-Werror=unused-function``, whatever the robot, task or kernel set.  In a file
    that compiles as several units (:func:`c_parts`), each helper is compiled in the units
    that call it, and only there (:func:`_unit_guards`).  Names are counted as words, once
    over the file (a search of a 1 MB file per helper took 0.4 s of a KR 210's render).
    """
    blocks = {b["name"]: b for b in _HELPER.finditer(text)}
    if not blocks:
        return text
    words = collections.Counter(_WORD.findall(text))
    inside = {name: collections.Counter(_WORD.findall(b.group(0))) for name, b in blocks.items()}
    kept = dict(blocks)
    while True:
        unused = [name for name in kept if words[name] == inside[name][name]]  # only in its own block
        if not unused:
            break
        for name in unused:
            words -= inside[name]
            del kept[name]
    guards = _unit_guards(text, {name: b["body"] for name, b in kept.items()})
    return _HELPER.sub(lambda b: guards.get(b["name"], "{}").format(b["body"]) if b["name"] in kept else "", text)


def _unit_guards(text: str, bodies: dict[str, str]) -> dict[str, str]:
    """{helper: its block's text around ``{}``, guarded to the units that call it} for a file of
    several units (none for one unit): the units each helper's name appears in, and those of
    the helpers that call it (``bodies``: each kept helper's text).  The helpers stand before the
    first unit, outside every unit."""
    units = list(_UNIT.finditer(text))
    if not units:
        return {}
    sections = [(int(u["part"]), set(_WORD.findall(text, u.start(), units[k + 1].start() if k + 1 < len(units)
                                                    else len(text))))
                for k, u in enumerate(units)]
    calls = {name: set(_WORD.findall(body)) for name, body in bodies.items()}
    callers = {name: {other for other in bodies if other != name and name in calls[other]} for name in bodies}
    used = {name: {part for part, section in sections if name in section} for name in bodies}
    changed = True
    while changed:  # a helper is needed where its callers are
        changed = False
        for name in bodies:
            wider = used[name].union(*(used[c] for c in callers[name]))
            changed, used[name] = changed or wider != used[name], wider
    guards = {}
    for name, parts in used.items():
        condition = " || ".join(["!defined(KINEGEN_PART)"] + [f"KINEGEN_PART == {part}" for part in sorted(parts)])
        guards[name] = f"#if {condition}\n{{}}#endif\n"
    return guards


# ik_numeric (robot.c.j2): what it converges to, and how many steps it takes at most (the numpy
# runtime's NUMERIC_TOLERANCE and NUMERIC_ITERATIONS, runtime.py.j2).
NUMERIC_TOLERANCE = "1e-12"
NUMERIC_ITERATIONS = 100


def numeric_ik(context: dict) -> dict | None:
    """What robot.c.j2 writes ik_numeric from, for a package with ik (``ik_method``): the residual's
    rows (6 for a pose: position and rotation vector; else the task's, its angles wrapped), the size of the
    normal matrix (the smaller of the residual's rows and the joints), and each joint's limits."""
    n = len(context["joints"])
    if not context.get("ik_method") or not n:
        return None
    rows = 6 if context["pose_task"] else len(context["task"])
    limits = {i: (low, high) for i, low, high, _ in context["joint_limits"]}
    return {"rows": rows, "size": min(rows, n), "wide": rows <= n,
            "angles": [] if context["pose_task"] else [k for k, t in enumerate(context["task"]) if t in ANGLE_TASKS],
            "limits": [limits.get(i) for i in range(n)],
            "residual": "metres and radians: the position and the rotation vector" if context["pose_task"]
            else "in task units",
            "tolerance": NUMERIC_TOLERANCE, "iterations": NUMERIC_ITERATIONS}


def general_6r_function(context: dict) -> dict | None:
    """The C entry point ``ik`` of a general 6R (general_6r.c.j2: the eigen-solve, the recovery of
    the joints and the Newton polish, all in C), as the templates see a kernel: x (12) -> Q (16, 6),
    valid (16), returning the number of valid answers like a closed-form ik; None for other arms."""
    if not context.get("general_6r"):
        return None
    slots = context["general_6r_slots"]
    equations = next(f for f in context["functions"] if f["name"] == "ik_6r_equations")
    return {
        "name": "ik", "general_6r": True, "is_ik": True, "checks": (), "solve": None,
        "doc": (f"Inverse kinematics of a general 6R, every real solution: Q (..., {slots}, 6), valid (..., {slots}). "
                "Raghavan and Roth's equations in Manocha and Canny's form (ik_6r_equations), the real roots of "
                "their 12 x 12 determinant (a 24 x 24 eigenproblem by Francis QR steps where those leave a doubt), "
                "the other joints from each real root, each answer polished by "
                "Newton steps on fk and the Jacobian; a valid answer reproduces the pose within 1e-10, the valid "
                "answers first, by q1 then q2, ..., each once."),
        "arguments": equations["arguments"], "params_used": equations["params_used"],
        "arguments_used": equations["arguments_used"],
        "outputs": [{"name": "Q", "shape": (slots, 6), "dtype": "float", "size": 6 * slots, "flat": [], "staged": [],
                     "constant": set()},
                    {"name": "valid", "shape": (slots,), "dtype": "bool", "size": slots, "flat": [], "staged": [],
                     "constant": set()}],
        "operations": equations["operations"], "prologue": [], "stages": [], "arrays": set(), "indexed": set(),
        "block": 1, "blocked": False, "block_outputs": [], "stream_outputs": [], "stream_size": 0,
        "boolean_temporaries": frozenset(),
    }


# A C file whose kernels hold at least SPLIT_OPERATIONS operations (after CSE) compiles as
# several units side by side (build_c.py.j2), one more for each further SPLIT_OPERATIONS, at most
# MAX_PARTS: a large file in one unit spends most of its build on one core while the other has only
# the cffi binding to compile.  The papers' robots (the PUMA 560: 5,929 operations) stay one unit.
SPLIT_OPERATIONS = 6000
MAX_PARTS = 3
# What a kernel costs GCC at -O2, in operations (c_parts balances the units by it).  Measured one
# kernel at a time (each with the file's preamble, gcc 12, 2026-11-26) on the KUKA KR 210's 29
# kernels and the Kinova Jaco's 22, the time grows with the operations (about 0.2-0.3 ms each), plus
# about 50 ms a kernel, plus a term in the square of the entries it stores: the Jaco's
# ik_6r_equations (2,044 operations, 1,124 entries stored) took 1.5-2.0 s where a kernel of
# 2,000 operations and few outputs takes 0.5 s (GCC's dead-store and alias passes compare each
# store with those before it).  The squared operations this used before put the KR 210's coriolis
# (3,106 operations, 0.6 s) in a unit alone and the rest in two: 0.7, 1.4 and 2.0 s.
KERNEL_WEIGHT = 200
STORES_SQUARED_PER_OPERATION = 300
# The general 6R's solver (general_6r.c.j2), in the first unit: about a 2,800-operation kernel.
GENERAL_6R_WEIGHT = 2800


def compile_weight(f: dict) -> int:
    """What kernel ``f`` (a template dict) costs the compiler, in operations (the notes above)."""
    stores = sum(len(out["staged"]) for out in f["outputs"])
    return f["operations"] + KERNEL_WEIGHT + stores * stores // STORES_SQUARED_PER_OPERATION


def _movable(f: dict) -> bool:
    """Whether kernel ``f`` (a template dict) may go in a unit of its own: it is not the ik (whose
    checks are a static function of its own beside it), the general 6R or a run-time solve.  The
    static helpers a kernel calls are compiled in each unit that calls them (prune_helpers)."""
    return not (f.get("general_6r") or f.get("solve") or f["is_ik"])


def c_parts(functions: list[dict]) -> tuple[int, dict[str, int]]:
    """(how many units the C file compiles as, {kernel name: its unit} for those not in the first).

    Kernels that may move (:func:`_movable`) go, heaviest first (:func:`compile_weight`), to the
    unit with the least weight (the first unit also carries what cannot move, and the general 6R's
    solver as GENERAL_6R_WEIGHT): deterministic, from the kernels alone, never the machine."""
    own = [f for f in functions if not f.get("solve") and not f.get("general_6r")]
    weight = {f["name"]: compile_weight(f) for f in own}
    parts = min(MAX_PARTS, sum(f["operations"] for f in own) // SPLIT_OPERATIONS + 1)
    if parts == 1:
        return 1, {}
    load = [0] * parts
    for f in functions:
        if f.get("general_6r"):
            load[0] += GENERAL_6R_WEIGHT
        elif not f.get("solve") and not _movable(f):
            load[0] += weight[f["name"]]
    assigned = {}
    for f in sorted((f for f in own if _movable(f)), key=lambda f: (-weight[f["name"]], f["name"])):
        part = min(range(parts), key=lambda k: (load[k], k))
        load[part] += weight[f["name"]]
        if part:
            assigned[f["name"]] = part + 1
    used = sorted(set(assigned.values()))  # a unit left empty (few movable kernels) is none
    renumber = {part: k + 2 for k, part in enumerate(used)}
    return len(used) + 1, {name: renumber[part] for name, part in assigned.items()}


def render(context: dict) -> dict[str, str]:
    """Files of the C backend, by name, for one robot."""
    printer = CKernelPrinter(memo=context.get("printed", {}).get("c"))
    name = context["name"]
    context = dict(context, numeric_ik=numeric_ik(context))
    general = general_6r_function(context)
    if general is not None:  # the general 6R's ik is a C entry point like a closed form's
        context = dict(context, functions=[*context["functions"], general])
    # One-point entry points for Python (robot_point.c.j2): kernels without requirement
    # statuses, whose outputs have at most three axes.
    functions = [dict(f, point=not f["checks"] and not f.get("solve") and all(len(o["shape"]) <= 3 for o in f["outputs"]))
                 for f in context["functions"]]
    parts, part_of = c_parts(functions)
    functions = [dict(f, part=part_of.get(f["name"], 1)) for f in functions]
    context = dict(context, functions=functions, c_parts=parts)
    context = dict(context, c_declarations=declarations(context, False), c_cdef=declarations(context, True),
                   c_checked=checked_prototypes(context))
    files = {}
    for template, filename in (
        ("robot.h.j2", f"{name}.h"),
        ("robot.c.j2", f"{name}.c"),
        ("robot_point.c.j2", f"{name}_point.c"),
        ("c_kernels.py.j2", "c_kernels.py"),
        ("build_c.py.j2", "build_c.py"),
    ):
        text = TEMPLATES.get_template(template).render(context, printer=printer, scalar_calls=SCALAR_CALLS)
        files[filename] = prune_helpers(text) if filename.endswith(".c") else text
    if parts > 1:
        _check_parts(files[f"{name}.c"])
    return files


_STATIC_FUNCTION = re.compile(r"^static\b[^;{=]*?\b(\w+)\(", re.M)


def _check_parts(text: str) -> None:
    """Raise if a unit after the first (from its ``#if ... KINEGEN_PART == 2`` on) names a static
    function, which that unit would not have: :func:`_movable` is to keep such kernels out."""
    later = text[text.index("#if !defined(KINEGEN_PART) || KINEGEN_PART == 2"):]
    found = sorted({m[1] for m in _STATIC_FUNCTION.finditer(text)} & set(re.findall(r"\w+", later)))
    if found:
        raise AssertionError(f"a C unit after the first calls static functions it does not hold: {', '.join(found)}")

"""Checking generated kernels against their SymPy originals.

The reference is the model's own expression, evaluated independently of the
printed code: exact substitution of the sample point (each float64 as the exact
rational it is) and ``evalf`` at 30 significant digits (45 for the common
subexpressions it is evaluated through).  The error of a kernel
output at a point is its relative error in the max norm,
``max|generated - reference| / max|reference|`` (absolute where the reference
is all zeros); a kernel passes below ``TOLERANCE``.  The geometric Jacobian is
checked again against central finite differences of ``fk``, and the rates of
the Jacobians (``jacobian_dot``, ``task_jacobian_dot``) against central
differences of the Jacobians along ``q + t qd``.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mpmath
import numpy as np
import sympy as sp

from derivations.model import RobotModel, SymbolicFunction
from derivations.program import evaluate

from .kernels import canonical

__all__ = ["TOLERANCE", "FD_TOLERANCE", "Check", "sample_points", "reference", "solve_reference", "verify_model",
           "jacobian_by_finite_differences", "derivative_along", "format_table"]

TOLERANCE = 1e-12
FD_TOLERANCE = 1e-7
DIGITS = 30
WORKING_DIGITS = 45  # for intermediate common subexpressions


@dataclass(frozen=True)
class Check:
    robot: str
    kernel: str
    backend: str
    error: float
    points: int
    method: str = "sympy evalf(30)"
    tolerance: float = TOLERANCE
    # The error beyond what rounding the kernel's system allows (solve_reference), where that
    # is what the check holds to tolerance: a run-time solve; None for every other kernel.
    excess: float | None = None

    @property
    def ok(self) -> bool:
        judged = self.error if self.excess is None else self.excess
        return math.isfinite(self.error) and judged <= self.tolerance


def sample_joints(model: RobotModel, rng: np.random.Generator, count: int) -> np.ndarray:
    """Joint values within the limits (or +-pi rad, +-1 m where a joint has none)."""
    columns = []
    for kind, lim in zip(model.joint_types, model.limits):
        low, high = lim if lim is not None else ((-math.pi, math.pi) if kind == "R" else (-1.0, 1.0))
        columns.append(rng.uniform(low, high, count))
    return np.stack(columns, axis=-1)


def sample_params(model: RobotModel, rng: np.random.Generator) -> dict[str, float]:
    """Parameters moved away from their defaults, to exercise the keyword path."""
    if hasattr(model, "sample_parameters"):  # a kernel set says where its formulas hold
        return model.sample_parameters(rng)
    return {str(s): (v * rng.uniform(0.7, 1.3) if v != 0 else rng.uniform(0.01, 0.1)) for s, v in model.params.items()}


def sample_targets(model: RobotModel, rng: np.random.Generator, count: int, param_sets=None,
                   joints: np.ndarray | None = None) -> np.ndarray:
    """Reachable task coordinates: the model's task at random joints (or at ``joints``),
    evaluated at 30 digits.

    Target k is reached with the parameters ``param_sets[k]`` ({name: value};
    None or absent: the defaults), the ones its kernel call will use.
    """
    by_name = {str(s): s for s in model.params}
    targets = []
    for k, q in enumerate(sample_joints(model, rng, count) if joints is None else joints):
        params = (param_sets[k] if param_sets is not None else None) or {str(s): v for s, v in model.params.items()}
        subs = {s: sp.Rational(float(v)) for s, v in zip(model.q, q)}
        subs.update({by_name[n]: sp.Rational(float(v)) for n, v in params.items()})
        targets.append([float(e) for e in evaluate(model.program, list(model.task), subs, DIGITS)])
    return np.array(targets, dtype=float).reshape(count, len(model.task_names))


def sample_points(model: RobotModel, function: SymbolicFunction, rng: np.random.Generator, count: int,
                  param_sets=None):
    """``count`` argument tuples for ``function``: joint arguments within limits, task
    coordinates (the inverse kinematics' input) reached by random joints with the
    parameters of ``param_sets`` (see :func:`sample_targets`), others in [-1, 1].

    A model may give ``sample_ranges`` {symbol: (low, high)}, SymPy expressions
    in its parameters: an argument whose symbols all have one is drawn from
    those intervals, evaluated at each point's parameters (``param_sets[k]``,
    ``None`` for the defaults), so that the point lies where the kernel is defined.
    A kernel set may say where its formulas hold with ``sample_arguments``.
    """
    if hasattr(model, "sample_arguments"):  # a kernel set says where its formulas hold
        return model.sample_arguments(function, rng, count)
    ranges = getattr(model, "sample_ranges", {})
    if function.name == "ik" and getattr(model, "ik_free", None) is not None:
        # a seven-joint ik: the target and the free joint's value from the same joints, as (count,)
        joints = sample_joints(model, rng, count)
        return [sample_targets(model, rng, count, param_sets, joints), joints[:, model.ik_free]]
    args = []
    for argument in function.arguments:
        if argument.symbols and all(s in ranges for s in argument.symbols):
            args.append(_sample_in_ranges(model, [ranges[s] for s in argument.symbols], rng, count, param_sets))
        elif argument.name == "q":
            args.append(sample_joints(model, rng, count))
        elif argument.symbols == model.task_symbols:
            args.append(sample_targets(model, rng, count, param_sets))
        else:
            args.append(rng.uniform(-1.0, 1.0, (count, len(argument.symbols))))
    return args


def _sample_in_ranges(model, bounds, rng, count, param_sets):
    symbols = {str(s): s for s in model.params}
    columns = []
    for low, high in bounds:
        column = []
        for k in range(count):
            values = (param_sets[k] if param_sets and param_sets[k] else
                      {n: model.params[s] for n, s in symbols.items()})
            subs = {symbols[n]: sp.Rational(v) for n, v in values.items()}
            column.append(rng.uniform(float(sp.sympify(low).xreplace(subs)), float(sp.sympify(high).xreplace(subs))))
        columns.append(column)
    return np.array(columns, dtype=float).T.reshape(count, len(bounds))


def truth(condition: sp.Basic, subs: dict) -> bool:
    """A SymPy condition at a point: each relation's sides by evalf(30), then compared."""
    condition = sp.sympify(condition)
    if condition is sp.true or condition is sp.false:
        return bool(condition)
    if isinstance(condition, sp.And):
        return all(truth(c, subs) for c in condition.args)
    if isinstance(condition, sp.Or):
        return any(truth(c, subs) for c in condition.args)
    if isinstance(condition, sp.Not):
        return not truth(condition.args[0], subs)
    if isinstance(condition, sp.core.relational.Relational):
        lhs, rhs = (side.xreplace(subs).evalf(DIGITS) for side in (condition.lhs, condition.rhs))
        return bool(condition.func(lhs, rhs))
    raise TypeError(f"cannot evaluate the condition {condition!r}")



@functools.lru_cache(maxsize=None)
def _evaluation_plan(function: SymbolicFunction):
    """The outputs of ``function`` as a chain of common subexpressions (SymPy's own ``cse``).

    The inverse-rate kernels are trees of ~10^5 operations once their shared
    subexpressions are unfolded; evaluating the chain keeps each ``evalf`` small.
    """
    flat = [canonical(sp.sympify(e)) for out in function.outputs for e in out.values]
    return sp.cse(flat, symbols=sp.numbered_symbols("_ref", real=True), order="canonical")


def reference(function: SymbolicFunction, values: dict[sp.Symbol, float], exact: bool = False) -> list[np.ndarray]:
    """Each output of ``function`` at ``values``: exact substitution, then evalf.

    The sample point enters exactly (each float64 as the rational it is); each
    common subexpression is evaluated with ``evalf`` at ``WORKING_DIGITS`` and the
    outputs at ``DIGITS`` significant digits (kept as ``mpmath.mpf`` in object
    arrays with ``exact``, rounded to float64 otherwise).
    """
    known: dict[sp.Basic, sp.Basic] = {s: sp.Rational(float(v)) for s, v in values.items()}
    replacements, reduced = _evaluation_plan(function)
    replacements = list(function.definitions) + list(replacements)  # a program: its steps first
    for symbol, expr in replacements:
        value = expr.xreplace(known)
        known[symbol] = value if isinstance(value, sp.logic.boolalg.Boolean) else value.evalf(WORKING_DIGITS)
    outputs, start = [], 0
    for out in function.outputs:
        entries = [e.xreplace(known) for e in reduced[start:start + len(out.values)]]
        start += len(out.values)
        if out.dtype == "bool":
            outputs.append(np.array([truth(e, {}) for e in entries], dtype=bool).reshape(out.shape))
        elif exact:
            numbers = [mpmath.mpf(sp.Float(e.evalf(DIGITS), DIGITS)._mpf_) for e in entries]
            outputs.append(np.array(numbers, dtype=object).reshape(out.shape))
        else:
            outputs.append(np.array([float(e.evalf(DIGITS)) for e in entries], dtype=float).reshape(out.shape))
    return outputs


# The float64 system's entries carry a few units of rounding each, and its SVD a few more: its
# singular values and singular vectors are known to within this many units of rounding of the
# system's size (the Frobenius norm), and a solve only to what that perturbation can move it.
ROUNDING_SYSTEM = 16 * np.finfo(float).eps


def solve_reference(function: SymbolicFunction, system: SymbolicFunction,
                    values: dict[sp.Symbol, float]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The outputs of a kernel solved at run time (``function.solve``), independently.

    Its system (A, b, row_scale, col_scale: the closed forms of ``system``) is
    evaluated at 30 digits and solved with mpmath's SVD at 40 digits by the rule of
    :class:`derivations.model.NumericSolve`, not by the generated code's Jacobi
    rotations or LAPACK.

    Returns ``(outputs, allowances)``: for each output, what a float64 solve cannot
    resolve, as an absolute bound per entry (zero for the flag).
    The generated code evaluates A and b in float64, so it solves a system off by
    ``e = ROUNDING_SYSTEM |An|_F`` (and ``ROUNDING_SYSTEM |bn|``).  To first order
    (Wedin's bound for the damped pseudo-inverse) that moves the solution ``y`` by
    up to ``F (e |y| + e_b) + F^2 e |r|``, with ``F`` the largest gain
    ``s / (s^2 + lambda^2)`` of a singular value above ``e`` and ``r`` the residual:
    about ``cond(An)`` units of rounding, so 1e-15 relative where the arm is well
    conditioned and 1e-11 near the condition limit 1e4.  A singular value at or
    below ``e`` cannot be told from zero at all: its term is known only up to the
    largest gain on ``[0, e]`` times ``|u . bn| |v|``.  The manipulability (the
    product of the singular values) is known up to what adding the rounding of
    the unscaled A to every singular value adds to the product.
    """
    solve = function.solve
    parts = reference(system, values, exact=True)
    A = parts[0]
    b, row_scale, col_scale = (parts[1], parts[2], parts[3]) if solve.kind == "solution" else (None, *parts[1:3])
    with mpmath.workdps(40):
        if b is None:
            system = mpmath.matrix(A.tolist())
            raw = mpmath.svd_r(system, compute_uv=False)
            measure = mpmath.fprod(raw)
            rounding = ROUNDING_SYSTEM * mpmath.mnorm(system, "f")
            slack = mpmath.fprod(raw[i] + rounding for i in range(len(raw))) - measure
        An = mpmath.matrix([[row_scale[i] * A[i, j] * col_scale[j] for j in range(A.shape[1])]
                            for i in range(A.shape[0])])
        U, S, V = mpmath.svd_r(An, full_matrices=False)
        s = [S[i] for i in range(len(S))]
        largest, smallest = max(s), min(s)
        singular = not smallest > largest / solve.COND_LIMIT
        if b is None:
            return [np.array(float(measure)), np.array(singular)], [np.array(float(slack)), np.zeros(())]
        threshold = largest / solve.COND_LIMIT
        damping = ((solve.DAMPING * threshold)**2 * max(1 - (smallest / threshold)**2, 0)
                   if singular and threshold > 0 else 0)
        bn = [row_scale[i] * b[i] for i in range(len(b))]
        projections = [mpmath.fsum(U[r, i] * bn[r] for r in range(len(bn))) for i in range(len(s))]
        gains = [si / (si**2 + damping) if si**2 + damping > 0 else mpmath.mpf(0) for si in s]
        y = [mpmath.fsum(gains[i] * projections[i] * V[i, j] for i in range(len(s))) for j in range(A.shape[1])]
        x = [float(col_scale[j] * y[j]) for j in range(A.shape[1])]
        e = ROUNDING_SYSTEM * mpmath.mnorm(An, "f")
        e_b = ROUNDING_SYSTEM * mpmath.norm(mpmath.matrix(bn))
        resolved = [g for si, g in zip(s, gains) if si > e]
        F = max(resolved, default=mpmath.mpf(0))
        fitted = An * mpmath.matrix(y)
        residual = mpmath.norm(mpmath.matrix([bn[i] - fitted[i] for i in range(len(bn))]))
        spread = F * (e * mpmath.norm(mpmath.matrix(y)) + e_b) + F**2 * e * residual
        # s / (s^2 + lambda^2) grows on [0, lambda]: its largest value on [0, e]
        top = min(e, mpmath.sqrt(damping)) if damping > 0 else e
        unresolved = top / (top**2 + damping) if top > 0 else mpmath.mpf(0)
        slack = [float(abs(col_scale[j]) * (spread + mpmath.fsum(unresolved * abs(projections[i] * V[i, j])
                                                                  for i, si in enumerate(s) if si <= e)))
                 for j in range(A.shape[1])]
    return [np.array(x), np.array(singular)], [np.array(slack), np.zeros(())]


def relative_error(generated: np.ndarray, expected: np.ndarray, allowance: np.ndarray | None = None) -> float:
    """``max|generated - expected| / max|expected|`` (absolute where ``expected`` is all zeros).

    With ``allowance`` (absolute, per entry; see :func:`solve_reference`), only the part of
    each difference beyond it counts.
    """
    if expected.dtype == bool:
        return float(np.mean(generated != expected))
    scale = float(np.max(np.abs(expected))) if expected.size else 0.0
    difference = np.abs(generated - expected)
    if allowance is not None:
        difference = np.maximum(difference - np.broadcast_to(allowance, difference.shape), 0.0)
    diff = float(np.max(difference)) if expected.size else 0.0
    if not math.isfinite(diff):
        return math.inf
    return diff / scale if scale > 0 else diff


def existence_mask(function: SymbolicFunction, expected: list[np.ndarray]) -> np.ndarray | None:
    """Where a kernel's float outputs are defined: its bool output (``valid``) at the reference.

    A kernel with one bool output of shape (k,) and float outputs of shape
    (k, ...) (the inverse kinematics: a branch per row) is compared only on the
    rows whose reference condition holds; other kernels everywhere (None).
    """
    bools = [(want, out) for want, out in zip(expected, function.outputs) if out.dtype == "bool"]
    if len(bools) != 1:
        return None
    want, flag = bools[0]
    rows = flag.shape[0] if flag.shape else None
    floats = [out for out in function.outputs if out.dtype == "float"]
    # Only a per-branch existence flag masks (not, say, a singular flag, which says nothing of definedness).
    if flag.name != "valid" or rows is None or not all(out.shape[:1] == (rows,) for out in floats):
        return None
    return want


def verify_model(model: RobotModel, modules: dict, samples: int = 6, seed: int = 0) -> list[Check]:
    """Check every kernel of ``model`` in every backend module given.

    ``modules`` maps a backend name to the imported generated module.  The first
    sample uses the default parameters (no keywords); the rest pass perturbed
    parameters as keywords.  A kernel with a ``valid`` output is compared on the
    rows (branches) where the reference says valid, and its ``valid`` everywhere;
    its check counts those rows as its points.
    """
    rng = np.random.default_rng(seed)
    checks = []
    param_symbols = {str(s): s for s in model.params}
    functions = model.functions()
    names = {f.name for f in functions}
    by_name = {f.name: f for f in functions}
    for function in functions:
        param_sets = [None] + [sample_params(model, rng) for _ in range(samples - 1)]
        points = sample_points(model, function, rng, samples, param_sets)
        worst = {backend: 0.0 for backend in modules}
        beyond = {backend: 0.0 for backend in modules}  # past the rounding of a solve's system
        compared = 0
        for k in range(samples):
            values = {}
            for argument, array in zip(function.arguments, points):
                values.update(zip(argument.symbols, np.atleast_1d(array[k])))
            params = param_sets[k]
            values.update({param_symbols[n]: v for n, v in (params or {n: float(model.params[s])
                                                                     for n, s in param_symbols.items()}).items()})
            slack = [None] * len(function.outputs)
            try:
                if function.solve is not None:
                    expected, slack = solve_reference(function, by_name[function.solve.system], values)
                else:
                    expected = reference(function, values)
            except (np.linalg.LinAlgError, OverflowError, ValueError, ZeroDivisionError):
                # no reference at this point (a system whose entries overflow a double, a value past
                # any float): a failed check for this kernel, not a crash of the verification
                for backend in modules:
                    worst[backend] = math.inf
                continue
            mask = existence_mask(function, expected)
            compared += 1 if mask is None else int(mask.sum())
            for backend, module in modules.items():
                kernel = getattr(module, function.name)
                result = kernel(*[array[k] for array in points], **(params or {}))
                result = result if isinstance(result, tuple) else (result,)
                for got, want, out, loose in zip(result, expected, function.outputs, slack):
                    got = np.asarray(got)
                    if mask is not None and out.dtype == "float":
                        got, want = got[mask], want[mask]
                    worst[backend] = max(worst[backend], relative_error(got, want))
                    beyond[backend] = max(beyond[backend], relative_error(got, want, loose))
        for backend in modules:
            checks.append(Check(model.name, function.name, backend, worst[backend], compared,
                                excess=beyond[backend] if function.solve is not None else None))
    if "jacobian" in names:
        for backend, module in modules.items():
            q = sample_joints(model, rng, samples)
            error = _difference_error(module.jacobian(q), jacobian_by_finite_differences(module.fk, q))
            checks.append(Check(model.name, "jacobian", backend, error, samples,
                                "central differences of fk", FD_TOLERANCE))
    for rate, kernel in (("jacobian_dot", "jacobian"), ("task_jacobian_dot", "task_jacobian")):
        if rate not in names:
            continue
        for backend, module in modules.items():
            q = sample_joints(model, rng, samples)
            qd = rng.uniform(-1.0, 1.0, q.shape)
            expected = derivative_along(getattr(module, kernel), q, qd)
            error = _difference_error(getattr(module, rate)(q, qd), expected)
            checks.append(Check(model.name, rate, backend, error, samples,
                                f"central differences of {kernel} along q + t qd", FD_TOLERANCE))
    return checks


def _difference_error(got: np.ndarray, differences: np.ndarray) -> float:
    """``max|got - differences|`` relative to max(1, max|got|): central differences carry an error of
    the size of the kernel's values times the step squared, so an arm 10^15 m long (a tan near its
    pole in a description) is held to the same relative standard as one of a metre."""
    scale = max(1.0, float(np.max(np.abs(got)))) if got.size else 1.0
    return float(np.max(np.abs(got - differences))) / scale if got.size else 0.0


def derivative_along(kernel, q: np.ndarray, qd: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``d/dt kernel(q + t qd)`` at t = 0 by central differences (the time derivative along qd)."""
    return (kernel(q + step * qd) - kernel(q - step * qd)) / (2 * step)


def jacobian_by_finite_differences(fk, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``[v; w]`` columns from central differences of ``fk``: ``dp/dq_i`` and ``vee(dR/dq_i R^T)``."""
    q = np.asarray(q, dtype=float)
    n = q.shape[-1]
    T = fk(q)
    R = T[..., :3, :3]
    columns = []
    for i in range(n):
        dT = derivative_along(fk, q, np.eye(n)[i], step)  # dT/dq_i
        v = dT[..., :3, 3]
        W = dT[..., :3, :3] @ np.swapaxes(R, -1, -2)
        w = np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], -1) / 2
        columns.append(np.concatenate([v, w], axis=-1))
    return np.stack(columns, axis=-1)


def format_table(checks: list[Check]) -> str:
    """robots x kernels x max error, one row per robot and kernel, both backends side by side."""
    backends = sorted({c.backend for c in checks}, key=lambda b: (b != "numpy", b))
    rows = {}
    for c in checks:
        key = (c.robot, c.kernel if c.method.startswith("sympy") else f"{c.kernel} (finite diff.)")
        rows.setdefault(key, {})[c.backend] = c
    header = ["robot", "kernel"] + [f"{b} max error" for b in backends] + ["status"]
    lines = [header]
    for (robot, kernel), by_backend in rows.items():
        cells = [f"{by_backend[b].error:.1e}" if b in by_backend else "-" for b in backends]
        ok = all(c.ok for c in by_backend.values())
        # A solve whose error is over the tolerance but within what its float64 system can resolve
        # (an arm singular to rounding, or near the condition limit): say so beside the figure.
        rounding = ok and any(not c.error <= c.tolerance for c in by_backend.values())
        lines.append([robot, kernel] + cells + ["ok (the system's rounding)" if rounding else "ok" if ok else "FAIL"])
    widths = [max(len(row[i]) for row in lines) for i in range(len(header))]
    text = []
    for j, row in enumerate(lines):
        text.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        if j == 0:
            text.append("  ".join("-" * w for w in widths))
    return "\n".join(text)

"""Checking generated kernels against their SymPy originals.

The reference is the model's own expression, evaluated independently of the
printed code: exact substitution of the sample point (each float64 as the exact
number it is, in a 40-digit Float) and ``evalf`` at 30 significant digits.  The error of a kernel
output at a point is its relative error in the max norm,
``max|generated - reference| / max|reference|`` (absolute where the reference
is all zeros); a kernel passes below ``TOLERANCE``.  The geometric Jacobian is
checked again against central finite differences of ``fk``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from derivations.model import RobotModel, SymbolicFunction

__all__ = ["TOLERANCE", "FD_TOLERANCE", "Check", "sample_points", "reference", "verify_model",
           "jacobian_by_finite_differences", "format_table"]

TOLERANCE = 1e-12
FD_TOLERANCE = 1e-7
DIGITS = 30


@dataclass(frozen=True)
class Check:
    robot: str
    kernel: str
    backend: str
    error: float
    points: int
    method: str = "sympy evalf(30)"
    tolerance: float = TOLERANCE

    @property
    def ok(self) -> bool:
        return math.isfinite(self.error) and self.error <= self.tolerance


def sample_joints(model: RobotModel, rng: np.random.Generator, count: int) -> np.ndarray:
    """Joint values within the limits (or +-pi rad, +-1 m where a joint has none)."""
    columns = []
    for kind, lim in zip(model.joint_types, model.limits):
        low, high = lim if lim is not None else ((-math.pi, math.pi) if kind == "R" else (-1.0, 1.0))
        columns.append(rng.uniform(low, high, count))
    return np.stack(columns, axis=-1)


def sample_params(model: RobotModel, rng: np.random.Generator) -> dict[str, float]:
    """Parameters moved away from their defaults, to exercise the keyword path."""
    return {str(s): (v * rng.uniform(0.7, 1.3) if v != 0 else rng.uniform(0.01, 0.1)) for s, v in model.params.items()}


def sample_targets(model: RobotModel, rng: np.random.Generator, count: int, param_sets=None) -> np.ndarray:
    """Reachable task coordinates: the model's task at random joints, evaluated at 30 digits.

    Target k is reached with the parameters ``param_sets[k]`` ({name: value};
    None or absent: the defaults), the ones its kernel call will use.
    """
    by_name = {str(s): s for s in model.params}
    targets = []
    for k, q in enumerate(sample_joints(model, rng, count)):
        params = (param_sets[k] if param_sets is not None else None) or {str(s): v for s, v in model.params.items()}
        subs = {s: sp.Rational(float(v)) for s, v in zip(model.q, q)}
        subs.update({by_name[n]: sp.Rational(float(v)) for n, v in params.items()})
        targets.append([float(e.evalf(DIGITS, subs=subs)) for e in model.task])
    return np.array(targets, dtype=float).reshape(count, len(model.task_names))


def sample_points(model: RobotModel, function: SymbolicFunction, rng: np.random.Generator, count: int,
                  param_sets=None):
    """``count`` argument tuples for ``function``: joint arguments within limits, task
    coordinates (the inverse kinematics' input) reached by random joints with the
    parameters of ``param_sets`` (see :func:`sample_targets`), others in [-1, 1]."""
    args = []
    for argument in function.arguments:
        if argument.name == "q":
            args.append(sample_joints(model, rng, count))
        elif argument.symbols == model.task_symbols:
            args.append(sample_targets(model, rng, count, param_sets))
        else:
            args.append(rng.uniform(-1.0, 1.0, (count, len(argument.symbols))))
    return args


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


def reference(function: SymbolicFunction, values: dict[sp.Symbol, float]) -> list[np.ndarray]:
    """Each output of ``function`` at ``values``, by exact substitution and evalf(30).

    Each value enters as the exact double it is, held in a 40-digit Float (a
    double needs 17), so SymPy evaluates every function at 40 digits as it
    substitutes; exact rationals for the values do the same far more slowly.
    """
    subs = {s: sp.Float(sp.Rational(float(v)), DIGITS + 10) for s, v in values.items()}
    outputs = []
    for out in function.outputs:
        if out.dtype == "bool":
            flat = [truth(e, subs) for e in out.values]
            outputs.append(np.array(flat, dtype=bool).reshape(out.shape))
        else:
            flat = [float(sp.sympify(e).xreplace(subs).evalf(DIGITS)) for e in out.values]
            outputs.append(np.array(flat, dtype=float).reshape(out.shape))
    return outputs


def relative_error(generated: np.ndarray, expected: np.ndarray) -> float:
    if expected.dtype == bool:
        return float(np.mean(generated != expected))
    scale = float(np.max(np.abs(expected))) if expected.size else 0.0
    diff = float(np.max(np.abs(generated - expected))) if expected.size else 0.0
    if not math.isfinite(diff):
        return math.inf
    return diff / scale if scale > 0 else diff


def existence_mask(function: SymbolicFunction, expected: list[np.ndarray]) -> np.ndarray | None:
    """Where a kernel's float outputs are defined: its bool output (``valid``) at the reference.

    A kernel with one bool output of shape (k,) and float outputs of shape
    (k, ...) (the inverse kinematics: a branch per row) is compared only on the
    rows whose reference condition holds; other kernels everywhere (None).
    """
    masks = [want for want, out in zip(expected, function.outputs) if out.dtype == "bool"]
    return masks[0] if len(masks) == 1 else None


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
    for function in model.functions():
        param_sets = [None] + [sample_params(model, rng) for _ in range(samples - 1)]
        points = sample_points(model, function, rng, samples, param_sets)
        worst = {backend: 0.0 for backend in modules}
        compared = 0
        for k in range(samples):
            values = {}
            for argument, array in zip(function.arguments, points):
                values.update(zip(argument.symbols, array[k]))
            params = param_sets[k]
            values.update({param_symbols[n]: v for n, v in (params or {n: float(model.params[s])
                                                                     for n, s in param_symbols.items()}).items()})
            expected = reference(function, values)
            mask = existence_mask(function, expected)
            compared += 1 if mask is None else int(mask.sum())
            for backend, module in modules.items():
                kernel = getattr(module, function.name)
                result = kernel(*[array[k] for array in points], **(params or {}))
                result = result if isinstance(result, tuple) else (result,)
                for got, want, out in zip(result, expected, function.outputs):
                    got = np.asarray(got)
                    if mask is not None and out.dtype == "float":
                        got, want = got[mask], want[mask]
                    worst[backend] = max(worst[backend], relative_error(got, want))
        for backend in modules:
            checks.append(Check(model.name, function.name, backend, worst[backend], compared))
    if "jacobian" in {f.name for f in model.functions()}:
        for backend, module in modules.items():
            q = sample_joints(model, rng, samples)
            error = float(np.max(np.abs(module.jacobian(q) - jacobian_by_finite_differences(module.fk, q))))
            checks.append(Check(model.name, "jacobian", backend, error, samples,
                                "central differences of fk", FD_TOLERANCE))
    return checks


def jacobian_by_finite_differences(fk, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``[v; w]`` columns from central differences of ``fk``: ``dp/dq_i`` and ``vee(dR/dq_i R^T)``."""
    q = np.asarray(q, dtype=float)
    n = q.shape[-1]
    T = fk(q)
    R = T[..., :3, :3]
    columns = []
    for i in range(n):
        dq = np.zeros(n)
        dq[i] = step
        dT = (fk(q + dq) - fk(q - dq)) / (2 * step)
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
        lines.append([robot, kernel] + cells + ["ok" if ok else "FAIL"])
    widths = [max(len(row[i]) for row in lines) for i in range(len(header))]
    text = []
    for j, row in enumerate(lines):
        text.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        if j == 0:
            text.append("  ".join("-" * w for w in widths))
    return "\n".join(text)

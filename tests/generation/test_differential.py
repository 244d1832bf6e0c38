"""numpy against C, differentially, over every kernel of every package (issue #17).

Each kernel is called through both backends with the same arguments, one point and a batch:
points where it is defined (the verification's sampling), wide random values, values at and
next to zero, tiny and huge magnitudes, a batch mixing them; and on the defined points and
the mixed batch, each robot parameter in turn at 0 and +-1e-300.  Where both
answer, they agree to 1e-12 relative to each item's output in the max norm (NaN and inf in
the same places, ik branches flagged
valid alike); where one refuses, the other refuses with the same exception class; the
numpy kernels raise no floating-point warnings where the C is silent.  The expected
behaviour is not either backend's: it is that the two are one function.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import derivations
import generated
from codegen.verify import sample_params, sample_points
from conftest import ROBOT_NAMES
from test_zoo import ARMS, generated_package, generated_root  # noqa: F401  (generated_root: a fixture)

POINTS = 24  # per kind of argument
RELATIVE = 1e-12
# At a degenerate parameter (a length of 0 or 1e-300) a rate map is damped at an exact
# singularity, where its answer's condition number is about 1 / damping^2 = 1e12: there the
# backends must agree on every flag and on where NaN and inf are, and their values to 1e-6
# (with arguments of 1e6 and more the values are rounding noise in both, and only the flags
# and the NaN and inf are compared).
RELATIVE_DEGENERATE = 1e-6


def _arguments(model, function, rng):
    """Argument tuples: (kind, [array per argument]) for the sweeps."""
    sizes = [len(argument.symbols) for argument in function.arguments]
    if function.name == "ik" and getattr(model, "ik_free", None) is not None:
        sizes = sizes[:1] + [0]
    kinds = {"defined": sample_points(model, function, rng, POINTS)}

    def each(make):
        return [make(size) for size in sizes]

    def shaped(values, size):
        return values if size else values[:, 0]

    kinds["wide"] = each(lambda s: shaped(rng.uniform(-10.0, 10.0, (POINTS, max(s, 1))), s))
    kinds["zero"] = each(lambda s: shaped(np.zeros((2, max(s, 1))), s))
    kinds["tiny"] = each(lambda s: shaped(rng.choice([-1e-300, 0.0, 1e-300, 5e-324], (POINTS, max(s, 1))), s))
    kinds["large"] = each(lambda s: shaped(rng.choice([-1e6, -1.0, 1e6, 1e8], (POINTS, max(s, 1))), s))
    # one batch of each kind's first item: an item's refusal must not depend on the others
    kinds["mixed"] = [np.stack([np.asarray(kinds[k][i])[0] for k in ("wide", "zero", "large", "defined", "tiny")])
                      for i in range(len(sizes))]
    return sizes, kinds


def _call(module, name, args, params):
    """(result as a tuple of arrays, None) or (None, the exception's class name)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            result = getattr(module, name)(*args, **params)
        except (ValueError, RuntimeWarning, ZeroDivisionError, FloatingPointError, OverflowError) as exc:
            return None, type(exc).__name__
    return (result if isinstance(result, tuple) else (result,)), None


def _batch_ndim(args, sizes):
    return len(np.broadcast_shapes(*[np.shape(a)[:-1] if size else np.shape(a) for a, size in zip(args, sizes)]))


def _unsettled(module, name, args, params, result, batch_ndim, rng):
    """Items whose answer the rounding of the arguments already changes: the kernel in ``module``
    at arguments moved by about 20 ulps (two random moves).  Returns (items whose flags or NaN
    pattern change, the spread of each float output): two correct implementations may differ by
    that much, and may flag such an item differently."""
    unsettled = np.zeros(np.shape(result[0])[:batch_ndim], bool)
    spread = [np.zeros(np.shape(r)) for r in result]
    for _ in range(2):
        moved = [np.asarray(a) * (1 + 4e-15 * rng.uniform(-1, 1, np.shape(a))) for a in args]
        other, error = _call(module, name, moved, params)
        if error:
            return np.ones_like(unsettled), spread
        for k, (r, o) in enumerate(zip(result, other)):
            r, o = np.asarray(r), np.asarray(o)
            changed = (r != o) if r.dtype != float else (np.isnan(r) != np.isnan(o)) | (np.isinf(r) != np.isinf(o))
            unsettled |= changed.reshape(changed.shape[:batch_ndim] + (-1,)).any(axis=-1)
            if r.dtype == float:
                with np.errstate(invalid="ignore"):
                    spread[k] = np.fmax(spread[k], np.abs(np.where(np.isfinite(r) & np.isfinite(o), r - o, 0.0)))
    return unsettled, spread


def _disagreement(numpy_result, c_result, outputs, unsettled, spread, relative=RELATIVE) -> str | None:
    """Why two backends' answers differ beyond rounding, or None."""
    valid = None
    for out, got_n, got_c, wobble in zip(outputs, numpy_result, c_result, spread):
        got_n, got_c = np.asarray(got_n), np.asarray(got_c)
        if got_n.shape != got_c.shape:
            return f"{out.name}: shapes {got_n.shape} and {got_c.shape}"
        settled = np.broadcast_to(~unsettled.reshape(unsettled.shape + (1,) * (got_n.ndim - unsettled.ndim)),
                                  got_n.shape)
        if out.dtype != "float":
            if not np.array_equal(got_n[settled], got_c[settled]):
                return f"{out.name}: {np.argwhere((got_n != got_c) & settled)[:3].tolist()} differ"
            valid = got_n if out.name == "valid" else valid
            continue
        mask = settled.copy()
        if valid is not None:  # an ik's joint values are compared on its valid branches
            mask &= np.broadcast_to(valid[..., None], got_n.shape)
        for what, test in (("NaN", np.isnan), ("inf", np.isinf)):
            if not np.array_equal(test(got_n) & mask, test(got_c) & mask):
                return f"{out.name}: {what} in different places"
        both = mask & np.isfinite(got_n) & np.isfinite(got_c)
        # Relative to the item's output as a whole (max norm, as the verification measures): an entry
        # that is zero in exact arithmetic but computed from entries of 1e8 (a general arm's
        # Jacobian columns, from its frames as a program) is rounding noise of that size in both.
        batch = unsettled.ndim
        finite = np.where(np.isfinite(got_n) & np.isfinite(got_c), np.maximum(np.abs(got_n), np.abs(got_c)), 0.0)
        scale = finite.reshape(finite.shape[:batch] + (-1,)).max(axis=-1, initial=0.0) if finite.size else finite
        scale = np.broadcast_to(np.reshape(scale, np.shape(scale) + (1,) * (got_n.ndim - batch)), got_n.shape)
        n, c, wobble = got_n[both], got_c[both], np.broadcast_to(wobble, got_n.shape)[both]
        scale = scale[both]
        difference = np.abs(n - c)
        if out.name == "Q" or "joint" in out.name:  # angles: +-pi is one answer
            difference = np.minimum(difference, np.abs(difference - 2 * np.pi))
        allowed = relative * np.maximum(1.0, scale) + 10 * wobble
        if difference.size and (difference > allowed).any():
            at = int(np.argmax(difference - allowed))
            return (f"{out.name}: {n[at]!r} and {c[at]!r} (difference {difference[at]:.2e}, "
                    f"rounding spread {wobble[at]:.2e})")
    return None


def _sweep(model, kn, kc) -> tuple[list[str], int]:
    """The disagreements of two backends' kernels of ``model`` over the sweep, and the calls made."""
    rng = np.random.default_rng(17)
    degenerate = [{p: v} for p in kn.PARAMS for v in (0.0, 1e-300, -1e-300)]
    problems, calls = [], 0
    for function in model.functions():
        sizes, kinds = _arguments(model, function, rng)
        for kind, args in kinds.items():
            # degenerate parameters on the defined points and the mixed batch (which holds an
            # item of every other kind)
            for params in [{}, sample_params(model, rng)] + (degenerate if kind in ("defined", "mixed") else []):
                one = [a[0] for a in args]
                for call_args in (one, args):  # one point, and the batch
                    result_n, error_n = _call(kn, function.name, call_args, params)
                    result_c, error_c = _call(kc, function.name, call_args, params)
                    calls += 1
                    if error_n or error_c:
                        why = None if error_n == error_c else f"numpy {error_n}, C {error_c}"
                    else:
                        unsettled, spread = _unsettled(kn, function.name, call_args, params, result_n,
                                                       _batch_ndim(call_args, sizes), rng)
                        why = _disagreement(result_n, result_c, function.outputs, unsettled, spread,
                                            RELATIVE if params not in degenerate else
                                            RELATIVE_DEGENERATE if kind not in ("large", "mixed") else np.inf)
                    if why:
                        first = [np.asarray(a).reshape(-1, np.shape(a)[-1] if np.ndim(a) else 1)[0].tolist()
                                 for a in call_args]
                        problems.append(f"{function.name} {kind} {params} {'one' if call_args is one else 'batch'} "
                                        f"{first}: {why}")
    return problems, calls


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_numpy_and_c_are_one_function(models, name):
    problems, calls = _sweep(models[name], generated.load(name, backend="numpy"), generated.load(name, backend="c"))
    assert not problems, f"{len(problems)} disagreements in {calls} calls:\n" + "\n".join(problems[:20])


@pytest.mark.parametrize("name", ["ur5", "stanford_arm", "kuka_lwr4", "adept_cobra600"])
def test_numpy_and_c_are_one_function_for_users_arms(name, generated_root):
    """The zoo's arms as a user generates them: the automatic IK of each family, the seven-joint
    ik with its free joint, and parameters as the descriptions name them."""
    package = generated_package(name, generated_root)
    model = derivations.load(ARMS[name].path)
    problems, calls = _sweep(model, package.load("numpy"), package.load("c"))
    assert not problems, f"{len(problems)} disagreements in {calls} calls:\n" + "\n".join(problems[:20])


def test_an_empty_batch_beside_a_nan_is_refused_by_both(models):
    """Broadcasting (0, n) against (1, n) leaves no item, but NaN is refused whatever the batch."""
    tried = []
    for name in ROBOT_NAMES:
        for function in models[name].functions():
            sizes = [len(argument.symbols) for argument in function.arguments]
            if len(sizes) < 2 or function.name == "ik":  # ik reports NaN through valid
                continue
            args = [np.zeros((0, sizes[0]))] + [np.full((1, size), np.nan) for size in sizes[1:]]
            for backend in ("numpy", "c"):
                with pytest.raises(ValueError, match="NaN or inf"):
                    getattr(generated.load(name, backend=backend), function.name)(*args)
            tried.append(f"{name}.{function.name}")
    assert len(tried) >= 20, tried  # the rate maps of every arm, and the AVR 3000's velocity maps

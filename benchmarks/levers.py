"""The measured effect of each performance lever, one at a time, on the Puma 560.

    python benchmarks/levers.py [--out benchmarks/levers.md]

Each row times the same work with a lever off and on, in this process:

* batched C (inside C, no Python): the plain loop over the single-point function
  (``KINEGEN_PORTABLE=1`` builds), the blocked layout in scalar C
  (``-DKINEGEN_BLOCKED``), and the blocked layout vectorised with libmvec
  (``-DKINEGEN_SIMD -fopenmp-simd`` and the rest of build_c.py's flags), with
  and without streaming stores; the single point with the vector calls of a
  stage's angles (vectorised builds) or one libm call each;
* the call from Python for one pose: the binding as first written (input checks
  in numpy, a parameter struct allocated per call), the thin cffi path, and the
  one-point entry written against numpy's C API (``<name>_point.c``);
* numpy: one pass over the whole batch against cache-sized chunks, and sin and
  cos from numpy.sin and numpy.cos against one tangent of the half angle;
* derivation: the Puma's task Jacobian simplified with ``trigsimp`` against
  ``expand`` + ``factor_terms`` (:func:`derivations.chain.simplify_derivative`).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import sympy as sp  # noqa: E402

import inside_c  # noqa: E402
from run import format_ratio, format_time, seconds_per_pose  # noqa: E402
from contenders import Run  # noqa: E402

ROBOT = "puma560"


def c_layouts(count: int, repeat: int) -> list[tuple[str, str, float, float]]:
    """(kernel, layout, single ns, batch ns) for the three layouts of the batched C."""
    fast = inside_c.library_flags(ROBOT)
    base = [f for f in fast if f not in ("-DKINEGEN_SIMD", "-fopenmp-simd")]
    layouts = {
        "plain loop over the single point": [f for f in base if f.startswith(("-std", "-O"))],
        "blocks, scalar C (-DKINEGEN_BLOCKED)": [*base, "-DKINEGEN_BLOCKED"],
        "blocks, vectorised (libmvec), plain stores": [*fast, "-DKINEGEN_NO_STREAM"],
        "blocks, vectorised (libmvec), streaming stores past 1 MiB": fast,
    }
    rows = []
    with tempfile.TemporaryDirectory(prefix="kinegen-levers-") as build:
        build = Path(build)
        source = build / "driver.c"
        source.write_text(inside_c.driver_source(ROBOT, count, repeat, rtb_ik=False))
        for label, flags in layouts.items():
            program = build / "driver"
            command = [inside_c.CC, *[f for f in flags if f != "-std=c99"], "-std=gnu99",
                       "-I", str(inside_c.GENERATED / ROBOT), str(source),
                       str(inside_c.GENERATED / ROBOT / f"{ROBOT}.c"), "-o", str(program), "-lm"]
            subprocess.run(command, check=True, capture_output=True)
            out = subprocess.run([str(program)], check=True, capture_output=True, text=True).stdout
            figures = {}
            for line in out.splitlines():
                _, kernel, mode, ns = line.split()
                figures[(kernel, mode)] = float(ns)
            for kernel in ("fk", "jacobian", "ik"):
                if (kernel, "single") in figures:
                    rows.append((kernel, label, figures[(kernel, "single")], figures[(kernel, "batch")]))
    return rows


def binding(repeat: int, min_time: float) -> list[tuple[str, float]]:
    """One pose from Python: the first binding's steps, the thin cffi path, the one-point C entry."""
    import generated
    from generated.puma560 import _runtime
    from generated.puma560._puma560_c import ffi, lib
    kernels = generated.load(ROBOT, "c")
    defaults = list(kernels.PARAMS.values())
    q = np.random.default_rng(2).uniform(-1, 1, 6)

    def first_binding(q):  # what c_kernels.py did before: numpy checks, a struct per call
        q = _runtime.as_batch(q, 6, "fk", "q")
        params = ffi.new("puma560_params *", tuple(_runtime.as_param(v, n) for v, n in zip(defaults, kernels.PARAMS)))
        batch = _runtime.batch_shape(q)
        q = np.ascontiguousarray(np.broadcast_to(q, batch + q.shape[-1:]))
        T = np.empty(batch + (4, 4))
        lib.puma560_fk_batch(int(np.prod(batch, dtype=np.int64)), ffi.from_buffer("double[]", q), params,
                             ffi.from_buffer("double[]", T, require_writable=True))
        return T

    def thin_cffi(q):  # what c_kernels.py did before puma560_point.c: from_buffer per array, numpy.empty
        if type(q) is np.ndarray and q.shape == (6,) and q.dtype is np.dtype(np.float64):
            T = np.empty((4, 4))
            if lib.puma560_fk_checked(1, ffi.from_buffer("double[]", q), kernels._DEFAULT_PARAMS,
                                      ffi.from_buffer("double[]", T)):
                raise ValueError("fk: q contains NaN or inf")
            return T

    np.testing.assert_allclose(first_binding(q), kernels.fk(q), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(thin_cffi(q), kernels.fk(q))
    return [("numpy checks, parameter struct per call (the first binding)",
             seconds_per_pose(Run(lambda: first_binding(q), 1), repeat, min_time)),
            ("cffi: checks in C, cached parameter struct, from_buffer per array (its steps, no signature)",
             seconds_per_pose(Run(lambda: thin_cffi(q), 1), repeat, min_time)),
            ("numpy's C API: puma560_point.c (generated now)",
             seconds_per_pose(Run(lambda: kernels.fk(q), 1), repeat, min_time))]


def numpy_chunks(count: int, repeat: int, min_time: float) -> list[tuple[str, str, float]]:
    import generated
    kernels = generated.load(ROBOT)
    q = np.random.default_rng(3).uniform(-1, 1, (count, 6))
    rows, chunk = [], kernels.CHUNK
    try:
        for label, size in (("one pass over the whole batch", count), (f"chunks of {chunk} poses", chunk)):
            kernels.CHUNK = size
            for kernel in ("fk", "jacobian"):
                f = getattr(kernels, kernel)
                rows.append((kernel, label, seconds_per_pose(Run(lambda: f(q), count), repeat, min_time)))
    finally:
        kernels.CHUNK = chunk
    return rows


def numpy_trig(repeat: int, min_time: float) -> list[tuple[str, float]]:
    """Sine and cosine of 4096 angles: numpy.sin and numpy.cos, or one tan of the half angle."""
    angles = np.random.default_rng(5).uniform(-np.pi, np.pi, 4096)

    def direct():
        return np.sin(angles), np.cos(angles)

    def half_angle():
        h = np.tan(0.5 * angles)
        u = h * h
        r = 1.0 / (1.0 + u)
        return (h + h) * r, (1.0 - u) * r

    return [(label, seconds_per_pose(Run(f, len(angles)), repeat, min_time))
            for label, f in (("numpy.sin and numpy.cos", direct), ("numpy.tan of the half angle", half_angle))]


def derivation() -> list[tuple[str, float]]:
    import derivations
    from derivations.chain import simplify_derivative, simplify_entry
    model = derivations.load(ROBOT)
    raw = model.task.jacobian(sp.Matrix(model.q))
    rows = []
    results = []
    for label, simplify in (("expand + trigsimp (simplify_entry)", simplify_entry),
                            ("expand + factor_terms (simplify_derivative)", simplify_derivative)):
        start = time.perf_counter()
        results.append(raw.applyfunc(simplify))
        rows.append((label, time.perf_counter() - start))
    assert results[0] == results[1], "the two simplifications disagree"
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "levers.md")
    parser.add_argument("--count", type=int, default=100_000)
    args = parser.parse_args(argv)
    repeat, min_time = 7, 0.05
    lines = ["# Performance levers, one at a time (Puma 560)", "",
             f"Generated by `python benchmarks/levers.py` on {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC; "
             "each figure a median, each pair measured in the same run.", ""]
    rows = c_layouts(args.count, 15)
    lines += ["## Batched C, inside C", "", f"{args.count} poses per batch.", "",
              "| kernel | layout | one pose per call | batched, per pose | batched vs plain loop |",
              "|---|---|---|---|---|"]
    plain = {k: b for k, label, s, b in rows if label.startswith("plain")}
    lines += [f"| {k} | {label} | {s:.1f} ns | {b:.1f} ns | {format_ratio(plain[k] / b)} |"
              for k, label, s, b in rows]
    rows = binding(repeat, min_time)
    lines += ["", "## One pose from Python (fk)", "", "| binding | per call | speed-up |", "|---|---|---|"]
    lines += [f"| {label} | {format_time(t)} | {format_ratio(rows[0][1] / t)} |" for label, t in rows]
    rows = numpy_chunks(args.count, repeat, min_time)
    lines += ["", "## numpy kernels", "", f"{args.count} poses per batch.", "",
              "| kernel | layout | per pose | speed-up |", "|---|---|---|---|"]
    whole = {k: t for k, label, t in rows if label.startswith("one pass")}
    lines += [f"| {k} | {label} | {format_time(t)} | {format_ratio(whole[k] / t)} |" for k, label, t in rows]
    rows = numpy_trig(repeat, min_time)
    lines += ["", "Inside the numpy kernels, sin and cos of an angle (numpy vectorises float64 tan, "
              "not sin and cos):", "", "| computed with | per angle, both | speed-up |", "|---|---|---|"]
    lines += [f"| {label} | {format_time(t)} | {format_ratio(rows[0][1] / t)} |" for label, t in rows]
    rows = derivation()
    lines += ["", "## Derivation: the Puma's task Jacobian (72 entries), same expressions", "",
              "| simplification | seconds | speed-up |", "|---|---|---|"]
    lines += [f"| {label} | {t:.2f} | {format_ratio(rows[0][1] / t)} |" for label, t in rows]
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Cost of Paul's partitioned inverse (two 3 x 3 solves) against solving the 6 x 6 system.

    python benchmarks/wrist_partition.py [--count N] [--repeat R]      (or: make bench)

Both routes start from the joint angles q and the tool twist and end with the
joint rates of the PUMA 560:

* partitioned: the generated kernel ``joint_velocity_from_twist`` (A, C, D and
  their closed-form inverses from q, plus the singular flag and the damped
  branch it carries: common-subexpression elimination hoists most of that
  branch out of the conditional, so C computes it every time);
* partitioned, closed form only: the same two 3 x 3 closed-form solves without
  flag or damping, printed here from ``model.rates.partition`` (C only);
* 6 x 6: the generated ``jacobian`` kernel, then Gaussian elimination with partial
  pivoting (C, below) or ``numpy.linalg.solve`` (numpy).

The C timings come from a driver compiled with the flags of the built library
(``inside_c.library_flags``: those its build_c.py chose here) and timed in C, so no Python overhead is counted; the numpy
timings are whole-batch calls.  A benchmark, not a test: nothing is asserted
about speed; the routes are only checked to agree (largest relative difference
from the 6 x 6 answer over the configurations not flagged singular).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "generated" / "puma560"
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import inside_c  # noqa: E402

DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include "puma560.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

%(undamped)s

/* Solve J x = b (6 x 6, row-major) by Gaussian elimination with partial pivoting. */
static int solve6(const double *J, const double *b, double *x)
{
    double a[6][7];
    int i, j, k;
    for (i = 0; i < 6; ++i) {
        for (j = 0; j < 6; ++j) a[i][j] = J[6 * i + j];
        a[i][6] = b[i];
    }
    for (k = 0; k < 6; ++k) {
        int p = k;
        for (i = k + 1; i < 6; ++i) if (fabs(a[i][k]) > fabs(a[p][k])) p = i;
        if (a[p][k] == 0.0) return 1;
        if (p != k) for (j = k; j < 7; ++j) { double t = a[k][j]; a[k][j] = a[p][j]; a[p][j] = t; }
        for (i = k + 1; i < 6; ++i) {
            double f = a[i][k] / a[k][k];
            for (j = k; j < 7; ++j) a[i][j] -= f * a[k][j];
        }
    }
    for (i = 5; i >= 0; --i) {
        double s = a[i][6];
        for (j = i + 1; j < 6; ++j) s -= a[i][j] * x[j];
        x[i] = s / a[i][i];
    }
    return 0;
}

static double seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

int main(int argc, char **argv)
{
    size_t n = (size_t)atol(argv[1]), i;
    int repeat = atoi(argv[2]), r;
    double *q = malloc(6 * n * sizeof *q), *tw = malloc(6 * n * sizeof *tw);
    double *x1 = malloc(6 * n * sizeof *x1), *x2 = malloc(6 * n * sizeof *x2), *x3 = malloc(6 * n * sizeof *x3);
    int *singular = malloc(n * sizeof *singular);
    double best_partition = 1e300, best_full = 1e300, best_undamped = 1e300, diff = 0.0, diff3 = 0.0, J[36];
    FILE *in = fopen(argv[3], "rb");
    (void)argc;
    if (fread(q, sizeof *q, 6 * n, in) != 6 * n || fread(tw, sizeof *tw, 6 * n, in) != 6 * n) return 2;
    fclose(in);
    for (r = 0; r < repeat; ++r) {
        double t0 = seconds(), t1, t2, t3;
        for (i = 0; i < n; ++i) puma560_joint_velocity_from_twist(q + 6 * i, tw + 6 * i, NULL, x1 + 6 * i, singular + i);
        t1 = seconds();
        for (i = 0; i < n; ++i) {
            puma560_jacobian(q + 6 * i, NULL, J);
            solve6(J, tw + 6 * i, x2 + 6 * i);
        }
        t2 = seconds();
        for (i = 0; i < n; ++i) undamped(q + 6 * i, tw + 6 * i, x3 + 6 * i);
        t3 = seconds();
        if (t1 - t0 < best_partition) best_partition = t1 - t0;
        if (t2 - t1 < best_full) best_full = t2 - t1;
        if (t3 - t2 < best_undamped) best_undamped = t3 - t2;
    }
    for (i = 0; i < 6 * n; ++i) {
        double d = fabs(x1[i] - x2[i]) / (1.0 + fabs(x2[i]));
        double d3 = fabs(x3[i] - x2[i]) / (1.0 + fabs(x2[i]));
        if (!singular[i / 6] && d > diff) diff = d;
        if (!singular[i / 6] && d3 > diff3) diff3 = d3;
    }
    printf("%%.6e %%.6e %%.3e %%.6e %%.3e\n", best_partition / n, best_full / n, diff, best_undamped / n, diff3);
    free(q); free(tw); free(x1); free(x2); free(x3); free(singular);
    return 0;
}
"""


def undamped_partition_source() -> str:
    """C of Paul's closed-form partitioned inverse alone (no flag, no damping), default parameters."""
    import sympy as sp

    import derivations
    from codegen.backends.c_backend import CKernelPrinter
    from codegen.kernels import prepare
    from derivations.model import Argument, Output, SymbolicFunction

    model = derivations.load("puma560")
    part, twist = model.rates.partition, sp.Matrix(model.rates.twist)
    v, w = twist[:3, 0], twist[3:, 0]
    arm = part.arm_inverse.adjugate * (v - w.cross(part.tool_offset)) / part.arm_inverse.determinant
    wrist = part.wrist_inverse.adjugate * (w - part.C * arm) / part.wrist_inverse.determinant
    function = SymbolicFunction("undamped", (Argument("q", model.q), Argument("twist", model.rates.twist)),
                                (Output("qd", tuple(arm) + tuple(wrist), (6,)),))
    prepared = prepare(function, tuple(str(p) for p in model.params))
    printer = CKernelPrinter()
    lines = ["static void undamped(const double *q, const double *twist, double *qd)", "{"]
    lines += [f"    const double q{i + 1} = q[{i}];" for i in range(6)]
    lines += [f"    const double {s} = twist[{i}];" for i, s in enumerate(prepared.arguments[1][1])]
    lines += [f"    const double {p} = {v!r};" for p, v in ((str(p), v) for p, v in model.params.items())]
    lines += [f"    const double {name} = {printer.doprint(expr)};" for name, expr in prepared.temporaries]
    lines += [f"    qd[{i}] = {printer.doprint(expr)};" for i, expr in enumerate(prepared.outputs[0].entries)]
    lines += ["    (void)q6;", "}"]
    return "\n".join(lines)


def sample(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.5, 2.5, (count, 6)), rng.uniform(-1.0, 1.0, (count, 6))


def time_c(q: np.ndarray, twist: np.ndarray, repeat: int) -> tuple[float, ...]:
    cc = os.environ.get("CC", "cc")
    with tempfile.TemporaryDirectory(prefix="kinegen-bench-") as scratch:
        scratch = Path(scratch)
        (scratch / "driver.c").write_text(DRIVER % {"undamped": undamped_partition_source()})
        data = scratch / "inputs.bin"
        data.write_bytes(np.ascontiguousarray(q).tobytes() + np.ascontiguousarray(twist).tobytes())
        exe = scratch / "driver"
        subprocess.run([cc, *inside_c.library_flags("puma560"), "-I", str(PACKAGE), str(scratch / "driver.c"),
                        str(PACKAGE / "puma560.c"), "-o", str(exe), "-lm"], check=True)
        out = subprocess.run([str(exe), str(len(q)), str(repeat), str(data)], check=True, capture_output=True,
                             text=True).stdout.split()
    return tuple(float(v) for v in out)


def time_numpy(q: np.ndarray, twist: np.ndarray, repeat: int) -> tuple[float, float, float]:
    from generated.puma560 import numpy_kernels as k
    best_partition = best_full = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        x1, singular = k.joint_velocity_from_twist(q, twist)
        t1 = time.perf_counter()
        x2 = np.linalg.solve(k.jacobian(q), twist[..., None])[..., 0]
        t2 = time.perf_counter()
        best_partition, best_full = min(best_partition, t1 - t0), min(best_full, t2 - t1)
    diff = float(np.max(np.abs(x1 - x2)[~singular] / (1 + np.abs(x2[~singular]))))
    return best_partition / len(q), best_full / len(q), diff


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=200_000, help="configurations per batch")
    parser.add_argument("--repeat", type=int, default=7, help="repetitions (the best is reported)")
    args = parser.parse_args(argv)
    q, twist = sample(args.count)
    partition, full, diff, undamped, undamped_diff = time_c(q, twist, args.repeat)
    rows = [("C (library flags), per call", partition, full, diff),
            ("C, closed form only", undamped, full, undamped_diff),
            ("numpy, per item of a batch", *time_numpy(q, twist, args.repeat))]
    print(f"PUMA 560 joint rates from a twist, {args.count} configurations, best of {args.repeat}")
    print(f"{'backend':28s} {'partitioned':>12s} {'6x6 solve':>12s} {'ratio':>7s} {'max rel. diff':>14s}")
    for label, partition, full, diff in rows:
        print(f"{label:28s} {partition * 1e9:10.1f} ns {full * 1e9:10.1f} ns {partition / full:7.2f} {diff:14.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Timing the generated C from C: a small driver, compiled here, no Python in the loop.

For each robot the driver times every kernel that has a C entry point among
``fk``, ``jacobian`` and ``ik``: one pose per call (the single-point function,
in a loop over a ring of poses) and a batch (the ``_batch`` function over all
poses), each repeated and reported as the median in nanoseconds per pose.  With
``rtb_ik_source`` it also times the Robotics Toolbox's generated closed-form C
for the Puma 560 (``analytic_ik().generate("c")``) on the same poses.

Everything is compiled with the flags of the built library (``build_c.py``'s
``compile_flags()``), so the figures are those of ``generated.load(..., "c")``
less the Python around it.
"""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import generated
from codegen.build import load_build_script

GENERATED = Path(generated.__file__).resolve().parent
CC = os.environ.get("CC", "cc")

DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include "@ROBOT@.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

@RTB_DECLARATION@

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int compare(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *samples, int count)
{
    qsort(samples, (size_t)count, sizeof *samples, compare);
    return samples[count / 2];
}

volatile double sink;

int main(void)
{
    enum { N = @COUNT@, RING = @RING@, REPEAT = @REPEAT@, JOINTS = @JOINTS@, TASK = @TASK@ };
    static double q[N * JOINTS], T[N * 16], J[N * 6 * JOINTS], x[N * TASK];
    @IK_BUFFERS@
    double samples[REPEAT];
    int r;
    size_t i;
    srand(1);
    for (i = 0; i < (size_t)N * JOINTS; ++i) {
        q[i] = 2.0 * rand() / RAND_MAX - 1.0;
    }
    @ROBOT@_fk_batch(N, q, NULL, T);
    @ROBOT@_task_batch(N, q, NULL, x);
@TIMINGS@
    return 0;
}
"""

SINGLE = r"""
    for (r = 0; r < REPEAT; ++r) {
        double start = now();
        int lap;
        for (lap = 0; lap < @LAPS@; ++lap) {
            for (i = 0; i < RING; ++i) {
                @CALL@;
            }
        }
        samples[r] = (now() - start) / ((double)@LAPS@ * RING) * 1e9;
        sink = @SINK@;
    }
    printf("%s %s single %.3f\n", "@ROBOT@", "@KERNEL@", median(samples, REPEAT));
"""

BATCH = r"""
    for (r = 0; r < REPEAT; ++r) {
        double start = now();
        @CALL@;
        samples[r] = (now() - start) / N * 1e9;
        sink = @SINK@;
    }
    printf("%s %s batch %.3f\n", "@ROBOT@", "@KERNEL@", median(samples, REPEAT));
"""


# Appended to the Toolbox's generated C (function rtb_ikine): its status enum as an int.
RTB_WRAPPER = r"""

int rtb_ikine_call(const double T[16], double solutions[IKINE_MAX_SOLUTIONS][IKINE_DOF], int *count)
{
    return (int)rtb_ikine(T, 1e-6, solutions, count);
}
"""


def _fill(text: str, **values) -> str:
    for key, value in values.items():
        text = text.replace(f"@{key.upper()}@", str(value))
    return text


def library_flags(robot: str, root: Path = GENERATED) -> list[str]:
    """The compile flags of the robot's built C library (its build_c.py decides)."""
    return list(load_build_script(root / robot).compile_flags())


def driver_source(robot: str, count: int, repeat: int, rtb_ik: bool, module=None, root: Path = GENERATED) -> str:
    """The driver's C; ``module`` (the package's numpy kernels) and ``root`` (the folder holding the
    package) for a package outside ``generated/``, such as a zoo arm's."""
    module = module or generated.load(robot)
    header = (root / robot / f"{robot}.h").read_text()
    n, m = len(module.JOINTS), len(module.TASK)
    ring = min(count, 1024)
    laps = max(1, 20000 // ring)
    timings = []
    for kernel, out in (("fk", "T"), ("jacobian", "J")):
        size = 16 if kernel == "fk" else 6 * n
        timings.append(_fill(SINGLE, call=f"{robot}_{kernel}(q + JOINTS * i, NULL, {out} + {size} * i)",
                             laps=laps, sink=f"{out}[1]", robot=robot, kernel=kernel))
        timings.append(_fill(BATCH, call=f"{robot}_{kernel}_batch(N, q, NULL, {out})", sink=f"{out}[1]",
                             robot=robot, kernel=kernel))
    ik_buffers = ""
    has_ik = re.search(rf"\b{robot}_ik\(", header) is not None
    if has_ik:
        k = max(1, len(module.BRANCHES))
        ik_buffers = f"static double Q[N * {k} * JOINTS]; static int valid[N * {k}];"
        timings.append(_fill(SINGLE, call=f"{robot}_ik(x + TASK * i, NULL, Q + {k} * JOINTS * i, valid + {k} * i)",
                             laps=laps, sink="Q[1]", robot=robot, kernel="ik"))
        timings.append(_fill(BATCH, call=f"{robot}_ik_batch(N, x, NULL, Q, valid)", sink="Q[1]",
                             robot=robot, kernel="ik"))
    rtb_declaration = ""
    if rtb_ik:
        rtb_declaration = ("int rtb_ikine_call(const double T[16], double solutions[64][6], int *count);\n"
                           "static double rtb_solutions[64][6];\nstatic int rtb_count;")
        timings.append(_fill(SINGLE, call="rtb_ikine_call(T + 16 * i, rtb_solutions, &rtb_count)", laps=laps,
                             sink="rtb_solutions[0][0] + rtb_count", robot=robot, kernel="rtb_analytic_ik"))
    return _fill(DRIVER, robot=robot, count=count, ring=ring, repeat=repeat, joints=n, task=m,
                 ik_buffers=ik_buffers, rtb_declaration=rtb_declaration, timings="".join(timings))


def time_in_c(robot: str, build: Path, count: int, repeat: int, rtb_ik_source: str | None = None,
              module=None, root: Path = GENERATED) -> dict:
    """{(kernel, mode): ns per pose} for ``robot``, from a compiled driver (see driver_source)."""
    build.mkdir(parents=True, exist_ok=True)
    flags = library_flags(robot, root)
    driver = build / f"driver_{robot}.c"
    driver.write_text(driver_source(robot, count, repeat, rtb_ik_source is not None, module, root))
    sources = [str(driver), str(root / robot / f"{robot}.c")]
    if rtb_ik_source is not None:
        rtb = build / "rtb_ik.c"
        rtb.write_text(rtb_ik_source + RTB_WRAPPER)
        sources.append(str(rtb))
    program = build / f"driver_{robot}"
    command = [CC, *[f for f in flags if f != "-std=c99"], "-std=gnu99", "-I", str(root / robot), *sources,
               "-o", str(program), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{result.stderr}")
    run = subprocess.run([str(program)], capture_output=True, text=True, check=True)
    figures = {}
    for line in run.stdout.splitlines():
        name, kernel, *mode, ns = line.split()
        figures[(kernel, mode[0] if mode else "single")] = float(ns)
    return figures

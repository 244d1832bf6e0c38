"""Two builds of one arm's C ik timed against each other in one process, in alternating blocks.

    python benchmarks/ab_c.py ARM.toml [--a REV] [--b REV] [--poses 256] [--blocks 400] [--python]

This machine's speed moves by up to 2 times within minutes, so two timings taken a minute apart
say little about a change of 10 %.  Here both builds run in one C program, on the same poses, in
alternating blocks (each block: every pose, five times; the first of each pair of blocks A, then
B, the next pair B first): per pair, the ratio B / A of their CPU times, taken at the same moment.
The median of those ratios, with its quartiles, is the figure to read; the best and median blocks
are printed too, and move with the machine.

A and B are git revisions of this repository (default: HEAD and the working tree).  Each is
checked out into a temporary folder (the working tree: as it stands), generates the arm there
(``kinegen generate --no-dynamics --no-build``), and its C kernels are compiled into a shared
object with the flags of that package's build script (no Python: the generated ``<name>.c``
alone).  The driver calls ``<name>_ik`` on the poses of random configurations (``<name>_task``
of uniform joint values in [-3, 3]; a pose task's arm).

With ``--python`` (a TOML description): the call users make instead, ``ik`` of one 4 x 4 from
Python through each package's C backend, the two packages built (renamed ``<name>_a`` and
``<name>_b``, so that one process imports both) and called in alternating blocks.

Measured with this tool: the branch-free ``kinegen_atan2`` against the branchy one it replaced
(UR5: B / A 0.77, quartiles 0.69 and 0.90, load average 3.7); a build against the same code
gave 1.001 (quartiles 0.978, 1.025) in the same minutes.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CC = os.environ.get("CC", "cc")

DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

typedef int (*ik_fn)(const double *, const void *, double *, int *);
typedef void (*task_fn)(const double *, const void *, double *);

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int ascending(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    const int poses = atoi(argv[3]), blocks = atoi(argv[4]), joints = @JOINTS@, slots = @SLOTS@;
    void *library[2];
    ik_fn ik[2];
    task_fn task;
    double *x, *Q, *times[2], *ratio, q[@JOINTS@];
    int *valid, side, i, j, block, rep;
    unsigned long long state = 99;
    if (argc != 5) {
        fprintf(stderr, "usage: ab LIBRARY_A LIBRARY_B POSES BLOCKS\n");
        return 2;
    }
    for (side = 0; side < 2; ++side) {
        library[side] = dlopen(argv[1 + side], RTLD_NOW | RTLD_LOCAL);
        if (library[side] == NULL) {
            fprintf(stderr, "%s\n", dlerror());
            return 1;
        }
        *(void **)&ik[side] = dlsym(library[side], "@NAME@_ik");
        if (ik[side] == NULL) {
            fprintf(stderr, "no @NAME@_ik in %s\n", argv[1 + side]);
            return 1;
        }
    }
    *(void **)&task = dlsym(library[0], "@NAME@_task");
    if (task == NULL) {
        fprintf(stderr, "no @NAME@_task\n");
        return 1;
    }
    x = malloc(sizeof(double) * 12 * (size_t)poses);
    Q = malloc(sizeof(double) * (size_t)(slots * joints));
    valid = malloc(sizeof(int) * (size_t)slots);
    times[0] = malloc(sizeof(double) * (size_t)blocks);
    times[1] = malloc(sizeof(double) * (size_t)blocks);
    ratio = malloc(sizeof(double) * (size_t)blocks);
    for (i = 0; i < poses; ++i) {
        for (j = 0; j < joints; ++j) {
            state = state * 6364136223846793005ull + 1442695040888963407ull;
            q[j] = ((double)(state >> 11) * 0x1p-53 * 2.0 - 1.0) * 3.0;
        }
        task(q, NULL, x + 12 * i);
    }
    for (block = 0; block < blocks; ++block) {
        for (j = 0; j < 2; ++j) {
            const int which = (block + j) & 1;
            const double start = now();
            for (rep = 0; rep < 5; ++rep) {
                for (i = 0; i < poses; ++i) {
                    ik[which](x + 12 * i, NULL, Q, valid);
                }
            }
            times[which][block] = (now() - start) / (5.0 * poses) * 1e9;
        }
        ratio[block] = times[1][block] / times[0][block];
    }
    qsort(times[0], (size_t)blocks, sizeof(double), ascending);
    qsort(times[1], (size_t)blocks, sizeof(double), ascending);
    qsort(ratio, (size_t)blocks, sizeof(double), ascending);
    printf("A: best block %.1f ns, median %.1f ns a pose\n", times[0][0], times[0][blocks / 2]);
    printf("B: best block %.1f ns, median %.1f ns a pose\n", times[1][0], times[1][blocks / 2]);
    printf("B / A, per pair of blocks: median %.3f (quartiles %.3f, %.3f)\n", ratio[blocks / 2], ratio[blocks / 4],
           ratio[3 * blocks / 4]);
    return 0;
}
"""


def say(message: str) -> None:
    print(f"[ab] {message}", file=sys.stderr, flush=True)


def checkout(revision: str | None, scratch: Path) -> Path:
    """The repository at ``revision`` (None: the working tree as it stands) in a folder of ``scratch``."""
    if revision is None:
        return REPO
    folder = scratch / f"tree-{re.sub(r'[^A-Za-z0-9]+', '-', revision)}"
    archive = subprocess.run(["git", "archive", "--format=tar", revision], cwd=REPO, capture_output=True, check=True)
    folder.mkdir()
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return folder


PYTHON_AB = r"""
import sys, time, importlib
import numpy as np
sys.path.insert(0, sys.argv[1])
names, poses_count, blocks = sys.argv[2:4], int(sys.argv[4]), int(sys.argv[5])
kernels = [importlib.import_module(name).load("c") for name in names]
q = np.random.default_rng(99).uniform(-3.0, 3.0, (poses_count, len(kernels[0].JOINTS)))
poses = list(kernels[0].fk(q))  # (4, 4) each, as users pass them
calls = [k.ik for k in kernels]

def block(ik):
    start = time.process_time()
    for _ in range(5):
        for pose in poses:
            ik(pose)
    return (time.process_time() - start) / (5 * len(poses)) * 1e9

times, ratios = [[], []], []
for b in range(blocks):
    got = {}
    for side in ((0, 1) if b % 2 == 0 else (1, 0)):
        got[side] = block(calls[side])
    times[0].append(got[0])
    times[1].append(got[1])
    ratios.append(got[1] / got[0])
for label, t in zip("AB", times):
    print(f"{label}: best block {min(t):.1f} ns, median {np.median(t):.1f} ns a call")
print(f"B / A, per pair of blocks: median {np.median(ratios):.3f} "
      f"(quartiles {np.quantile(ratios, 0.25):.3f}, {np.quantile(ratios, 0.75):.3f})")
"""


def renamed(description: Path, name: str, scratch: Path) -> Path:
    """A copy of the TOML ``description`` whose robot is called ``name``."""
    text = description.read_text(encoding="utf-8")
    if description.suffix != ".toml" or not re.search(r'(?m)^name\s*=\s*".*"\s*$', text):
        raise SystemExit("ab: --python takes a TOML description with a top-level name = \"...\" line")
    copy = scratch / f"{name}.toml"
    copy.write_text(re.sub(r'(?m)^name\s*=\s*".*"\s*$', f'name = "{name}"', text, count=1), encoding="utf-8")
    return copy


def generate(tree: Path, description: Path, out: Path, build: bool) -> None:
    env = dict(os.environ, PYTHONPATH=str(tree), KINEGEN_NO_CACHE="1")
    subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(description), "--no-dynamics",
                    *(() if build else ("--no-build",)), "--out", str(out)], cwd=tree, env=env, check=True,
                   stdout=subprocess.DEVNULL)


def build(tree: Path, description: Path, out: Path) -> tuple[Path, str, int, int]:
    """(shared object, C name, joints, ik slots) of ``description`` generated by the code in ``tree``."""
    generate(tree, description, out, build=False)
    name = next(out.glob("*.h")).stem
    found = re.search(r"Q \(\.\.\., (\d+), (\d+)\)", (out / f"{name}.c").read_text())
    if found is None:
        raise SystemExit(f"ab: {name}.c has no ik")
    slots, joints = int(found[1]), int(found[2])
    sys.path.insert(0, str(REPO))
    from codegen.build import load_build_script
    flags = [f for f in load_build_script(out).compile_flags() if f != "-DKINEGEN_PYTHON_MODULE"]
    library = out / f"lib{name}.so"
    subprocess.run([CC, *flags, "-fPIC", "-shared", str(out / f"{name}.c"), "-o", str(library), "-lm"], check=True)
    return library, name, joints, slots


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("description", type=Path, help="the arm (TOML or URDF, as kinegen generate takes it)")
    parser.add_argument("--a", default="HEAD", help="git revision of A (default HEAD)")
    parser.add_argument("--b", default=None, help="git revision of B (default: the working tree)")
    parser.add_argument("--poses", type=int, default=256)
    parser.add_argument("--blocks", type=int, default=400)
    parser.add_argument("--python", action="store_true", help="time ik of one 4 x 4 from Python instead")
    args = parser.parse_args(argv)
    description = args.description.resolve()
    with tempfile.TemporaryDirectory(prefix="kinegen-ab-") as scratch:
        scratch = Path(scratch)
        if args.python:
            stem = re.sub(r"\W", "_", description.stem)
            names = [f"{stem}_a", f"{stem}_b"]
            for name, revision in zip(names, (args.a, args.b)):
                generate(checkout(revision, scratch), renamed(description, name, scratch), scratch / name, build=True)
                say(f"{name} ({revision or 'working tree'}): built")
            script = scratch / "ab.py"
            script.write_text(PYTHON_AB)
            say(f"{args.blocks} pairs of blocks of {args.poses} calls x 5, load average {os.getloadavg()[0]:.2f}")
            subprocess.run([sys.executable, str(script), str(scratch), *names, str(args.poses), str(args.blocks)],
                           check=True)
            return 0
        built = []
        for label, revision in (("A", args.a), ("B", args.b)):
            tree = checkout(revision, scratch)
            built.append(build(tree, description, scratch / f"package_{label.lower()}"))
            say(f"{label} ({revision or 'working tree'}): built {built[-1][0].name}")
        (library_a, name, joints, slots), (library_b, name_b, _, _) = built
        if name != name_b:
            raise SystemExit(f"ab: the two builds name the arm differently ({name}, {name_b})")
        source = scratch / "ab.c"
        source.write_text(DRIVER.replace("@NAME@", name).replace("@JOINTS@", str(joints))
                          .replace("@SLOTS@", str(slots)))
        program = scratch / "ab"
        subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", str(source), "-o", str(program), "-ldl"],
                       check=True)
        say(f"{args.blocks} pairs of blocks of {args.poses} poses x 5, load average {os.getloadavg()[0]:.2f}")
        subprocess.run([str(program), str(library_a), str(library_b), str(args.poses), str(args.blocks)], check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

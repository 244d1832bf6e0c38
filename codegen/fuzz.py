"""libFuzzer over every C entry point of the generated packages (``kinegen fuzz``, ``make fuzz``).

For each package, its kernels (the SIMD layout a real build uses, which works in blocks: of
``FUZZ_BLOCK`` items, so that a batch spans full and partial blocks, with streaming stores
from ``FUZZ_STREAM_BYTES`` of output on, so that some batches stream and some do not; clang
vectorises no math call, so the results stay those of the single point) and a harness rendered from
``fuzz_driver.c.j2`` are compiled by clang with libFuzzer, AddressSanitizer and
UndefinedBehaviorSanitizer, every report fatal, and the project's strict flags, into one
program whose fuzz target ``KINEGEN_FUZZ_TARGET`` chooses: one target per entry point
the header declares (each kernel, single and batched; ``ik_numeric``; ``within_limits``), and for a
package with inverse kinematics a round trip, ``ik (round trip)``.

Inputs are bytes read as doubles, so NaN, infinities, subnormals and huge values reach
every argument and parameter.  A target fails on a sanitizer report, a crash, a hang, or
a broken contract the harness checks (see the template): single and batched results
that differ, a truth value other than 0 and 1, a valid ik branch with a joint value that
is not finite or a return value that does not count the valid branches, and in the round
trip, where the target is the task of finite joint values, a valid branch that does not
give the target back to ``TOLERANCE`` times max(1, |x|).  Each target runs for a number
of inputs and/or seconds, as many at a time as there are cores, in a scratch folder
removed afterwards, also on an error, Ctrl-C or SIGTERM (the fuzzers are stopped first).
"""
from __future__ import annotations

import concurrent.futures
import functools
import math
import os
import random
import re
import shutil
import struct
import subprocess
import tempfile
import threading
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

from .backends import TEMPLATES
from .backends.c_backend import STRICT_FLAGS, general_6r_function, numeric_ik
from .build import CompileError

__all__ = ["Argument", "Kernel", "FuzzPackage", "Target", "Result", "clang_missing", "angle_coordinates",
           "package_from_context", "targets", "fuzz", "format_table", "describe_input", "ROUND_TRIP", "INSTALL_HINT"]

CLANG = os.environ.get("CLANG", "clang")
INSTALL_HINT = "install clang with its compiler-rt runtimes: apt-get install clang libclang-rt-dev, or `make fuzz` does"
# Instrumentation of every object (the harness's, the kernels') and of the link.
FUZZ_FLAGS = ("-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g1")
# A small block, so that the batches of at most MAX_ITEMS items span a full block and a partial one;
# scalar C in blocks computes what the single point computes, bit for bit (no contraction into FMAs).
# The SIMD layout (-DKINEGEN_SIMD, which implies the blocks) adds the single point's vector sines
# and cosines and the streaming stores; those start at FUZZ_STREAM_BYTES of output here instead of
# 1 MiB, so that the larger of the harness's batches (a pose is 128 bytes) take them and the
# smaller do not.  clang 14 calls no vector math library, so the results stay bit for bit.
FUZZ_BLOCK = 4
MAX_ITEMS = 8
FUZZ_STREAM_BYTES = 256
KERNEL_FLAGS = ("-O1", "-ffp-contract=off", "-fopenmp-simd", "-DKINEGEN_SIMD", f"-DKINEGEN_BLOCK={FUZZ_BLOCK}",
                f"-DKINEGEN_STREAM_BYTES={FUZZ_STREAM_BYTES}")
# The round trip: joint values reduced to at most JOINT_BOUND (radians or metres), each parameter
# its default times 1 + a value within +-PARAM_SPREAD, and a valid branch within TOLERANCE * max(1, |x|).
JOINT_BOUND = 4.0
PARAM_SPREAD = 0.5
TOLERANCE = 1e-6
ROUND_TRIP = "ik (round trip)"
# libFuzzer: an input running longer than this (seconds) is a hang, and fails its target.
INPUT_TIMEOUT = 25


@dataclass(frozen=True)
class Argument:
    """An array argument of a kernel, or an output: its name and number of values per item."""
    name: str
    size: int
    dtype: str = "float"


@dataclass(frozen=True)
class Kernel:
    """What the harness needs of one kernel of the package's header."""
    name: str
    arguments: tuple[Argument, ...]
    outputs: tuple[Argument, ...]
    checks: bool
    is_ik: bool


@dataclass(frozen=True)
class FuzzPackage:
    """A generated package to fuzz: its folder, parameters (name, default), kernels and joints.

    ``reachable`` holds task vectors of real configurations, seeds for the raw ik target
    (raw bytes almost never make a rotation matrix, nor a point within reach);
    ``angles``, the task coordinates that are angles (the round trip compares them modulo
    2 pi: ik returns revolute joints wrapped to (-pi, pi]).
    """
    name: str
    path: Path
    params: tuple[tuple[str, float], ...]
    kernels: tuple[Kernel, ...]
    n_joints: int
    pose_task: bool
    reachable: tuple[tuple[float, ...], ...] = ()
    angles: tuple[int, ...] = ()

    @property
    def round_trip(self) -> dict | None:
        """The ik and task kernels of the round trip, or None where there is none to make."""
        by_name = {k.name: k for k in self.kernels}
        ik, task = by_name.get("ik"), by_name.get("task")
        if (self.n_joints == 0 or ik is None or task is None or len(ik.arguments) != 1
                or ik.arguments[0].size != task.outputs[0].size or task.arguments[0].size != self.n_joints):
            return None
        return {"entry": ROUND_TRIP, "ik": ik, "task": task.outputs[0], "angles": self.angles}


@dataclass(frozen=True)
class Target:
    """One fuzz target: a package's entry point and what the doubles of its inputs are.

    An input is a control byte, then one double per name of ``params`` (values, or for the
    round trip relative changes of the defaults), then ``MAX_ITEMS`` at most items of the
    arguments ``item``.
    """
    package: str
    entry: str
    params: tuple[str, ...]
    item: tuple[Argument, ...]
    params_are_changes: bool = False

    @property
    def max_len(self) -> int:
        return 1 + 8 * (len(self.params) + MAX_ITEMS * sum(a.size for a in self.item))


@dataclass(frozen=True)
class Result:
    """How one target's run went: the inputs it ran, its wall time and, if it failed, why
    (``reason`` in a line; ``failure`` the reports and the input spelled out)."""
    target: Target
    runs: int
    seconds: float
    failure: str | None = None
    reason: str = ""

    @property
    def per_second(self) -> float:
        return self.runs / self.seconds if self.seconds > 0 else 0.0


def angle_coordinates(task, joints, joint_types) -> tuple[int, ...]:
    """The indices of the task coordinates that are angles: those affine in the joint
    variables, with a revolute joint among them (the planar 3R's phi = q1 + q2 + q3, the
    AVR 3000's T = pi/2 - q1 - q2/2), as opposed to lengths and direction cosines."""
    revolute = {q for q, kind in zip(joints, joint_types) if kind == "R"}
    found = []
    for k, expression in enumerate(task):
        used = expression.free_symbols & set(joints)
        if used & revolute and all(not (expression.diff(q).free_symbols & set(joints)) for q in used):
            found.append(k)
    return tuple(found)


def package_from_context(path: Path, context: dict, reachable=(), angles=()) -> FuzzPackage:
    """The FuzzPackage of a generated package from its ``generate.robot_context`` (what the
    sanitizer run reads too): every kernel the header declares, with its arrays' sizes;
    ``reachable`` and ``angles`` as FuzzPackage has them."""
    kernels = tuple(
        Kernel(name=f["name"], arguments=tuple(Argument(a[0], len(a[1])) for a in f["arguments"]),
               outputs=tuple(Argument(o["name"], int(o["size"]), "float" if o["dtype"] == "float" else "int")
                             for o in f["outputs"]),
               checks=bool(f["checks"]), is_ik=bool(f["is_ik"]))
        for f in context["functions"])
    general = general_6r_function(context)
    if general is not None:  # a general 6R's ik, all in C: as a closed form's ik
        kernels += (Kernel(name="ik", arguments=(Argument("x", 12),),
                           outputs=(Argument("Q", 6 * context["general_6r_slots"]),
                                    Argument("valid", context["general_6r_slots"], "int")), checks=False, is_ik=True),)
    if numeric_ik(context):  # the numeric solver: x and a seed -> q and a converged flag
        n = len(context["joints"])
        kernels += (Kernel(name="ik_numeric", arguments=(Argument("x", len(context["task"])), Argument("q0", n)),
                           outputs=(Argument("q", n), Argument("converged", 1, "int")), checks=False, is_ik=False),)
    return FuzzPackage(name=context["name"], path=Path(path),
                       params=tuple((p, float(value)) for p, value in context["params"]), kernels=kernels,
                       n_joints=len(context["joints"]), pose_task=bool(context["pose_task"]),
                       reachable=tuple(tuple(float(v) for v in x) for x in reachable),
                       angles=tuple(int(k) for k in angles))


def targets(package: FuzzPackage) -> list[Target]:
    """The fuzz targets of a package, in the header's order, the round trip last."""
    names = tuple(p for p, _ in package.params)
    found = [Target(package.name, k.name, names, k.arguments) for k in package.kernels]
    if package.n_joints:
        found.append(Target(package.name, "within_limits", (), (Argument("q", package.n_joints),)))
    if package.round_trip:
        found.append(Target(package.name, ROUND_TRIP, names, (Argument("q", package.n_joints),),
                            params_are_changes=True))
    return found


@functools.lru_cache(maxsize=None)
def clang_missing() -> str | None:
    """Why the fuzzers cannot be built here (clang, or its libFuzzer and sanitizer runtimes,
    missing), with how to install them; None when a probe harness builds."""
    if shutil.which(CLANG) is None:
        return f"{CLANG} not found: kinegen fuzz needs clang with libFuzzer ({INSTALL_HINT})"
    with tempfile.TemporaryDirectory(prefix="kinegen-probe-") as scratch:
        source = Path(scratch) / "probe.c"
        source.write_text("#include <stddef.h>\n#include <stdint.h>\n"
                          "int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);\n"
                          "int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)\n"
                          "{ (void)data; (void)size; return 0; }\n")
        result = subprocess.run([CLANG, *FUZZ_FLAGS, str(source), "-o", str(Path(scratch) / "probe")],
                                capture_output=True, text=True)
    if result.returncode != 0:
        last = (result.stderr.strip().splitlines() or ["(no message)"])[-1]
        return f"{CLANG} cannot build a libFuzzer harness ({last}): {INSTALL_HINT}"
    return None


def render_harness(package: FuzzPackage) -> str:
    """The C of the package's fuzz program (fuzz_driver.c.j2)."""
    return TEMPLATES.get_template("fuzz_driver.c.j2").render(
        name=package.name, params=[p for p, _ in package.params], functions=package.kernels,
        n_joints=package.n_joints, pose_task=package.pose_task, round_trip=package.round_trip,
        max_items=MAX_ITEMS, joint_bound=repr(JOINT_BOUND), param_spread=repr(PARAM_SPREAD),
        tolerance=repr(TOLERANCE))


class _Stopped(Exception):
    """The session is being stopped (an error elsewhere, Ctrl-C or SIGTERM)."""


class _Children:
    """The compilers and fuzzers a session runs, so that stopping it ends them all."""

    def __init__(self):
        self._lock = threading.Lock()
        self._running: set[subprocess.Popen] = set()
        self._stopped = False

    def run(self, command: list[str], **options) -> tuple[int, str]:
        """Run ``command`` to its end; its exit status and its output (stdout and stderr together)."""
        with self._lock:
            if self._stopped:
                raise _Stopped
            process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                       errors="replace", **options)
            self._running.add(process)
        try:
            output, _ = process.communicate()
        finally:
            with self._lock:
                self._running.discard(process)
        if self._stopped:
            raise _Stopped
        return process.returncode, output

    def compile(self, command: list[str]) -> None:
        status, output = self.run(command)
        if status != 0:
            raise CompileError(f"{' '.join(command)} failed:\n{output}")

    def stop(self) -> None:
        """Kill every running child, and refuse to start more."""
        with self._lock:
            self._stopped = True
            for process in self._running:
                process.kill()


def build_harness(package: FuzzPackage, folder: Path, children: _Children) -> Path:
    """Compile and link the package's fuzz program in ``folder``; returns its path."""
    folder.mkdir(parents=True, exist_ok=True)
    driver = folder / "fuzz_driver.c"
    driver.write_text(render_harness(package))
    children.compile([CLANG, *STRICT_FLAGS, *FUZZ_FLAGS, *KERNEL_FLAGS, "-c", str(package.path / f"{package.name}.c"),
                      "-o", str(folder / "kernels.o")])
    children.compile([CLANG, *STRICT_FLAGS, *FUZZ_FLAGS, "-O1", "-I", str(package.path), "-c", str(driver),
                      "-o", str(folder / "driver.o")])
    program = folder / f"fuzz_{package.name}"
    children.compile([CLANG, *FUZZ_FLAGS, str(folder / "driver.o"), str(folder / "kernels.o"), "-o", str(program),
                      "-lm"])
    return program


def seed_inputs(target: Target, package: FuzzPackage) -> list[bytes]:
    """Starting inputs of a target: full batches of moderate values (within 3 in size) with the
    default parameters, as NULL and as values, and for ik and ik_numeric batches of reachable targets."""
    rng = random.Random(zlib.crc32(f"{target.package} {target.entry}".encode()))
    per_item = sum(a.size for a in target.item)
    defaults = [0.0 if target.params_are_changes else value for _, value in package.params] if target.params else []
    items = [[rng.uniform(-3.0, 3.0) for _ in range(per_item)] for _ in range(MAX_ITEMS)]
    batches = [items]
    if target.entry == "ik" and package.reachable and per_item == len(package.reachable[0]):
        batches.append([list(package.reachable[i % len(package.reachable)]) for i in range(MAX_ITEMS)])
    if target.entry == "ik_numeric" and package.reachable:  # reachable targets, seeds anywhere
        batches.append([list(package.reachable[i % len(package.reachable)])
                        + [rng.uniform(-3.0, 3.0) for _ in range(package.n_joints)] for i in range(MAX_ITEMS)])
    full = (MAX_ITEMS - 1) << 1
    seeds = []
    for batch in batches:
        values = [v for item in batch for v in item]
        for control in (full | 1, full):
            seeds.append(bytes([control]) + struct.pack(f"<{len(defaults) + len(values)}d", *defaults, *values))
    return seeds


def describe_input(target: Target, data: bytes) -> str:
    """An input of ``target`` spelled out: the control byte, the parameters and each item's arguments."""
    control = data[0] if data else 0
    count = 1 + ((control >> 1) & 7)
    body = data[1:]
    values = [struct.unpack_from("<d", body, 8 * k)[0] for k in range(len(body) // 8)]
    needed = len(target.params) + count * sum(a.size for a in target.item)
    values += [0.0] * max(0, needed - len(values))
    null = bool(control & 1) and bool(target.params)
    lines = [f"control byte 0x{control:02x}: {count} item(s)"
             + (", params NULL (the defaults)" if null else "")]
    at = len(target.params)
    if target.params:
        kind = "changes of the defaults (each reduced modulo 0.5)" if target.params_are_changes else "params"
        lines.append(f"{kind}: " + ", ".join(f"{p} = {v!r}" for p, v in zip(target.params, values)))
    for item in range(count):
        parts = []
        for argument in target.item:
            parts.append(f"{argument.name} = [{', '.join(repr(v) for v in values[at:at + argument.size])}]")
            at += argument.size
        lines.append(f"item {item}: " + "; ".join(parts))
    lines.append(f"bytes ({len(data)}): {data.hex()}")
    return "\n".join(lines)


# Lines of a fuzzer's output that explain a failure (the harness's own, the sanitizers' reports),
# and those that say it in a line, the most telling first.
_EXPLAINS = re.compile(r"kinegen fuzz:|^  \S.* = |misses the target|runtime error|ERROR: |SUMMARY: |deadly signal")
_REASONS = (
    (r"kinegen fuzz: (.*)", "{0}"),
    (r"([^\s/]+):(\d+):\d+: runtime error: (.*)", "{2} ({0}:{1})"),
    (r"SUMMARY: (\w+Sanitizer: \S+) \S*?([^\s/]+:\d+):\d+ in (\S+)", "{0} ({1}, in {2})"),
    (r"SUMMARY: (\w+Sanitizer: .*)", "{0}"),
    (r"ERROR: libFuzzer: (.*)", "{0}"),
)


def _reason(output: str, status: int) -> str:
    """A failure in a line: the harness's message, or the sanitizer's, or libFuzzer's."""
    for pattern, form in _REASONS:
        found = re.search(pattern, output)
        if found:
            return form.format(*(group.strip() for group in found.groups()))
    return f"exit status {status}"


def run_target(program: Path, target: Target, package: FuzzPackage, runs: int, seconds: float | None,
               folder: Path, children: _Children) -> Result:
    """Fuzz one target for ``runs`` inputs (and at most ``seconds``) with its own corpus in ``folder``."""
    slug = re.sub(r"\W+", "_", target.entry).strip("_")
    corpus, seeds, artifacts = folder / f"corpus-{slug}", folder / f"seeds-{slug}", folder / f"crash-{slug}"
    for path in (corpus, seeds, artifacts):
        path.mkdir(parents=True)
    for k, seed in enumerate(seed_inputs(target, package)):
        (seeds / f"seed-{k}").write_bytes(seed)
    command = [str(program), f"-runs={runs}", f"-max_len={target.max_len}", "-len_control=0",
               f"-timeout={INPUT_TIMEOUT}", f"-artifact_prefix={artifacts}/", "-print_final_stats=1"]
    if seconds is not None:
        command.append(f"-max_total_time={max(1, math.ceil(seconds))}")
    env = dict(os.environ, KINEGEN_FUZZ_TARGET=target.entry, ASAN_OPTIONS="detect_leaks=1",
               UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1")
    start = time.perf_counter()
    status, output = children.run([*command, str(corpus), str(seeds)], env=env, cwd=folder)
    elapsed = time.perf_counter() - start
    executed = re.search(r"stat::number_of_executed_units:\s*(\d+)", output)
    progress = re.findall(r"^#(\d+)\s", output, re.M)
    count = int(executed.group(1)) if executed else int(progress[-1]) if progress else 0
    if status == 0:
        return Result(target, count, elapsed)
    explained = [line.rstrip() for line in output.splitlines() if _EXPLAINS.search(line)][:24]
    crashes = sorted(artifacts.iterdir())
    reproducer = describe_input(target, crashes[0].read_bytes()) if crashes else "(no input was written)"
    seed = re.search(r"INFO: Seed: (\d+)", output)
    failure = "\n".join([f"exit status {status}" + (f", libFuzzer seed {seed.group(1)}" if seed else ""),
                         *explained, "the input:", reproducer])
    return Result(target, count, elapsed, failure, _reason(output, status))


def fuzz(packages: list[FuzzPackage], runs: int, seconds: float | None, jobs: int,
         report=lambda result: None) -> list[Result]:
    """Fuzz every target of ``packages``, ``jobs`` processes at a time; the results in target order.

    The programs are built first (the largest C first), each package's targets queued as
    soon as its program is linked; ``report(result)`` is called in this thread as each
    target finishes.  A failed compile is raised (CompileError) once the running children
    are stopped; a failed target is a result, and the others go on.
    """
    children = _Children()
    order = {(t.package, t.entry): k for k, t in enumerate(t for p in packages for t in targets(p))}
    results = []
    with tempfile.TemporaryDirectory(prefix="kinegen-fuzz-") as scratch:
        pool = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs))
        try:
            largest = sorted(packages, key=lambda p: -(p.path / f"{p.name}.c").stat().st_size)
            builds = {pool.submit(build_harness, p, Path(scratch) / p.name, children): p for p in largest}
            running = []
            for done in concurrent.futures.as_completed(builds):
                package = builds[done]
                program = done.result()
                running += [pool.submit(run_target, program, target, package, runs, seconds,
                                        Path(scratch) / package.name, children) for target in targets(package)]
            for done in concurrent.futures.as_completed(running):
                results.append(done.result())
                report(results[-1])
        except BaseException:
            children.stop()
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    return sorted(results, key=lambda r: order[(r.target.package, r.target.entry)])


def format_table(results: list[Result]) -> str:
    """package, entry point, runs, exec/s, result: one row per target, then the totals."""
    rows = [("package", "entry point", "runs", "exec/s", "result")]
    for r in results:
        verdict = "clean" if r.failure is None else f"FAILED: {r.reason}"
        rows.append((r.target.package, r.target.entry, f"{r.runs:,}", f"{r.per_second:,.0f}", verdict[:100]))
    widths = [max(len(row[c]) for row in rows) for c in range(4)]
    lines = ["  ".join([row[0].ljust(widths[0]), row[1].ljust(widths[1]), row[2].rjust(widths[2]),
                        row[3].rjust(widths[3]), row[4]]) for row in rows]
    lines.insert(1, "-" * len(lines[0]))
    failed = sum(r.failure is not None for r in results)
    lines.append(f"\n{sum(r.runs for r in results):,} inputs over {len(results)} targets; "
                 f"{len(results) - failed} clean, {failed} failed")
    return "\n".join(lines)

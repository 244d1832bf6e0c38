"""Building and checking the generated C: cffi extensions, strict warnings, sanitizers."""
from __future__ import annotations

import concurrent.futures
import functools
import hashlib
import importlib.util
import json
import os
import random
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import numpy

from .backends import TEMPLATES
from .backends.c_backend import STRICT_FLAGS
from .generate import GENERATED

__all__ = ["load_build_script", "build_extension", "build_package", "compile_strict", "point_includes",
           "sanitizer_run", "memcheck_run", "valgrind", "CompileError"]

CC = os.environ.get("CC", "cc")
# A small block in the sanitizer run, so that its batches span a full block and a partial one.
SANITIZER_BLOCK = 4


class CompileError(RuntimeError):
    """The C compiler rejected generated code (its output is in the message)."""


def _beside_output(cmd: list[str]) -> dict | None:
    """The environment for a compile: TMPDIR in the folder of its ``-o`` output (always a scratch
    folder), so that the compiler's own temporary files (cc*.s) go when the scratch folder goes,
    a killed run's too."""
    if "-o" not in cmd:
        return None
    return dict(os.environ, TMPDIR=str(Path(cmd[cmd.index("-o") + 1]).parent))


def _run(cmd: list[str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    result = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=_beside_output(cmd))
    if result.returncode != 0:
        raise CompileError(f"{' '.join(cmd)} failed:\n{result.stdout}{result.stderr}")
    return result


def load_build_script(package: Path):
    """The package's generated ``build_c.py`` as a module (its ``build()``, ``compile_flags()``, ...)."""
    package = Path(package)
    spec = importlib.util.spec_from_file_location(f"_kinegen_build_{package.name}", package / "build_c.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def build_extension(package: Path, warnings=(), fast: bool = False) -> Path:
    """Run the package's generated ``build_c.py``; returns the built extension.

    Each C source is compiled once, with ``warnings`` in front of the library's flags; ``fast``
    asks for the vectorised layout tuned to this machine (the build script's ``compile_flags``).
    """
    try:
        return load_build_script(package).build(warnings=tuple(warnings), fast=fast)
    except RuntimeError as exc:  # the build script's report of a failed compile
        raise CompileError(str(exc)) from None


@functools.lru_cache(maxsize=None)
def _compiler_identity(command: tuple[str, ...]) -> str:
    result = subprocess.run([*command, "--version"], capture_output=True, text=True)
    return " ".join(command) + "\n" + result.stdout


def _build_key(package: Path, name: str, script, fast: bool) -> str:
    """What the built extension depends on: its C and its build script, flags, compiler, Python, numpy, cffi."""
    import cffi
    digest = hashlib.sha256()
    for filename in (f"{name}.c", f"{name}.h", f"{name}_point.c", "build_c.py"):
        path = package / filename
        digest.update(filename.encode() + b"\0")
        digest.update(path.read_bytes() if path.exists() else b"(absent)")
    settings = [STRICT_FLAGS, _compile_flags(script, fast), _compiler_identity(tuple(script.compiler())),
                sys.version, sysconfig.get_config_var("EXT_SUFFIX"), numpy.__version__, cffi.__version__,
                [os.environ.get(v, "") for v in ("CFLAGS", "CPPFLAGS", "LDFLAGS", "LDSHARED")]]
    digest.update(json.dumps(settings, default=list).encode())
    return digest.hexdigest()


def _compile_flags(script, fast: bool) -> list[str]:
    """``script.compile_flags(fast)``, its probe run once per process for each distinct build script setting."""
    key = (tuple(script.CFLAGS), tuple(script.FAST_CFLAGS), script.PROBE, tuple(script.compiler()),
           os.environ.get("KINEGEN_PORTABLE", ""), os.environ.get("KINEGEN_OPT", ""), fast)
    if key not in _FLAGS:
        _FLAGS[key] = list(script.compile_flags(fast))
    return _FLAGS[key]


_FLAGS: dict = {}


def _stamp_path(package: Path, name: str) -> Path:
    return package / f"_{name}_c.stamp"


def _stamp_holds(stamp: Path, key: str) -> bool:
    """The stamp names ``key`` and the extension it records is still the file it built."""
    try:
        record = json.loads(stamp.read_text())
        extension = stamp.parent / record["extension"]
        info = extension.stat()
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return record.get("key") == key and [info.st_size, info.st_mtime_ns] == record.get("file")


def stamp_text(package: Path, name: str) -> str:
    """The build stamp of ``package`` ("" if there is none): what its extension was built from."""
    try:
        return _stamp_path(Path(package), name).read_text()
    except OSError:
        return ""


def build_package(package: Path, name: str, fast: bool = False) -> tuple[str, float]:
    """Build the cffi extension of generated ``package`` unless its build stamp says it is up to date.

    ``fast`` builds the vectorised layout for this machine (``kinegen build`` does, for
    ``generated/``); without it, the portable layout that compiles in a few seconds
    (``kinegen generate`` without ``--fast``).

    Returns ("built" or "up to date", seconds).  ``name.c`` is compiled once, with
    the strict flags in front of the library's own (that object is linked into the
    extension); the other layouts of its batched entry points are checked with the
    strict flags by the compiler's front end (-fsyntax-only), and fully, optimised
    and under the sanitizers, by ``make test`` and ``make sanitize``.  The stamp,
    ``_<name>_c.stamp`` beside the extension, is keyed on the C sources, the build
    script, the flags, the compiler, Python, numpy and cffi.
    """
    start = time.perf_counter()
    package = Path(package)
    script = load_build_script(package)
    key = _build_key(package, name, script, fast)
    stamp = _stamp_path(package, name)
    if _stamp_holds(stamp, key):
        return "up to date", time.perf_counter() - start
    stamp.unlink(missing_ok=True)
    flags = _compile_flags(script, fast)
    built_layout = "simd" if "-DKINEGEN_SIMD" in flags else "plain"
    # the front end's checks of the other layouts (0.35 s of a KR 210's) beside the build
    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
        checked = pool.submit(check_syntax, package, name, [layout for layout in LAYOUTS if layout != built_layout])
        extension = build_extension(package, warnings=STRICT_FLAGS, fast=fast)
        checked.result()
    info = extension.stat()
    record = {"key": key, "extension": extension.name, "file": [info.st_size, info.st_mtime_ns],
              "layout": built_layout}
    fd, partial = tempfile.mkstemp(dir=stamp.parent, prefix=f".{stamp.name}.", suffix=".part")
    with os.fdopen(fd, "w") as handle:
        handle.write(json.dumps(record) + "\n")
    os.replace(partial, stamp)
    return "built", time.perf_counter() - start


def build_packages(targets: list[tuple[Path, str]], jobs: int, report=lambda name, status, seconds: None,
                   fast: bool = True) -> None:
    """build_package for each (package, name), in ``jobs`` processes, the largest C source first.

    ``report(name, status, seconds)`` is called in this process as each finishes, so
    progress lines never interleave.  The first failure stops the builds not yet started
    and is raised once the running ones are done.
    """
    ordered = sorted(targets, key=lambda t: -(Path(t[0]) / f"{t[1]}.c").stat().st_size)
    if jobs <= 1 or len(ordered) <= 1:
        for package, name in ordered:
            report(name, *build_package(package, name, fast))
        return
    with concurrent.futures.ProcessPoolExecutor(max_workers=min(jobs, len(ordered))) as pool:
        futures = {pool.submit(build_package, package, name, fast): name for package, name in ordered}
        try:
            for future in concurrent.futures.as_completed(futures):
                report(futures[future], *future.result())
        except BaseException:
            for future in futures:
                future.cancel()
            raise


# The layouts of the batched entry points (see robot.c.j2): plain loops over the single
# point, blocks in scalar C, blocks vectorised with libmvec.  The last needs GCC's
# -fopenmp-simd; a compiler without it is checked in the first two.
LAYOUTS = {"plain": [], "blocked": ["-DKINEGEN_BLOCKED"], "simd": ["-DKINEGEN_SIMD", "-fopenmp-simd"]}


def extension_layout(package: Path, name: str | None = None) -> str:
    """The layout ``build_package`` compiled (strictly) into the package's extension, as its build
    stamp records it: "simd" or "plain"."""
    package = Path(package)
    try:
        return json.loads(_stamp_path(package, name or package.name).read_text())["layout"]
    except (OSError, ValueError, KeyError, TypeError):
        return "plain"


def compile_strict(package: Path, name: str, skip=()) -> None:
    """Compile ``name.c`` with ``-std=c99 -Wall -Wextra -Werror -pedantic`` in every layout but
    those in ``skip`` (objects discarded), at -O1: the flow analysis the warnings need
    (-Wmaybe-uninitialized) without the vectoriser, which made the PUMA's SIMD layout most of a
    minute; the extension's own layout is compiled strictly at its real flags by its build.

    ``name_point.c`` (the one-point entry points for Python) is held to the same flags;
    the Python and numpy headers it includes are system headers (-isystem), whose own
    warnings are not ours to fix.
    """
    with tempfile.TemporaryDirectory(prefix="kinegen-strict-") as scratch:
        for layout, flags in LAYOUTS.items():
            if layout in skip or (layout == "simd" and not _accepts(("-fopenmp-simd",))):
                continue
            _run([CC, *STRICT_FLAGS, *flags, "-O1", "-c", str(package / f"{name}.c"),
                  "-o", str(Path(scratch) / f"{name}-{layout}.o")])
        point = package / f"{name}_point.c"
        if point.exists():
            _run([CC, *STRICT_FLAGS, "-O2", *point_includes(package), "-c", str(point),
                  "-o", str(Path(scratch) / f"{name}_point.o")])


# What the generated C includes (robot.c.j2, robot.h.j2, robot_point.c.j2, the build script's
# binding): a parameter is a C identifier there, so no macro these define may name one.
GENERATED_HEADERS = ("#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION", "#include <Python.h>",
                     "#include <numpy/arrayobject.h>", "#include <math.h>", "#include <stddef.h>",
                     "#include <stdint.h>", "#include <stdio.h>", "#include <stdlib.h>", "#include <string.h>",
                     "#include <emmintrin.h>")


def header_macros(compiler: str = CC) -> set[str]:
    """The macros the generated C's headers define here (``cc -dM -E``), with the flags of a fast
    build (-march=native), but for the names that start with an underscore (never a parameter)."""
    source = "\n".join(GENERATED_HEADERS) + "\n"
    result = subprocess.run([compiler, "-std=c99", "-march=native", "-dM", "-E", "-isystem",
                             sysconfig.get_paths()["include"], "-isystem", numpy.get_include(), "-"],
                            input=source, capture_output=True, text=True, check=True)
    names = {line.split()[1].split("(")[0] for line in result.stdout.splitlines() if line.startswith("#define ")}
    return {name for name in names if not name.startswith("_")}


def point_includes(package: Path) -> list[str]:
    """The flags of ``<name>_point.c``: its body switched on (without KINEGEN_PYTHON_MODULE it is
    empty, so that ``cc -c *.c`` in a package needs no Python), the package's header, and Python's
    and numpy's as system headers (-isystem: their own warnings are not ours to fix)."""
    return ["-DKINEGEN_PYTHON_MODULE", "-I", str(package), "-isystem", sysconfig.get_paths()["include"],
            "-isystem", numpy.get_include()]


@functools.lru_cache(maxsize=None)
def _accepts(flags: tuple[str, ...]) -> bool:
    """Whether the C compiler accepts ``flags`` (probed once per process)."""
    with tempfile.TemporaryDirectory(prefix="kinegen-probe-") as scratch:
        source = Path(scratch) / "probe.c"
        source.write_text("int main(void) { return 0; }\n")
        command = [CC, *flags, str(source), "-o", str(Path(scratch) / "probe")]
        result = subprocess.run(command, capture_output=True, env=_beside_output(command))
        return result.returncode == 0


def check_syntax(package: Path, name: str, layouts) -> None:
    """The strict flags on ``name.c`` in each of ``layouts``, front end only (-fsyntax-only: a fraction of a second)."""
    for layout in layouts:
        if layout == "simd" and not _accepts(("-fopenmp-simd",)):
            continue
        _run([CC, *STRICT_FLAGS, *LAYOUTS[layout], "-fsyntax-only", str(Path(package) / f"{name}.c")])


# The sanitizer build: the kernels' plain layout at -O1 (the single-point code every plain batch
# calls: every access still instrumented, and UBSan's object-size check, which needs the
# optimiser, on); the blocked layout, the same expressions in loops over blocks, at -O0, where
# ASan instruments every access and catches any out-of-bounds one that the object-size check
# could (-O1 made it 12.5 s of the PUMA's 14 s compile; -O0 takes 3.9 s). Line tables only (-g1:
# the reports' file:line; full -g with variable tracking made the Puma's blocked layout a
# 5-minute compile); the driver, which only calls and compares, at -O0.
# The SIMD layout (in `kinegen sanitize`, see sanitizer_run) at -O0 too, with streaming stores
# from 16 bytes of output on, so that the driver's small batches take the path a batch past
# 1 MiB takes in a real build (the Puma: 10 s, where -O1 took 22 s and -O2 45 s).
SANITIZE_FLAGS = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g1")
SANITIZE_KERNEL_FLAGS = {"plain": ("-O1",), "blocked": ("-O0",), "simd": ("-O0", "-DKINEGEN_STREAM_BYTES=16")}
SANITIZE_LAYOUTS = ("plain", "blocked")
SANITIZE_DRIVER_FLAGS = ("-O0",)


def _sanitize_driver(name: str, functions: list[dict], n_joints: int, seed: int) -> str:
    """The C of the driver of the sanitizer and memcheck runs (sanitize_driver.c.j2)."""
    rng = random.Random(seed)
    inputs = [[rng.uniform(-3.0, 3.0) for _ in range(64)] for _ in range(3)]
    return TEMPLATES.get_template("sanitize_driver.c.j2").render(
        name=name, functions=functions, inputs=inputs, count=3 + SANITIZER_BLOCK, n_joints=n_joints)


def sanitizer_run(package: Path, name: str, functions: list[dict], n_joints: int, seed: int = 1,
                  layouts: tuple[str, ...] = SANITIZE_LAYOUTS) -> str:
    """Compile a driver calling every entry point under ASan and UBSan; return its output.

    The driver evaluates each kernel on a few pseudo-random inputs, single and
    batched, and exits non-zero if the two disagree bit for bit; the sanitizers
    abort on any out-of-bounds access or undefined behaviour.  It runs once per
    layout: by default with the plain batched loops and with the blocked layout (in
    scalar C, so that its results must equal the single point's exactly), with more
    items than a block.  ``"simd"`` adds the layout of a real build: its vector
    sines and cosines of the single point, and its streaming stores (from 16 bytes
    on, see SANITIZE_KERNEL_FLAGS); at -O0 nothing is vectorised, so its results
    too must equal the others' exactly.  A compiler without ``-fopenmp-simd`` skips
    it.  The driver and the layouts of the kernels compile side by side, and the
    programs run side by side.
    """
    source = _sanitize_driver(name, functions, n_joints, seed)
    layouts = tuple(layout for layout in layouts if layout != "simd" or _accepts(("-fopenmp-simd",)))
    with tempfile.TemporaryDirectory(prefix="kinegen-asan-") as scratch:
        scratch = Path(scratch)
        driver = scratch / "driver.c"
        driver.write_text(source)
        compiles = [[CC, *STRICT_FLAGS, *SANITIZE_FLAGS, *SANITIZE_DRIVER_FLAGS, "-I", str(package),
                     "-c", str(driver), "-o", str(scratch / "driver.o")]]
        compiles += [[CC, *STRICT_FLAGS, *SANITIZE_FLAGS, *SANITIZE_KERNEL_FLAGS[layout], *LAYOUTS[layout],
                      f"-DKINEGEN_BLOCK={SANITIZER_BLOCK}", "-c", str(package / f"{name}.c"),
                      "-o", str(scratch / f"{name}-{layout}.o")] for layout in layouts]
        with concurrent.futures.ThreadPoolExecutor(max_workers=len(compiles)) as pool:
            for done in [pool.submit(_run, command) for command in compiles]:
                done.result()
        for layout in layouts:
            _run([CC, *SANITIZE_FLAGS, str(scratch / "driver.o"), str(scratch / f"{name}-{layout}.o"),
                  "-o", str(scratch / f"driver-{layout}"), "-lm"])
        env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
        running = {layout: subprocess.Popen([str(scratch / f"driver-{layout}")], stdout=subprocess.PIPE,
                                            stderr=subprocess.PIPE, text=True, env=env) for layout in layouts}
        finished = {layout: (*process.communicate(), process.returncode) for layout, process in running.items()}
    outputs = {}
    for layout, (stdout, stderr, status) in finished.items():
        if status != 0 or "runtime error" in stderr or "Sanitizer" in stderr:
            raise CompileError(f"sanitizer run of {name} ({layout} batches) failed (exit {status}):\n{stdout}{stderr}")
        outputs[layout] = stdout
    first = next(iter(outputs.values()))
    differing = [layout for layout, text in outputs.items() if text != first]
    if differing:
        raise CompileError(f"{name}: the {' and '.join(outputs)} batched entry points print different results "
                           f"({', '.join(differing)} differ from {next(iter(outputs))})")
    return first


# The memcheck run: the sanitizer run's driver and the blocked layout of the kernels (the single
# points, which the plain batches loop over, and the batches in blocks of SANITIZER_BLOCK) with
# no instrumentation, at -O1 with full debug information for valgrind's reports (3.4 s for the
# Puma's blocked layout).  Any report is an error: memcheck's exit status, and --leak-check=full
# makes a leak one.
MEMCHECK_FLAGS = ("-O1", "-g")
MEMCHECK_COMMAND = ("--error-exitcode=99", "--leak-check=full", "--quiet")


def valgrind() -> str | None:
    """The valgrind command found on PATH, or None."""
    return shutil.which("valgrind")


def memcheck_run(package: Path, name: str, functions: list[dict], n_joints: int, seed: int = 1) -> str:
    """Compile the sanitizer run's driver without sanitizers and run it once under valgrind's
    memcheck; returns its output.

    memcheck sees what ASan and UBSan do not: a read of uninitialised memory (a lane of a
    partial block, an output left unwritten) that decides a branch or reaches the output,
    in code compiled as a user compiles it.  The driver compares single and batched
    results as in the sanitizer run.  Raises CompileError on any report.
    """
    command = valgrind()
    if command is None:
        raise CompileError("valgrind not found (apt-get install valgrind)")
    with tempfile.TemporaryDirectory(prefix="kinegen-memcheck-") as scratch:
        scratch = Path(scratch)
        driver = scratch / "driver.c"
        driver.write_text(_sanitize_driver(name, functions, n_joints, seed))
        _run([CC, *STRICT_FLAGS, *MEMCHECK_FLAGS, "-I", str(package), "-c", str(driver), "-o", str(scratch / "driver.o")])
        _run([CC, *STRICT_FLAGS, *MEMCHECK_FLAGS, *LAYOUTS["blocked"], f"-DKINEGEN_BLOCK={SANITIZER_BLOCK}",
              "-c", str(package / f"{name}.c"), "-o", str(scratch / f"{name}.o")])
        _run([CC, str(scratch / "driver.o"), str(scratch / f"{name}.o"), "-o", str(scratch / "driver"), "-lm"])
        result = subprocess.run([command, *MEMCHECK_COMMAND, str(scratch / "driver")], capture_output=True, text=True)
    if result.returncode != 0 or result.stderr.strip():
        # memcheck's report (it can run long: its first 60 lines), or the driver's own
        report = "\n".join(result.stderr.splitlines()[:60]) if result.stderr.strip() else result.stdout
        raise CompileError(f"memcheck run of {name} (blocked batches) failed (exit {result.returncode}):\n{report}")
    return result.stdout

"""Building and checking the generated C: cffi extensions, strict warnings, sanitizers."""
from __future__ import annotations

import functools
import importlib.util
import os
import random
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

import numpy

from .backends import TEMPLATES
from .backends.c_backend import STRICT_FLAGS
from .generate import GENERATED

__all__ = ["load_build_script", "build_extension", "compile_strict", "sanitizer_run", "CompileError"]

CC = os.environ.get("CC", "cc")
# A small block in the sanitizer run, so that its batches span a full block and a partial one.
SANITIZER_BLOCK = 4


class CompileError(RuntimeError):
    """The C compiler rejected generated code (its output is in the message)."""


def _run(cmd: list[str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    result = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
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


def build_extension(package: Path) -> Path:
    """Run the package's generated ``build_c.py``; returns the built extension."""
    return load_build_script(package).build()


# The layouts of the batched entry points (see robot.c.j2): plain loops over the single
# point, blocks in scalar C, blocks vectorised with libmvec.  The last needs GCC's
# -fopenmp-simd; a compiler without it is checked in the first two.
LAYOUTS = {"plain": [], "blocked": ["-DKINEGEN_BLOCKED"], "simd": ["-DKINEGEN_SIMD", "-fopenmp-simd"]}


def compile_strict(package: Path, name: str) -> None:
    """Compile ``name.c`` with ``-std=c99 -Wall -Wextra -Werror -pedantic`` in every layout (objects discarded).

    ``name_point.c`` (the one-point entry points for Python) is held to the same flags;
    the Python and numpy headers it includes are system headers (-isystem), whose own
    warnings are not ours to fix.
    """
    with tempfile.TemporaryDirectory(prefix="kinegen-strict-") as scratch:
        for layout, flags in LAYOUTS.items():
            if layout == "simd" and not _accepts(("-fopenmp-simd",)):
                continue
            _run([CC, *STRICT_FLAGS, *flags, "-O2", "-c", str(package / f"{name}.c"),
                  "-o", str(Path(scratch) / f"{name}-{layout}.o")])
        point = package / f"{name}_point.c"
        if point.exists():
            _run([CC, *STRICT_FLAGS, "-O2", "-I", str(package), "-isystem", sysconfig.get_paths()["include"],
                  "-isystem", numpy.get_include(), "-c", str(point), "-o", str(Path(scratch) / f"{name}_point.o")])


@functools.lru_cache(maxsize=None)
def _accepts(flags: tuple[str, ...]) -> bool:
    """Whether the C compiler accepts ``flags`` (probed once per process)."""
    with tempfile.TemporaryDirectory(prefix="kinegen-probe-") as scratch:
        source = Path(scratch) / "probe.c"
        source.write_text("int main(void) { return 0; }\n")
        result = subprocess.run([CC, *flags, str(source), "-o", str(Path(scratch) / "probe")], capture_output=True)
        return result.returncode == 0


def sanitizer_run(package: Path, name: str, functions: list[dict], n_joints: int, seed: int = 1) -> str:
    """Compile a driver calling every entry point under ASan and UBSan; return its output.

    The driver evaluates each kernel on a few pseudo-random inputs, single and
    batched, and exits non-zero if the two disagree bit for bit; the sanitizers
    abort on any out-of-bounds access or undefined behaviour.  It runs twice: with
    the plain batched loops and with the blocked layout (in scalar C, so that its
    results must equal the single point's exactly), with more items than a block.
    """
    rng = random.Random(seed)
    inputs = [[rng.uniform(-3.0, 3.0) for _ in range(64)] for _ in range(3)]
    source = TEMPLATES.get_template("sanitize_driver.c.j2").render(
        name=name, functions=functions, inputs=inputs, count=3 + SANITIZER_BLOCK, n_joints=n_joints)
    outputs = []
    with tempfile.TemporaryDirectory(prefix="kinegen-asan-") as scratch:
        driver = Path(scratch) / "driver.c"
        driver.write_text(source)
        for layout in ("plain", "blocked"):
            exe = Path(scratch) / f"driver-{layout}"
            _run([CC, *STRICT_FLAGS, *LAYOUTS[layout], f"-DKINEGEN_BLOCK={SANITIZER_BLOCK}", "-O1", "-g",
                  "-fno-omit-frame-pointer", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                  "-I", str(package), str(driver), str(package / f"{name}.c"), "-o", str(exe), "-lm"])
            env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
            result = subprocess.run([str(exe)], capture_output=True, text=True, env=env)
            if result.returncode != 0 or "runtime error" in result.stderr or "Sanitizer" in result.stderr:
                raise CompileError(f"sanitizer run of {name} ({layout} batches) failed (exit {result.returncode}):\n"
                                   f"{result.stdout}{result.stderr}")
            outputs.append(result.stdout)
    if outputs[0] != outputs[1]:
        raise CompileError(f"{name}: the plain and blocked batched entry points print different results")
    return outputs[0]

"""Building and checking the generated C: cffi extensions, strict warnings, sanitizers."""
from __future__ import annotations

import importlib.util
import os
import random
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from .backends import TEMPLATES
from .backends.c_backend import STRICT_FLAGS
from .generate import GENERATED

__all__ = ["build_extension", "compile_strict", "sanitizer_run", "CompileError"]

CC = os.environ.get("CC", "cc")


class CompileError(RuntimeError):
    """The C compiler rejected generated code (its output is in the message)."""


def _run(cmd: list[str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    result = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if result.returncode != 0:
        raise CompileError(f"{' '.join(cmd)} failed:\n{result.stdout}{result.stderr}")
    return result


def build_extension(package: Path) -> Path:
    """Run the package's generated ``build_c.py``; returns the built extension."""
    spec = importlib.util.spec_from_file_location(f"_kinegen_build_{package.name}", package / "build_c.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.build()


def compile_strict(package: Path, name: str) -> None:
    """Compile ``name.c`` with ``-std=c99 -Wall -Wextra -Werror -pedantic`` (object discarded)."""
    with tempfile.TemporaryDirectory(prefix="kinegen-strict-") as scratch:
        _run([CC, *STRICT_FLAGS, "-O2", "-c", str(package / f"{name}.c"), "-o", str(Path(scratch) / f"{name}.o")])


def sanitizer_run(package: Path, name: str, functions: list[dict], n_joints: int, seed: int = 1) -> str:
    """Compile a driver calling every entry point under ASan and UBSan; return its output.

    The driver evaluates each kernel on a few pseudo-random inputs, single and
    batched, and exits non-zero if the two disagree; the sanitizers abort on any
    out-of-bounds access or undefined behaviour.
    """
    rng = random.Random(seed)
    inputs = [[rng.uniform(-3.0, 3.0) for _ in range(64)] for _ in range(3)]
    source = TEMPLATES.get_template("sanitize_driver.c.j2").render(
        name=name, functions=functions, inputs=inputs, count=3, n_joints=n_joints)
    with tempfile.TemporaryDirectory(prefix="kinegen-asan-") as scratch:
        driver = Path(scratch) / "driver.c"
        driver.write_text(source)
        exe = Path(scratch) / "driver"
        _run([CC, *STRICT_FLAGS, "-O1", "-g", "-fno-omit-frame-pointer", "-fsanitize=address,undefined",
              "-fno-sanitize-recover=all", "-I", str(package), str(driver), str(package / f"{name}.c"),
              "-o", str(exe), "-lm"])
        env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
        result = subprocess.run([str(exe)], capture_output=True, text=True, env=env)
        if result.returncode != 0 or "runtime error" in result.stderr or "Sanitizer" in result.stderr:
            raise CompileError(f"sanitizer run of {name} failed (exit {result.returncode}):\n"
                               f"{result.stdout}{result.stderr}")
        return result.stdout

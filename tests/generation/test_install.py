"""kinegen as a user installs it, and a generated package as it travels (issue #27).

The wheel is built from a copy of the checkout and installed into a fresh virtual environment
outside the repository; a package that ``kinegen generate`` wrote is copied elsewhere and installed
with ``pip install`` into another, where kinegen is not.  Nothing is downloaded: the environments
are made without pip (the dev environment's pip installs into them through ``--python``) and see
the dependencies (sympy, numpy, jinja2, cffi, setuptools) through a ``.pth`` line naming the dev
environment's site-packages.  A folder a ``.pth`` line adds is not a site folder, so the ``.pth``
files in it, the hook of kinegen's editable install among them, are not run: kinegen can come only
from the wheel (asserted).
"""
import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

import generated

REPO = Path(__file__).resolve().parents[2]
CC = os.environ.get("CC", "cc")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]

# Two small arms of our own (not the README's, which is edited for readers): the RRR in standard
# DH with a twist, the cylindrical RPP with constant thetas, prismatic joints and a tool.
RRR = """
name = "test_rrr"
title = "Three-joint RRR arm"
convention = "standard"
task = ["x", "y", "z"]
[params]
d1 = 0.4
a2 = 0.3
a3 = 0.25
[[joint]]
type = "R"
d = "d1"
alpha = "pi/2"
[[joint]]
type = "R"
a = "a2"
[[joint]]
type = "R"
a = "a3"
"""
CYLINDRICAL = """
name = "test_cyl"
title = "Cylindrical RPP arm"
convention = "standard"
task = ["x", "y", "z"]
[params]
d1 = 0.5
[[joint]]
type = "R"
d = "d1"
[[joint]]
type = "P"
theta = "-pi/2"
alpha = "-pi/2"
[[joint]]
type = "P"
[tool]
xyz = [0, 0, 0.1]
"""


def dh(theta, d, a, alpha):
    """One standard DH link: Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])


def rrr_by_hand(q):
    return dh(q[0], 0.4, 0.0, np.pi / 2) @ dh(q[1], 0.0, 0.3, 0.0) @ dh(q[2], 0.0, 0.25, 0.0)


def cylindrical_by_hand(q):
    tool = np.eye(4)
    tool[2, 3] = 0.1
    return dh(q[0], 0.5, 0.0, 0.0) @ dh(-np.pi / 2, q[1], 0.0, -np.pi / 2) @ dh(0.0, q[2], 0.0, 0.0) @ tool


Q = np.random.default_rng(27).uniform(-1.0, 1.0, (5, 3))


def environment(**extra):
    """The environment of a user's shell: no PYTHONPATH, no user site, the derivation cache in
    ``extra``; no KINEGEN_OPT (`make test`'s -O0), so that the default -O2 build is the one tested."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "KINEGEN_FAST", "KINEGEN_OPT")}
    return dict(env, PYTHONNOUSERSITE="1", **extra)


def run(command, cwd, **extra):
    result = subprocess.run([str(c) for c in command], cwd=cwd, capture_output=True, text=True,
                            env=environment(**extra))
    assert result.returncode == 0, f"{' '.join(map(str, command))}:\n{result.stdout[-3000:]}{result.stderr[-3000:]}"
    return result


def fresh_venv(folder: Path) -> Path:
    """A virtual environment without pip or kinegen whose dependencies are the dev environment's; its python."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True)
    python = folder / "bin" / "python"
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    dev = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (site / "_kinegen_test_dependencies.pth").write_text("".join(f"{path}\n" for path in sorted(dev)))
    return python


def pip_install(python: Path, *args, cwd, **extra):
    return run([sys.executable, "-m", "pip", "--python", python, "install", "--no-deps",
                "--disable-pip-version-check", *args], cwd, **extra)


def python_json(python: Path, code: str, cwd: Path):
    """What ``code``, run by ``python`` in ``cwd``, prints as JSON."""
    return json.loads(run([python, "-c", code], cwd).stdout)


def outside_repository(path: Path) -> Path:
    assert REPO not in path.resolve().parents
    return path


def test_the_wheel_installs_kinegen_that_works_outside_the_repository(tmp_path):
    # A copy of the checkout as a user's clone is after `make`, with a built extension and its stamp
    # (the wheel must leave them out); building from the copy keeps pip's build/ out of the checkout.
    source = tmp_path / "clone"
    shutil.copytree(REPO, source, ignore=shutil.ignore_patterns(
        ".venv*", ".git", ".cache", ".hypothesis", ".pytest_cache", "build", "*.egg-info", "__pycache__", "plots"))
    for suffix in (sysconfig.get_config_var("EXT_SUFFIX"), ".stamp"):
        (source / "generated" / "planar_2r" / f"_planar_2r_c{suffix}").write_bytes(b"built here")
    wheels = tmp_path / "wheels"
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--disable-pip-version-check",
         "-q", "-w", wheels, source], tmp_path)
    [wheel] = wheels.glob("kinegen-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {name.split("/")[0] for name in names} - {"codegen", "derivations", "generated"} \
        == {wheel.name.split("-py3")[0] + ".dist-info"}
    assert {"derivations/ik/__init__.py", "derivations/c_macros.txt", "derivations/robots/puma560.toml",
            "codegen/backends/templates/build_c.py.j2", "codegen/backends/templates/package_setup.py.j2"} <= names
    robots = [source / "generated" / name for name in generated.ROBOTS + generated.KERNEL_SETS]
    shipped = {f"generated/{p.parent.name}/{p.name}" for robot in robots for p in robot.iterdir()
               if p.suffix in (".py", ".c", ".h", ".tex", ".toml", ".md")}
    built = {f"generated/{p.parent.name}/{p.name}" for robot in robots for p in robot.iterdir()
             if p.suffix in (".so", ".stamp")}
    assert {"generated/puma560/puma560.c", "generated/puma560/puma560.h", "generated/puma560/puma560.tex",
            "generated/puma560/pyproject.toml", "generated/puma560/README.md"} <= shipped <= names
    assert built and not built & names

    venv = tmp_path / "venv"
    python = fresh_venv(venv)
    pip_install(python, wheel, cwd=tmp_path)
    work = outside_repository(tmp_path / "work")
    work.mkdir()
    where = python_json(python, "import json, codegen, derivations, generated; "
                        "print(json.dumps([m.__file__ for m in (codegen, derivations, generated)]))", work)
    assert all(Path(path).is_relative_to(venv) for path in where), where

    assert "usage: kinegen" in run([venv / "bin" / "kinegen", "--help"], work).stdout
    fk = python_json(python, "import json, generated; "
                     "print(json.dumps(generated.load('planar_2r').fk([0.1, 0.2]).tolist()))", work)
    np.testing.assert_allclose(fk, generated.load("planar_2r").fk([0.1, 0.2]), rtol=0, atol=1e-15)

    (work / "arm.toml").write_text(RRR)
    run([venv / "bin" / "kinegen", "--quiet", "generate", "arm.toml", "--out", "pkg"], work,
        KINEGEN_CACHE=str(tmp_path / "cache"))
    result = python_json(python, f"import json, numpy, pkg; q = numpy.array({Q.tolist()}); c = pkg.load('c'); "
                         "print(json.dumps([c.fk(q).tolist(), pkg.fk(q).tolist(), c.fk(q[0]).tolist(), "
                         "c._library.__file__]))", work)
    c_batch, numpy_batch, c_point, library = result
    expected = np.stack([rrr_by_hand(q) for q in Q])
    np.testing.assert_allclose(c_batch, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(numpy_batch, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(c_point, expected[0], rtol=0, atol=1e-14)
    assert Path(library).parent == work / "pkg"


@pytest.fixture(scope="module")
def arm_package(tmp_path_factory):
    """A user's package folder ``arm`` as `kinegen generate --no-build` writes it (C not compiled);
    tests copy it before changing anything."""
    folder = outside_repository(tmp_path_factory.mktemp("generate"))
    (folder / "cyl.toml").write_text(CYLINDRICAL)
    run([sys.executable, "-m", "codegen", "--quiet", "generate", "cyl.toml", "--out", "arm", "--no-build"], folder,
        KINEGEN_CACHE=str(folder / "cache"))
    return folder / "arm"


def test_a_generated_package_installs_with_pip_where_kinegen_is_not(tmp_path, arm_package):
    elsewhere = outside_repository(tmp_path / "elsewhere")
    elsewhere.mkdir()
    shutil.copytree(arm_package, elsewhere / "moved_arm")  # a renamed folder installs under its new name
    venv = tmp_path / "venv"
    python = fresh_venv(venv)
    missing = run([python, "-c", "import importlib.util; print(importlib.util.find_spec('codegen'))"], tmp_path)
    assert missing.stdout.strip() == "None"  # kinegen is not importable here
    # KINEGEN_FAST=1 asks build_c.py for -march=native; a wheel is built portable all the same.
    result = pip_install(python, "-v", "--no-build-isolation", "./moved_arm", cwd=elsewhere, KINEGEN_FAST="1")
    log = result.stdout + result.stderr  # the build's own output, which pip -v passes on
    assert "build_c.py: moved_arm._test_cyl_c with -std=c99 -O2 -fno-math-errno\n" in log and "-march=native" not in log

    site = Path(python_json(python, "import json, sysconfig; print(json.dumps(sysconfig.get_paths()['platlib']))",
                            tmp_path))
    installed = {p.name for p in (site / "moved_arm").iterdir()}
    assert {"__init__.py", "c_kernels.py", "build_c.py", "test_cyl.h", "test_cyl.c", "README.md"} <= installed
    assert "setup.py" not in installed
    [extension] = (site / "moved_arm").glob("_test_cyl_c.*")
    assert b"_ZGV" not in extension.read_bytes()  # no call into glibc's vector sin/cos, as a fast build makes
    other = tmp_path / "other"
    other.mkdir()
    c_batch, numpy_batch, c_point, library = python_json(
        python, f"import json, numpy, moved_arm as m; q = numpy.array({Q.tolist()}); c = m.load('c'); "
        "print(json.dumps([c.fk(q).tolist(), m.fk(q).tolist(), c.fk(q[0]).tolist(), c._library.__file__]))", other)
    expected = np.stack([cylindrical_by_hand(q) for q in Q])
    np.testing.assert_allclose(c_batch, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(numpy_batch, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(c_point, expected[0], rtol=0, atol=1e-14)
    assert Path(library).parent == site / "moved_arm"


LOAD_C = """
import sys
for name in {hidden}:
    sys.modules[name] = None  # as if not installed or not built
import {package}
try:
    {package}.load("c")
except ImportError as exc:
    print(exc)
"""


def load_error(package: str, cwd: Path, hidden=()) -> str:
    """The ImportError message of ``package``'s C backend, run in a process of its own."""
    return run([sys.executable, "-c", LOAD_C.format(package=package, hidden=list(hidden))], cwd).stdout.strip()


def test_a_c_backend_that_cannot_load_names_the_fix_where_the_package_is(tmp_path, arm_package):
    shutil.copytree(arm_package, tmp_path / "arm")
    folder = tmp_path / "arm"
    not_built = load_error("arm", tmp_path)
    assert f"run `python build_c.py` in {folder} (or `pip install {folder}`)" in not_built, not_built
    assert "make build" not in not_built
    no_cffi = load_error("arm", tmp_path, hidden=["cffi", "_cffi_backend"])
    assert "needs cffi, which is not installed: run `pip install cffi`" in no_cffi, no_cffi
    # The repository's own packages are built by `make build` (the fix the message names there).
    in_repository = load_error("generated.planar_2r", REPO, hidden=["generated.planar_2r._planar_2r_c"])
    assert "run `make build` in the kinegen repository" in in_repository, in_repository
    # The fix named works: `python build_c.py` in the folder builds the extension beside the files.
    run([sys.executable, "build_c.py"], folder)
    fk = python_json(sys.executable, "import json, arm; "
                     f"print(json.dumps(arm.load('c').fk({Q[0].tolist()}).tolist()))", tmp_path)
    np.testing.assert_allclose(fk, cylindrical_by_hand(Q[0]), rtol=0, atol=1e-14)


def readme_program(folder: Path) -> str:
    """The C example of the package's README as a program that prints its first output."""
    example = re.search(r"```c\n(.*?)```", (folder / "README.md").read_text(), re.S)[1].splitlines()
    output, size = re.search(r"^(?:double|int) (\w+)\[(\d+)\];$", "\n".join(example), re.M).groups()
    includes = [line for line in example if line.startswith("#include")]
    body = [line for line in example if not line.startswith("#include")]
    return "\n".join(["#include <stdio.h>", *includes, "int main(void)", "{", "int i;", *body,
                      f'for (i = 0; i < {size}; ++i) printf("%.17g\\n", (double){output}[i]);', "return 0;", "}", ""])


@pytest.mark.parametrize("which", ["user", "planar_2r", "scorbot_path"])
def test_the_c_sources_of_a_package_build_a_c_program_without_python(tmp_path, arm_package, which):
    """`cc -c *.c` in a package folder, strictly: <name>_point.c, the Python module, compiles to
    nothing without the build script's macro; the objects and the README's C example make a program."""
    folder, name = (arm_package, "test_cyl") if which == "user" else (REPO / "generated" / which, which)
    sources = sorted(folder.glob("*.c"))
    assert {p.name for p in sources} == {f"{name}.c", f"{name}_point.c"}
    run([CC, *STRICT, "-c", *sources], tmp_path)
    (tmp_path / "main.c").write_text(readme_program(folder))
    run([CC, *STRICT, "-I", folder, "main.c", f"{name}.o", f"{name}_point.o", "-lm", "-o", "main"], tmp_path)
    printed = np.array(run([tmp_path / "main"], tmp_path).stdout.split(), dtype=float)
    if which != "scorbot_path":  # fk at q = 0 (the path's first kernel has no by-hand value to hold it to)
        expected = cylindrical_by_hand(np.zeros(3)) if which == "user" else generated.load(which).fk(np.zeros(2))
        np.testing.assert_allclose(printed.reshape(4, 4), expected, rtol=0, atol=1e-14)

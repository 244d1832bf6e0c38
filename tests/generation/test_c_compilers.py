"""The generated C under more warnings than the build asks for, with gcc and with clang.

The build holds every package's C to -std=c99 -Wall -Wextra -Werror -pedantic; here each
layout of ``<name>.c`` (build.LAYOUTS) and the ``<name>_point.c`` the build compiles with
those flags are held also to c_backend.EXTRA_WARNINGS (-Wconversion -Wshadow
-Wdouble-promotion), through the compiler's front end (-fsyntax-only: a fraction of a
second each).  clang also compiles one package in full as ``CC=clang kinegen build`` does:
its -Wpass-failed on the SIMD loops comes from the optimiser, which the front end never runs.
"""
import concurrent.futures
import os
import re
import shutil
import subprocess
import tempfile

import pytest

import derivations
from codegen import build, generate
from codegen.backends import c_backend
from codegen.backends.c_backend import EXTRA_WARNINGS, STRICT_FLAGS
from test_zoo import generated_package, generated_root  # noqa: F401  (a fixture)

PACKAGES = list(derivations.ROBOTS) + list(derivations.KERNEL_SETS)
FLAGS = (*STRICT_FLAGS, *EXTRA_WARNINGS)


def require(compiler):
    if shutil.which(compiler) is None:
        pytest.skip(f"{compiler} is not on PATH (apt-get install clang libclang-rt-dev, or `make fuzz`, installs it)")


def front_end_commands(compiler):
    """The -fsyntax-only compiles of every layout and point file of every package."""
    commands = []
    for name in PACKAGES:
        package = generate.GENERATED / name
        for flags in build.LAYOUTS.values():
            commands.append([compiler, *FLAGS, *flags, "-fsyntax-only", str(package / f"{name}.c")])
        point = package / f"{name}_point.c"
        if point.exists():
            commands.append([compiler, *FLAGS, *build.point_includes(package), "-fsyntax-only", str(point)])
    return commands


def failures(commands):
    """The commands that fail or warn, each with the compiler's message, run two at a time."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(lambda c: subprocess.run(c, capture_output=True, text=True), commands))
    return [f"{' '.join(c)}:\n{r.stderr}" for c, r in zip(commands, results) if r.returncode != 0 or r.stderr]


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_every_layout_and_point_file_compiles_under_the_extra_warnings(compiler):
    require(compiler)
    commands = front_end_commands(compiler)
    assert len(commands) >= 3 * len(PACKAGES)
    assert failures(commands) == []


def test_clang_compiles_the_vectorised_build_with_the_strict_flags(monkeypatch, tmp_path):
    """The planar 2R's C as `CC=clang kinegen build` compiles it: -O3, the vectorised layout
    where clang's probe passes; its ik's atan2 and acos loops are the ones clang does not vectorise."""
    require("clang")
    monkeypatch.setenv("CC", "clang")
    monkeypatch.delenv("KINEGEN_PORTABLE", raising=False)
    package = generate.GENERATED / "planar_2r"
    flags = build.load_build_script(package).compile_flags(fast=True)
    if "-DKINEGEN_SIMD" not in flags:
        pytest.skip("clang's probe of the vectorised layout fails here: the build would compile the plain one")
    command = ["clang", *FLAGS, *flags, "-c", str(package / "planar_2r.c"), "-o", str(tmp_path / "planar_2r.o")]
    result = subprocess.run(command, capture_output=True, text=True, env=dict(os.environ, TMPDIR=str(tmp_path)))
    assert result.returncode == 0 and result.stderr == "", result.stderr


def test_a_large_file_compiles_as_units_that_together_are_the_whole(generated_root):
    """The Kinova Jaco's C (over c_backend.SPLIT_OPERATIONS operations) builds as two units,
    ``-DKINEGEN_PART=1`` and ``=2``, side by side (c_backend.c_parts, build_c.py's PARTS): each unit
    compiles alone under the strict flags and the extra warnings in every layout, and the units'
    objects define between them exactly the global symbols of the whole file's object, each once
    (as `nm` reads them): what the header declares, so that linking the units is linking the file."""
    package = generated_package("kinova_jaco", generated_root)
    folder = os.path.dirname(package.__file__)
    source = os.path.join(folder, "kinova_jaco.c")
    with open(source) as handle:
        assert "#if !defined(KINEGEN_PART) || KINEGEN_PART == 2" in handle.read()
    assert build.load_build_script(folder).PARTS == 2
    commands = [["gcc", *FLAGS, *flags, f"-DKINEGEN_PART={part}", "-fsyntax-only", source]
                for flags in build.LAYOUTS.values() for part in (1, 2)]
    assert failures(commands) == []

    def defined(flags, target):
        subprocess.run(["gcc", *STRICT_FLAGS, "-O0", "-c", source, *flags, "-o", target], check=True)
        listing = subprocess.run(["nm", "-g", "--defined-only", target], capture_output=True, text=True, check=True)
        return [line.split()[-1] for line in listing.stdout.splitlines() if line.strip()]

    with tempfile.TemporaryDirectory() as scratch:
        whole = defined([], os.path.join(scratch, "whole.o"))
        units = [defined([f"-DKINEGEN_PART={part}"], os.path.join(scratch, f"part{part}.o")) for part in (1, 2)]
    with open(os.path.join(folder, "kinova_jaco.h")) as handle:  # what the header declares
        header = handle.read()
    declared = set(re.findall(r"^(?:extern const \w+|void|int|long|size_t) (kinova_jaco_\w+)\b", header, re.M))
    assert len(whole) == len(set(whole)) and set(whole) == declared
    assert sorted(units[0] + units[1]) == sorted(whole)
    assert "kinova_jaco_ik" in units[0] and units[1]


def test_each_unit_compiles_the_static_helpers_it_calls_and_no_other(tmp_path):
    """c_backend.prune_helpers on a file of three units: a helper called only in unit 3, one
    called only through it (another helper's block), one called in units 1 and 2, and one called
    nowhere.  Every unit, and the whole file, compiles under the strict flags: a helper compiled
    in a unit that does not call it is an unused static function (-Werror), one missing where it
    is called an implicit declaration (an error in C99).  The units define between them the
    whole file's global symbols, each once."""
    text = """#include <math.h>
@@helper h_inner@@
static double h_inner(double a) { return a * 2.0; }
@@end@@
@@helper h_outer@@
static double h_outer(double a) { return h_inner(a) + 1.0; }
@@end@@
@@helper h_shared@@
static double h_shared(double a) { return sqrt(a); }
@@end@@
@@helper h_unused@@
static double h_unused(double a) { return a; }
@@end@@
#if !defined(KINEGEN_PART) || KINEGEN_PART == 1
double k_one(double a);
double k_one(double a) { return h_shared(a); }
#endif
#if !defined(KINEGEN_PART) || KINEGEN_PART == 2
double k_two(double a);
double k_two(double a) { return h_shared(a) - 1.0; }
#endif
#if !defined(KINEGEN_PART) || KINEGEN_PART == 3
double k_three(double a);
double k_three(double a) { return h_outer(a); }
#endif
"""
    pruned = c_backend.prune_helpers(text)
    assert "h_unused" not in pruned and "@@" not in pruned
    source = tmp_path / "units.c"
    source.write_text(pruned)

    def symbols(part):
        target = tmp_path / f"part{part}.o"
        defines = [] if part is None else [f"-DKINEGEN_PART={part}"]
        result = subprocess.run(["gcc", *STRICT_FLAGS, *defines, "-c", str(source), "-o", str(target)],
                                capture_output=True, text=True)
        assert result.returncode == 0 and result.stderr == "", (part, result.stderr)
        listing = subprocess.run(["nm", "-g", "--defined-only", str(target)], capture_output=True, text=True, check=True)
        return sorted(line.split()[-1] for line in listing.stdout.splitlines() if line.strip())

    units = [symbols(part) for part in (1, 2, 3)]
    assert units == [["k_one"], ["k_two"], ["k_three"]]
    assert symbols(None) == ["k_one", "k_three", "k_two"]

"""Code generation: deterministic, fresh, warning-free and sanitizer-clean C."""
import os
import re
import subprocess
import sys

import pytest
import sympy as sp

import derivations
from codegen import build, generate
from codegen.backends.c_backend import CKernelPrinter
from codegen.backends.numpy_backend import NumpyKernelPrinter
from conftest import ROBOT_NAMES


def test_generated_tree_is_up_to_date_whatever_the_hash_seed():
    """What `make check` checks: the committed generated/ is what the derivations give, rendered here
    in a process of its own with a hash seed of its own (the committed tree was rendered with
    others): byte-identical across processes and hash seeds, the whole tree."""
    env = dict(os.environ, PYTHONHASHSEED="12345")
    result = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "check"], capture_output=True, text=True,
                            env=env, cwd=generate.REPO)
    assert result.returncode == 0 and result.stdout.strip() == "generated/ is up to date", result.stdout + result.stderr


def test_the_tree_is_the_same_rendered_in_one_process_or_several(monkeypatch):
    names = ["planar_pp", "planar_2r", "trajectory"]
    assert generate.render_tree(names, jobs=2) == generate.render_tree(names, jobs=1)
    monkeypatch.setenv("KINEGEN_JOBS", "3")
    assert generate.default_jobs() == 3
    for bad in ("0", "two"):
        monkeypatch.setenv("KINEGEN_JOBS", bad)
        with pytest.raises(ValueError, match="KINEGEN_JOBS must be a positive integer"):
            generate.default_jobs()


def test_a_robot_is_the_same_with_its_kernels_prepared_in_one_process_or_several(monkeypatch):
    """robot_context's worker processes (prepared_functions) CSE and stage each kernel and print it
    ahead for the backends: the package's every file is byte-identical to the one-process render,
    for an arm with dynamics (program-form kernels, derived in a process of their own), rates and
    checks."""
    model = derivations.load(generate.REPO / "tests" / "data" / "dynamics" / "rrp_arm.toml")
    monkeypatch.setenv("KINEGEN_JOBS", "1")
    one = generate.render_robot(model, None)
    monkeypatch.setenv("KINEGEN_JOBS", "2")
    assert generate._prepare_jobs(len(model.functions())) == 2
    contexts, forked = [], []  # the two-process render's context, kept (rather than a third render to look at)
    context, fork = generate.robot_context, generate.Forked
    monkeypatch.setattr(generate, "robot_context",
                        lambda *args, **kwargs: contexts.append((context(*args, **kwargs), kwargs)) or contexts[-1][0])
    monkeypatch.setattr(generate, "Forked", lambda function: forked.append(function) or fork(function))
    model = derivations.load(generate.REPO / "tests" / "data" / "dynamics" / "rrp_arm.toml")  # dynamics not yet derived
    assert "_dynamics" not in model.__dict__
    several = generate.render_robot(model, None)
    assert several == one and f"{model.name}.tex" in several
    [(rendered, options)] = contexts
    printed = rendered["printed"]
    assert len(printed["c"]) > 100 and len(printed["numpy"]) > 100  # the workers printed ahead
    # fk, frames, the Jacobians, task, ik were prepared beside the rates and the dynamics, the dynamics
    # derived beside the rates, the LaTeX written beside the rest: three forked processes
    assert {"fk", "jacobian", "ik"} <= options["early"].names and len(forked) == 3


def test_stale_files_are_reported(tmp_path):
    tree = generate.render_tree(["planar_2r"])
    generate.write_tree(tree, tmp_path)
    assert generate.stale_files(tree, tmp_path) == []
    (tmp_path / "planar_2r" / "planar_2r.c").write_text("/* edited by hand */\n")
    (tmp_path / "planar_2r" / "old_kernel.py").write_text("")
    assert generate.stale_files(tree, tmp_path) == [
        "planar_2r/planar_2r.c (out of date)", "planar_2r/old_kernel.py (not generated any more)"]
    generate.write_tree(tree, tmp_path)
    assert generate.stale_files(tree, tmp_path) == []


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_c_compiles_with_strict_flags_and_runs_clean_under_sanitizers(models, name):
    package = generate.GENERATED / name
    # The extension's layout was compiled with the strict flags by the build (`make build`: the fast
    # layout; `make test`: the portable one; up to date: its stamp names these sources and flags);
    # the other layouts are compiled in full here.
    assert build.build_package(package, name, fast=build.extension_layout(package) == "simd")[0] == "up to date"
    build.compile_strict(package, name, skip=(build.extension_layout(package),))
    functions = generate.entry_points(models[name])
    output = build.sanitizer_run(package, name, functions, models[name].n)
    assert output.count("\n") >= len(functions)
    # Kernels with requirements (a reach, a singularity): each computes some item, and some item fails a check.
    # The driver's batches hold 3 items plus a block (build.SANITIZER_BLOCK), so that they span blocks.
    items = 3 + build.SANITIZER_BLOCK
    failed = {f["name"]: int(re.search(rf"^{f['name']}: (\d+) of {items} items failed", output, re.M).group(1))
              for f in functions if f["checks"]}
    assert all(count < items for count in failed.values()), failed
    assert not failed or any(failed.values())


def test_the_simd_layout_streams_and_runs_clean_under_sanitizers(models):
    """`kinegen sanitize` adds the layout of a real build (vector sines and cosines of the single
    point, streaming stores): here for the planar 2R, whose streaming stores the 16-byte threshold
    of the sanitizer build makes the driver's small batches take; its results equal the plain and
    blocked layouts' exactly (at -O0 nothing is vectorised)."""
    import platform
    import shutil
    import subprocess
    package = generate.GENERATED / "planar_2r"
    if not build._accepts(("-fopenmp-simd",)):
        pytest.skip("the C compiler has no -fopenmp-simd: the SIMD layout is not built")
    assert "KINEGEN_STREAM_BYTES=16" in " ".join(build.SANITIZE_KERNEL_FLAGS["simd"])
    output = build.sanitizer_run(package, "planar_2r", generate.entry_points(models["planar_2r"]), 2,
                                 layouts=("blocked", "simd"))
    assert "fk T[0] = " in output
    # The streaming stores are in that object: the threshold does put them on the driver's path.
    objdump = shutil.which("objdump")
    if objdump and platform.machine() in ("x86_64", "AMD64"):  # SSE2's streaming stores
        import tempfile
        with tempfile.TemporaryDirectory() as scratch:
            obj = f"{scratch}/k.o"
            subprocess.run([build.CC, *build.STRICT_FLAGS, *build.SANITIZE_KERNEL_FLAGS["simd"], *build.LAYOUTS["simd"],
                            "-c", str(package / "planar_2r.c"), "-o", obj], check=True)
            assert "movntpd" in subprocess.run([objdump, "-d", obj], capture_output=True, text=True).stdout


def test_strict_compile_failure_is_reported(tmp_path):
    (tmp_path / "broken.c").write_text("int f(void) { int unused; return 0; }\n")
    with pytest.raises(build.CompileError, match="unused"):
        build.compile_strict(tmp_path, "broken")


def test_printers_fold_constants_and_avoid_pow_for_small_powers():
    x, y = sp.symbols("x y", real=True)
    c, p = CKernelPrinter(), NumpyKernelPrinter()
    assert c.doprint(x**2) == "(x*x)"
    assert c.doprint((x + y)**3) == "((x + y)*(x + y)*(x + y))"
    assert c.doprint(1 / x**2) == "1.0/(x*x)"
    assert c.doprint(y / x**2) == "y/(x*x)"  # not y/x*x
    assert p.doprint(y / x**2) == "y/(x*x)"
    assert p.doprint(x**2) == "(x*x)"
    assert c.doprint(sp.Rational(2159, 5000) * x) == "(0.4318)*x"  # one correctly rounded literal
    assert c.doprint(sp.sqrt(x)) == "sqrt(x)"
    assert p.doprint(sp.sqrt(x)) == "numpy.sqrt(x)"
    assert p.doprint(sp.Min(x, 1)) == "numpy.minimum(1, x)"


def test_no_posix_only_constants_in_generated_c():
    for name in ROBOT_NAMES:
        text = (generate.GENERATED / name / f"{name}.c").read_text()
        assert "M_PI" not in text and "pow(" not in text


def test_generated_files_say_what_they_are_generated_from():
    for name in ROBOT_NAMES:
        for filename in ("numpy_kernels.py", "c_kernels.py", f"{name}.c", f"{name}.h"):
            text = (generate.GENERATED / name / filename).read_text()
            assert f"derivations/robots/{derivations.ROBOTS[name].name} (sha256" in text
            assert "Do not edit by hand" in text


def test_templates_compiled_in_another_process_render_the_same(monkeypatch):
    """generate.TemplatesAhead: the templates compiled in a forked process and handed over render a
    package byte-identical to templates compiled where they are used; handed-over code that does not
    match its template's source (every entry moved to another template's key) is not used: jinja
    compiles those templates afresh, and the package is the same again."""
    import jinja2

    from codegen import backends
    model = derivations.load("planar_2r")

    def fresh():  # TEMPLATES as in a new process: nothing loaded yet, nothing handed over
        monkeypatch.setattr(backends.TEMPLATES, "cache", jinja2.utils.LRUCache(400))
        monkeypatch.setattr(backends.TEMPLATES, "bytecode_cache", None)

    fresh()
    reference = generate.render_robot(model, None)
    fresh()
    monkeypatch.setenv("KINEGEN_JOBS", "2")
    ahead = generate.TemplatesAhead()
    assert ahead._job is not None  # forked
    assert generate.render_robot(model, None, templates=ahead) == reference
    assert ahead._job is None and len(backends.TEMPLATES.bytecode_cache.code) == len(backends.TEMPLATES.list_templates())
    code = backends.compile_templates()
    keys = sorted(code)
    moved = {key: code[keys[(k + 1) % len(keys)]] for k, key in enumerate(keys)}
    fresh()
    backends.adopt_templates(moved)
    assert generate.render_robot(model, None) == reference


def test_rates_and_dynamics_derived_beside_the_ik_give_the_same_package(monkeypatch):
    """generate.RatesAndMotion, as `kinegen generate` uses it: derivations.load calls it with the model
    before the ik is derived (derived afresh: the cache off), it forks a process that derives the
    rates and the dynamics, and the render takes them at its rates stage.  The package is
    byte-identical to one whose rates and dynamics the rendering process derived, no process is
    left, and a run that stops before the render (cancel) leaves none either."""
    import multiprocessing
    import time

    monkeypatch.setenv("KINEGEN_NO_CACHE", "1")
    monkeypatch.setenv("KINEGEN_JOBS", "2")
    path = generate.REPO / "tests" / "data" / "dynamics" / "rrp_arm.toml"
    reference = generate.render_robot(derivations.load(path), path)
    beside, seen = generate.RatesAndMotion(), []
    model = derivations.load(path, before_ik=lambda m: seen.append(tuple(m.ik)) or beside(m))
    assert seen == [()] and model.ik and beside.pending  # called once, before the ik
    assert "_rate_kinematics" not in model.__dict__ and "_dynamics" not in model.__dict__
    assert generate.render_robot(model, path, beside=beside) == reference
    assert not beside.pending and model.dynamics is not None
    assert multiprocessing.active_children() == []
    # cancelled while its own worker processes prepare the kernels (held there by a slow prepare):
    # the forked process leads a process group, and the group goes, workers and all
    slow = generate.prepare
    monkeypatch.setattr(generate, "prepare", lambda *args: (time.sleep(60), slow(*args))[1])
    beside = generate.RatesAndMotion()
    derivations.load(path, before_ik=beside)
    assert beside.pending
    group = beside._job._pid

    def members():
        found = []
        for entry in os.listdir("/proc"):
            try:
                with open(f"/proc/{entry}/stat") as handle:
                    fields = handle.read().rsplit(")", 1)[1].split()
            except (OSError, IndexError):
                continue
            if int(fields[2]) == group and fields[0] != "Z":  # pgrp, and not a zombie
                found.append(int(entry))
        return found

    deadline = time.monotonic() + 60
    while len(members()) < 3 and time.monotonic() < deadline:  # the process and its two workers
        time.sleep(0.05)
    assert len(members()) >= 3
    beside.cancel()
    deadline = time.monotonic() + 10
    while members() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert members() == []
    with pytest.raises(ChildProcessError):  # no forked child left (none to wait for)
        os.waitpid(-1, os.WNOHANG)


def test_the_render_workers_end_cleanly_when_done_and_when_a_budget_stops_the_parent(monkeypatch):
    """prepared_functions' worker processes: after a render, none is left; a budget that runs out in
    the parent (its alarm) stops the render at once with BudgetExceeded, and the workers go with it
    (they take SIGTERM as its default, not kinegen's handler, which in a forked copy of the parent's
    stack could block for ever: a `kinegen generate` that once hung after its last kernel)."""
    import multiprocessing
    import signal
    import time

    from codegen import cli
    from derivations.support.budget import ENFORCED, BudgetExceeded, budget
    previous = signal.signal(signal.SIGTERM, cli._terminated)  # as `kinegen` runs: SIGTERM is SystemExit
    try:
        model = derivations.load(generate.REPO / "tests" / "data" / "dynamics" / "rrp_arm.toml")
        functions = list(model.functions())
        params = tuple(str(s) for s in model.params)
        generate.prepared_functions(functions, params, jobs=2)
        assert multiprocessing.active_children() == []
        if not ENFORCED:
            pytest.skip("budgets are enforced only in the main thread")
        slow = generate.prepare
        monkeypatch.setattr(generate, "prepare", lambda *args: (time.sleep(30), slow(*args))[1])  # in the workers too
        start = time.perf_counter()
        with pytest.raises(BudgetExceeded):
            with budget(1.0, "a render"):
                generate.prepared_functions(functions, params, jobs=2)
        assert time.perf_counter() - start < 10
        assert multiprocessing.active_children() == []
        # a whole render, with the kernels prepared beside the derivation (EarlyKernels): the same
        monkeypatch.setenv("KINEGEN_JOBS", "2")
        start = time.perf_counter()
        with pytest.raises(BudgetExceeded):
            with budget(1.0, "a render"):
                generate.render_robot(model, None)
        assert time.perf_counter() - start < 10
        assert multiprocessing.active_children() == []
        with pytest.raises(ChildProcessError):  # no forked child left either (none to wait for)
            os.waitpid(-1, os.WNOHANG)
    finally:
        signal.signal(signal.SIGTERM, previous)

"""Command line: ``kinegen`` (also ``python -m codegen``).

    kinegen list                                  registered robots
    kinegen show ROBOT|FILE [--what W] [--latex]  the derived equations of a robot
    kinegen generate                              regenerate generated/ for every registered robot
    kinegen generate ROBOT|FILE --out DIR         a self-contained package for one robot
    kinegen build [ROBOT ...]                     strict-warning compile + cffi extension per robot
    kinegen sanitize [ROBOT ...]                  every C entry point under ASan + UBSan, then valgrind
    kinegen fuzz [ROBOT ...] [--runs N] [--seconds S]  libFuzzer over every C entry point (needs clang)
    kinegen verify [ROBOT ...]                    kernels against SymPy at 30 digits; summary table
    kinegen verify FILE --out DIR                 the same for a package made by `generate`
    kinegen check                                 fail when generated/ is not what the derivations give
    kinegen all                                   generate, build, verify (what `make` runs, with a stamp)
    kinegen latex ROBOT|FILE [--what W]            the LaTeX of a robot's derived equations (W: fk, jacobian, ik, ...)
    kinegen report                                build report/build/kinegen-report.pdf with pdflatex
    kinegen avr3000-limits [--R 18.3in] [--T 0]   the AVR 3000 Matlab script: axis velocity and acceleration
                                                  limits from motor speed limits

Progress goes to stderr; ``--quiet`` silences it.  Exit status: 0 on success,
1 when a check or a compilation fails, 2 on bad input (nothing is written then).
"""
from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import hashlib
import importlib
import io
import os
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import sympy as sp

import derivations
from derivations.support.budget import BudgetExceeded, MemoryCapExceeded, budget, memory_cap, stage
import generated

from . import avr_limits
from . import build as c_build
from . import fuzz as c_fuzz
from . import generate as gen
from . import report as tex_report
from . import show as show_equations
from .backends import latex_backend
from .verify import format_table, verify_model

__all__ = ["main"]

# One vocabulary for `show --what` and `latex --what` (codegen/show.py).
SHOW_TEXT, WHAT, LATEX_ALIASES = show_equations.SHOW_TEXT, show_equations.WHAT, show_equations.LATEX_ALIASES
SHOW = WHAT


class InputError(ValueError):
    """Bad command-line input: reported with exit status 2."""


# The budget of `generate FILE` for deriving and rendering (not compiling): a 6-joint arm
# takes seconds; a description that would take longer stops with a message naming the stage.
DEFAULT_TIME_LIMIT = 120.0
# The memory the same work may take on top of what the process holds (a 7-joint arm takes
# under 1 GiB); past it, the run stops with a message naming the stage.
DEFAULT_MEMORY_LIMIT = 8.0


def _positive(unit: str):
    """An argparse type: a positive number of ``unit`` below 1e6."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number of {unit}, got {text!r}") from None
        if not (value > 0 and value < 1e6):
            raise argparse.ArgumentTypeError(f"expected a positive number of {unit} below 1e6, got {text!r}")
        return value
    return parse


_seconds, _gib = _positive("seconds"), _positive("GiB")


def _positive_count(text: str) -> int:
    """A count given as 1000000, 1_000_000, 1,000,000 or 1e6."""
    try:
        number = float(text.replace("_", "").replace(",", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    value = int(number) if number.is_integer() and number < 1e15 else 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number below 1e15, got {text!r}")
    return value


class Progress:
    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.start = time.perf_counter()

    def __call__(self, message: str):
        if not self.quiet:
            print(f"[{time.perf_counter() - self.start:6.1f} s] {gen.terminal_text(message, MESSAGE_LIMIT)}",
                  file=sys.stderr, flush=True)


# The longest message line kinegen prints, and the longest path in one: names and paths in them come
# from the user's files.
MESSAGE_LIMIT = 1000
ECHO_PATH = 300


def _is_file(target: str) -> bool:
    return target.endswith((".toml", ".urdf", ".xacro")) or "/" in target


def _registered(names: list[str]) -> list[str]:
    """Registered robots and kernel sets (all of them when ``names`` is empty)."""
    if not names:
        return list(derivations.ROBOTS) + list(derivations.KERNEL_SETS)
    for n in names:
        if n not in derivations.ROBOTS and n not in derivations.KERNEL_SETS:
            raise InputError(f"unknown robot {n!r}; known robots: {', '.join(derivations.ROBOTS)} "
                             f"(kernel sets: {', '.join(derivations.KERNEL_SETS)}; or give a .toml description file)")
    return names


def _symbolic(name: str):
    """The model of a registered robot or kernel set."""
    return derivations.load_kernel_set(name) if name in derivations.KERNEL_SETS else derivations.load(name)


def _load(target: str, say, args=None, before_ik=None) -> tuple:
    """(model, description path) of a registered name or a description file (a URDF's
    --base, --tip and --no-snap from ``args``; ``before_ik``: derivations.load's)."""
    if not _is_file(target):
        _registered([target])
    say(f"deriving {target} (cached after the first time)")
    options = {}
    if target.endswith(".urdf") and args is not None:
        options = dict(base=getattr(args, "base", None), tip=getattr(args, "tip", None),
                       snap=not getattr(args, "no_snap", False))
    if getattr(args, "free_joint", None) is not None:
        options["free_joint"] = args.free_joint
    if getattr(args, "no_dynamics", False):
        options["dynamics"] = False
    if getattr(args, "task", None) is not None:
        options["task"] = args.task
    model = derivations.load(target, verbose=not say.quiet, before_ik=before_ik, **options)
    if target.endswith(".urdf") and (options.get("base") is None or options.get("tip") is None):
        # the chain the file's tree gave where the user named no end: say which, so that a jaw or a
        # sensor link taken as the tip is seen at once (--base and --tip cut out another)
        # (the URDF reader's title ends "(URDF, BASE to TIP)"; the file's robot name before it is free text)
        at = model.title.rfind(" (URDF, ")
        chain = model.title[at + 8:-1] if at >= 0 and model.title.endswith(")") else None
        if chain:
            say(f"{model.name}: the chain {chain.replace(' to ', ' -> ')}, {len(model.joint_names)} joints "
                f"({', '.join(model.joint_names)}); --base and --tip choose another")
    if model.notes.get("snapped"):
        say(f"{model.name}: snapped to exact values: {model.notes['snapped']}")
    path = derivations.ROBOTS[target] if target in derivations.ROBOTS and not _is_file(target) else Path(target)
    return model, path


def _default_out(model) -> Path:
    return Path.cwd() / model.name


# -- commands ---------------------------------------------------------------------------------

def cmd_list(args, say) -> int:
    width = max(len(n) for n in derivations.ROBOTS)
    for name, path in derivations.ROBOTS.items():
        if path.suffix == ".toml":
            title = derivations.formats.description.read_description(path).title
        else:  # a robot built in Python: its module's docstring names it (without deriving it)
            import ast
            title = (ast.get_docstring(ast.parse(path.read_text())) or "").split("\n")[0].split(":")[0]
        print(f"{name.ljust(width)}  {title}")
    return 0


def cmd_show(args, say) -> int:
    with _limited(args, f"{args.robot}: derivation"):
        return _show(args, say)


def _show(args, say) -> int:
    model, _ = _load(args.robot, say, args)
    try:
        return show_equations.print_model(model, args.what, args.latex)
    except show_equations.NotShown as exc:
        raise InputError(str(exc)) from None


def cmd_generate(args, say) -> int:
    gen.check_opt_level()
    backends = args.backend
    if args.out is not None or any(_is_file(t) for t in args.robots):
        if len(args.robots) != 1:
            raise InputError("generate with --out or a description file takes exactly one robot")
        out = Path(args.out) if args.out else None
        # --out is taken before the slow work: created empty by this run, or refused at once
        if out is not None:
            gen.clear_leftovers(out, say)
        claimed = gen.claim_output(out, args.force) if out is not None else False
        templates = gen.TemplatesAhead()  # compiled beside the derivation
        beside = gen.RatesAndMotion()  # the rates and the dynamics derived beside the ik
        try:
            what = f"{args.robots[0]}: derivation and rendering"
            # The steps nest in one outer step, so that a budget running out between two of them
            # (a signal is handled at the next bytecode, which may be just past a step's end)
            # still names where the run stopped.
            with budget(args.time_limit, what), memory_cap(args.memory_limit, what), \
                    stage("deriving and rendering the package"):
                with stage("deriving the model"):
                    model, path = _load(args.robots[0], say, args, before_ik=beside)
                with stage("choosing the ik method and the output folder"):
                    say(f"{model.name}: ik: {gen.ik_method(model) or 'none'}"
                        + (f" (no closed form: {model.ik_unsupported})" if model.ik_unsupported else ""))
                    if out is None:  # ./<robot name>, known once the description is read
                        out = _default_out(model)
                        gen.clear_leftovers(out, say)
                        claimed = gen.claim_output(out, args.force)
                with stage("rendering the package"):  # each rendering step names itself inside this
                    files = gen.render_robot(model, path, backends=tuple(dict.fromkeys(("numpy", *backends))),
                                             say=say, templates=templates, beside=beside)
            # As `make build` does: one strict compile of the layout the extension uses, the others
            # through the compiler's front end (a Panda: 11 s, where compiling all three took 97 s).
            build = None if args.no_build else (lambda folder: c_build.build_package(folder, model.name, args.fast))
            written = gen.write_package(model, path, out, backends=backends, force=args.force, build=build, say=say,
                                        files=files, claimed=claimed)
        except BaseException:
            if claimed:
                gen.release_output(out)
            raise
        finally:
            templates.cancel()  # (each taken by the render, unless it never came)
            beside.cancel()
        say(f"wrote {written}")
        print(gen.terminal_text(written, len(str(written))))
        return 0
    names = _registered(args.robots)
    say(f"deriving and rendering {len(names)} robot(s)")
    tree = gen.render_tree(names, verbose=not args.quiet)
    if not args.robots:
        changed = gen.write_tree(tree)
    else:
        changed = gen.write_tree({k: v for k, v in tree.items() if "/" in k}, robots=names)
    say(f"generated/: {len(changed)} file(s) changed" + (": " + ", ".join(changed) if changed else ""))
    return 0


def cmd_build(args, say) -> int:
    gen.check_opt_level()
    names = _registered(args.robots)
    jobs = gen.default_jobs()
    say(f"building {len(names)} C extension(s) in {min(jobs, len(names))} process(es), the largest first; "
        f"each C file compiled once, with {' '.join(c_build.STRICT_FLAGS)}")
    counts = {"built": 0, "up to date": 0}

    def report(name, status, seconds):
        counts[status] += 1
        if status == "built":
            say(f"{name}: built ({seconds:.1f} s)")

    c_build.build_packages([(gen.GENERATED / name, name) for name in names], jobs, report,
                           fast=not getattr(args, "portable", False))
    say(f"build: {counts['built']} built, {counts['up to date']} up to date (their build stamps hold)")
    return 0


def _sanitize_one(name: str, memcheck: bool) -> tuple[str, float]:
    """The sanitizer run of a registered robot or kernel set, then its memcheck run if
    ``memcheck`` (a worker of cmd_sanitize)."""
    start = time.perf_counter()
    model = _symbolic(name)
    functions = gen.entry_points(model)
    c_build.sanitizer_run(gen.GENERATED / name, name, functions, model.n,
                          layouts=(*c_build.SANITIZE_LAYOUTS, "simd"))
    if memcheck:
        c_build.memcheck_run(gen.GENERATED / name, name, functions, model.n)
    return name, time.perf_counter() - start


def cmd_sanitize(args, say) -> int:
    names = _registered(args.robots)
    # The largest C first: the Puma's instrumented compile is most of the run.
    names.sort(key=lambda n: -(gen.GENERATED / n / f"{n}.c").stat().st_size)
    jobs = min(gen.default_jobs(), len(names))
    memcheck = c_build.valgrind() is not None
    if not memcheck:
        print("kinegen sanitize: valgrind not found: the memcheck runs are skipped (apt-get install valgrind)",
              file=sys.stderr)
    checks = "ASan + UBSan" + (", then valgrind memcheck" if memcheck else "")
    say(f"sanitizer runs ({checks}) of every entry point of {len(names)} package(s), {jobs} at a time")
    with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
        for done in concurrent.futures.as_completed([pool.submit(_sanitize_one, name, memcheck) for name in names]):
            name, seconds = done.result()
            say(f"{name}: clean under ASan and UBSan (plain, blocked and SIMD layouts)"
                f"{' and memcheck' if memcheck else ''} ({seconds:.1f} s)")
    return 0


def _fuzz_package(name: str) -> c_fuzz.FuzzPackage:
    """What the fuzz harness of a registered robot or kernel set needs (a worker of cmd_fuzz):
    its kernels from the sanitizer run's context, reachable ik targets as seeds, and which
    task coordinates are angles."""
    model = _symbolic(name)
    context = gen.robot_context(model, "")
    reachable, angles = (), ()
    if model.n and "ik" in {f["name"] for f in context["functions"]}:
        q = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(8, model.n))
        reachable = generated.load(name).task(q)
        angles = c_fuzz.angle_coordinates(list(model.task), model.q, model.joint_types)
    return c_fuzz.package_from_context(gen.GENERATED / name, context, reachable, angles)


def cmd_fuzz(args, say) -> int:
    """libFuzzer over every C entry point of the packages (codegen/fuzz.py); a table of the runs."""
    missing = c_fuzz.clang_missing()
    if missing:
        print(f"kinegen: {missing}", file=sys.stderr)
        return 2
    names = _registered(args.robots)
    jobs = gen.default_jobs()
    with concurrent.futures.ProcessPoolExecutor(max_workers=min(jobs, len(names))) as pool:
        packages = list(pool.map(_fuzz_package, names))
    count = sum(len(c_fuzz.targets(p)) for p in packages)
    limit = f"{args.runs:,} inputs" + (f" or {args.seconds:g} s" if args.seconds else "")
    say(f"fuzzing {count} entry points of {len(packages)} package(s) with libFuzzer, ASan and UBSan, "
        f"{limit} each, {jobs} at a time")

    def report(result):
        verdict = "clean" if result.failure is None else "FAILED"
        say(f"{result.target.package} {result.target.entry}: {result.runs:,} inputs, "
            f"{result.per_second:,.0f}/s, {verdict}")

    results = c_fuzz.fuzz(packages, runs=args.runs, seconds=args.seconds, jobs=jobs, report=report)
    print(c_fuzz.format_table(results))
    failed = [r for r in results if r.failure is not None]
    for r in failed:
        print(f"\n{r.target.package} {r.target.entry} failed:\n{r.failure}")
    return 1 if failed else 0


def _package_modules(package: Path, backends: list[str]) -> dict:
    """Import a standalone package's backends by path."""
    if not (package / "numpy_kernels.py").is_file():
        raise InputError(f"{package}: no generated package here (run `kinegen generate ... --out {package}`)")
    sys.path.insert(0, str(package.resolve().parent))
    importlib.invalidate_caches()
    try:
        return {b: importlib.import_module(f"{package.name}.{'numpy_kernels' if b == 'numpy' else 'c_kernels'}")
                for b in backends}
    finally:
        sys.path.pop(0)


def _verify_one(name: str, backends: list[str], samples: int) -> list:
    """verify_model of a registered robot or kernel set in generated/ (a worker of _verify_registered)."""
    modules = {b: generated.load(name, backend=b) for b in backends}
    return verify_model(_symbolic(name), modules, samples=samples)


def _verify_registered(names: list[str], backends: list[str], samples: int, say) -> list:
    """The checks of ``names``, in that order; robots are verified in parallel processes, the largest first."""
    jobs = min(gen.default_jobs(), len(names))
    say(f"verifying {len(names)} package(s) against SymPy at 30 digits ({samples} points per kernel), "
        f"{jobs} at a time")
    if jobs <= 1:
        results = {}
        for name in names:
            say(f"{name}: verifying")
            results[name] = _verify_one(name, backends, samples)
    else:
        results = {}
        largest_first = sorted(names, key=lambda n: -(gen.GENERATED / n / f"{n}.c").stat().st_size
                               if (gen.GENERATED / n / f"{n}.c").exists() else 0)
        with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_verify_one, name, backends, samples): name for name in largest_first}
            for done in concurrent.futures.as_completed(futures):
                results[futures[done]] = done.result()
                say(f"{futures[done]}: verified ({len(results[futures[done]])} checks)")
    return [check for name in names for check in results[name]]


def cmd_verify(args, say) -> int:
    checks = []
    if any(_is_file(t) for t in args.robots) or args.out:
        if len(args.robots) != 1:
            raise InputError("verify with --out or a description file takes exactly one robot")
        with _limited(args, f"{args.robots[0]}: derivation"):
            model, _ = _load(args.robots[0], say, args)
        package = Path(args.out) if args.out else _default_out(model)
        say(f"{model.name}: verifying {package} against SymPy at 30 digits")
        checks = verify_model(model, _package_modules(package, args.backends), samples=args.samples)
    else:
        # generated/__init__.py may have been rewritten in this process (`kinegen all` with a
        # newly registered robot): read its ROBOTS afresh.
        importlib.invalidate_caches()
        importlib.reload(generated)
        checks = _verify_registered(_registered(args.robots), args.backends, args.samples, say)
    print(format_table(checks))
    failed = [c for c in checks if not c.ok]
    print(f"\n{len(checks) - len(failed)} passed, {len(failed)} failed "
          f"(tolerance 1e-12 relative against SymPy, past the rounding of the system for a run-time solve; "
          f"finite differences 1e-7)")
    return 1 if failed else 0


def cmd_check(args, say) -> int:
    say("rendering generated/ afresh to compare with the committed copy")
    stale = gen.stale_files(gen.render_tree(verbose=False))
    if stale:
        print("generated/ is out of date with derivations/ and codegen/ (run `make generate`):")
        for line in stale:
            print(f"  {line}")
        return 1
    print("generated/ is up to date")
    return 0


def cmd_latex(args, say) -> int:
    what = [LATEX_ALIASES.get(w, w) for item in args.what or [] for w in item.split(",") if w]
    textual = [w for w in what if w in ("summary", "frames", "base")]
    if textual:
        where = " (the base parameters are in the dynamics section)" if textual[0] == "base" else ""
        raise InputError(f"--what {textual[0]}: has no LaTeX section (`kinegen show --what {textual[0]}` prints it){where}")
    with _limited(args, f"{args.robot}: derivation and LaTeX"):
        model, _ = _load(args.robot, say, args)
        try:
            text = latex_backend.latex_for(model, what)
        except ValueError as exc:  # an unknown section name
            raise InputError(str(exc)) from None
    print(text, end="")
    return 0


def cmd_report(args, say) -> int:
    if args.robot is not None:
        return _robot_report(args, say)
    say(f"pdflatex {tex_report.MAIN.relative_to(gen.REPO)} -> {tex_report.BUILD.relative_to(gen.REPO)}/")
    result = tex_report.build_report()
    for warning in result.warnings:
        print(f"warning: {warning}")
    print(f"{result.pdf.relative_to(gen.REPO)}: {result.pages} pages, {len(result.warnings)} warning(s)")
    return 1 if result.warnings else 0


def _report_out(path: Path, force: bool) -> Path:
    """The PDF ``path`` of `kinegen report ROBOT`, refused (exit 2) where a file is already there
    (without --force) or its folder is missing, before any work."""
    if path.suffix != ".pdf":
        raise InputError(f"--out {gen.terminal_text(path, ECHO_PATH)}: expected a file name ending in .pdf")
    if not path.parent.is_dir():
        raise InputError(f"--out {gen.terminal_text(path, ECHO_PATH)}: no folder {gen.terminal_text(path.parent, ECHO_PATH)}")
    if (path.exists() or path.is_symlink()) and not force:
        raise gen.OutputExistsError(f"{gen.terminal_text(path, ECHO_PATH)} exists (--force replaces it)")
    return path


def _robot_report(args, say) -> int:
    """`kinegen report ROBOT|FILE`: one arm's derived equations as a PDF (its package's LaTeX)."""
    if tex_report.pdflatex() is None:
        raise InputError("pdflatex not found: install TeX Live (Debian/Ubuntu: apt-get install "
                         "texlive-latex-base texlive-latex-recommended; `make texlive` does)")
    out = _report_out(Path(args.out), args.force) if args.out else None
    with _limited(args, f"{args.robot}: derivation and LaTeX"):
        model, description = _load(args.robot, say, args)
        out = out or _report_out(Path(f"{model.name}.pdf"), args.force)
        fragments = latex_backend.render(model, gen.describe_origin(model, description))
    say(f"{model.name}: pdflatex -> {gen.terminal_text(out, ECHO_PATH)}")
    result = tex_report.build_robot_report(fragments, out)
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"wrote {gen.terminal_text(out, ECHO_PATH)}: {result.pages} pages, {len(result.warnings)} warning(s)")
    return 0


MAKE_STAMPS = gen.REPO / ".cache" / "make"


def _generate_inputs() -> str:
    """Digest of what `generate` reads and writes: derivations/, codegen/, generated/ and the versions that matter."""
    import jinja2
    digest = hashlib.sha256()
    for root, suffixes in ((Path(derivations.__file__).parent, (".py", ".toml")),
                           (Path(__file__).parent, (".py", ".j2")), (gen.GENERATED, gen.OWNED_SUFFIXES)):
        for path in sorted(root.rglob("*")):
            if path.suffix in suffixes and "__pycache__" not in path.parts and path.is_file():
                digest.update(f"{path.relative_to(gen.REPO)}\0".encode() + path.read_bytes())
    digest.update(f"{sys.version} sympy {sp.__version__} jinja2 {jinja2.__version__}".encode())
    return digest.hexdigest()


def _read_stamp(name: str) -> str | None:
    try:
        return (MAKE_STAMPS / name).read_text()
    except OSError:
        return None


def _write_stamp(name: str, text: str) -> None:
    MAKE_STAMPS.mkdir(parents=True, exist_ok=True)
    gen.atomic_write(MAKE_STAMPS / name, text)


def cmd_all(args, say) -> int:
    """generate, build, verify (the sanitizer runs are `make test`'s and `make sanitize`'s).

    For the whole tree each stage runs only if its inputs changed since the last `all`:
    generate when derivations/, codegen/ or generated/ did (a digest in .cache/make),
    build per robot by its build stamp, verify when the generated files or a built
    library did (it then prints the table of that run again).  Robots named on the
    command line are always done.  Each stage's time is printed at the end, and
    appended to the file --times names.
    """
    stages = []
    whole = not args.robots

    def finished(stage, start):
        stages.append((stage, time.perf_counter() - start))

    start = time.perf_counter()
    if whole and _read_stamp("generate") == _generate_inputs():
        say("generate: derivations/, codegen/ and generated/ unchanged since the last run: skipped "
            "(`make generate` forces it)")
    else:
        # Without the per-kernel [derive]/[cse] lines (`make generate` prints them).
        status = cmd_generate(argparse.Namespace(**{**vars(args), "quiet": True}), say)
        if status:
            return status
        if whole:
            _write_stamp("generate", _generate_inputs())
    finished("generate", start)

    start = time.perf_counter()
    status = cmd_build(args, say)
    finished("build", start)
    if status:
        return status

    start = time.perf_counter()
    names = _registered(args.robots)
    built = "".join(c_build.stamp_text(gen.GENERATED / name, name) for name in names)
    key = hashlib.sha256(f"{_read_stamp('generate')}\n{built}\n{args.samples} {args.backends} "
                         f"numpy {np.__version__}".encode()).hexdigest()
    table = _read_stamp("verify")
    if whole and table is not None and table.startswith(key + "\n"):
        say("verify: the kernels, their libraries and the derivations are those of the last run, which "
            "passed: its table follows (`make verify` runs it again)")
        print(table[len(key) + 1:], end="")
        status = 0
    else:
        output = io.StringIO()
        with contextlib.redirect_stdout(output):
            status = cmd_verify(args, say)
        print(output.getvalue(), end="")
        if whole and status == 0:
            _write_stamp("verify", f"{key}\n{output.getvalue()}")
    finished("verify", start)

    say("time per stage: " + ", ".join(f"{stage} {seconds:.1f} s" for stage, seconds in stages))
    if args.times:
        with open(args.times, "a") as handle:
            handle.writelines(f"{stage:<9} {seconds:6.1f} s\n" for stage, seconds in stages)
    return status


def _backends(text: str) -> list[str]:
    names = [b.strip() for b in text.split(",") if b.strip()]
    bad = [b for b in names if b not in ("numpy", "c")]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"unknown backend {bad[0] if bad else text!r} (expected numpy, c)")
    return names


def _version() -> str:
    """The installed distribution's version (the checkout's pyproject.toml says the same)."""
    from importlib import metadata
    try:
        return metadata.version("kinegen")
    except metadata.PackageNotFoundError:  # run from a checkout that was never installed
        import tomllib
        return tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]["version"]


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kinegen", description=__doc__.split("\n\n")[0],
                                epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    p.add_argument("--version", action="version", version=f"kinegen {_version()}")
    # --quiet is accepted after the command too (SUPPRESS keeps the top-level value otherwise).
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help="no progress output")
    sub = p.add_subparsers(dest="command", required=True, metavar="command")
    sub.add_parser("list", help="registered robots", parents=[common]).set_defaults(run=cmd_list)
    show = sub.add_parser("show", help="the derived equations of a robot", parents=[common])
    show.add_argument("robot", help="a registered robot name, a .toml description or a .urdf file")
    _urdf_options(show)
    show.add_argument("--what", choices=SHOW, default="summary", help="which quantity (default: summary)")
    show.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    _limit_options(show)
    show.set_defaults(run=cmd_show)
    for name, run, text in (
        ("generate", cmd_generate, "write generated/, or a standalone package with --out"),
        ("build", cmd_build, "compile the generated C (strict flags, cffi extension)"),
        ("sanitize", cmd_sanitize, "run every C entry point under ASan and UBSan, then valgrind's memcheck"),
        ("verify", cmd_verify, "check the kernels against SymPy"),
        ("all", cmd_all, "generate, build and verify"),
    ):
        s = sub.add_parser(name, help=text, parents=[common])
        s.add_argument("robots", nargs="*", metavar="robot", help="robot names or a .toml file (default: all)")
        if name in ("generate", "verify", "all"):
            s.add_argument("--backend", "--backends", dest="backends" if name != "generate" else "backend",
                           type=_backends, default=["numpy", "c"], help="comma-separated: numpy,c (default both)")
        if name in ("generate", "verify"):
            s.add_argument("--out", help="folder of a standalone package (default ./ROBOT_NAME)")
        if name in ("generate", "verify"):
            _urdf_options(s)
        if name == "generate":
            s.add_argument("--force", action="store_true", help="replace an existing --out folder")
            s.add_argument("--no-build", action="store_true", help="do not compile the C extension")
            s.add_argument("--fast", action="store_true",
                           help="compile the vectorised batch layout for this machine's CPU (-march=native; a "
                                "compile several times as long); default: portable C99 -O2")
        if name in ("generate", "verify"):
            _limit_options(s)
        if name == "build":
            s.add_argument("--portable", action="store_true",
                           help="the portable C99 -O2 layout (as a user's package builds; `make test` does), "
                                "not the vectorised one for this machine")
        if name in ("verify", "all"):
            s.add_argument("--samples", type=int, default=6, help="points per kernel (default 6)")
        if name == "all":
            s.set_defaults(out=None, backend=["numpy", "c"], force=False, no_build=False, fast=False,
                           time_limit=DEFAULT_TIME_LIMIT,
                           memory_limit=DEFAULT_MEMORY_LIMIT)
            s.add_argument("--times", metavar="FILE", help="append each stage's time to FILE (make does)")
        s.set_defaults(run=run)
    s = sub.add_parser("fuzz", help="libFuzzer over every C entry point (needs clang)", parents=[common])
    s.add_argument("robots", nargs="*", metavar="robot", help="robot names (default: all)")
    s.add_argument("--runs", type=_positive_count, default=1_000_000, metavar="N",
                   help="inputs per entry point (default 1,000,000)")
    s.add_argument("--seconds", type=_seconds, default=None, metavar="S",
                   help="stop each entry point's fuzzing after S seconds, whatever its inputs (default: no limit)")
    s.set_defaults(run=cmd_fuzz)
    sub.add_parser("check", help="fail when generated/ is stale", parents=[common]).set_defaults(run=cmd_check)
    s = sub.add_parser("latex", help="print the LaTeX of a robot's derived equations", parents=[common])
    s.add_argument("robot", help="robot name, .toml description or .urdf file")
    _urdf_options(s)
    s.add_argument("--what", action="append", metavar="SECTION",
                   help=f"section(s) to print, comma-separated: {', '.join(latex_backend.SECTION_KEYS)}, "
                        "or an extra a model carries (default: all)")
    _limit_options(s)
    s.set_defaults(run=cmd_latex)
    s = sub.add_parser("report", help="build the PDF report of the papers, or of one robot (needs pdflatex)",
                       parents=[common])
    s.add_argument("robot", nargs="?", help="a robot name, .toml description or .urdf file: its equations as a PDF "
                                            "(default: the papers' report, report/build/kinegen-report.pdf)")
    _urdf_options(s)
    s.add_argument("--out", metavar="PDF", help="one robot's PDF (default: NAME.pdf in the current folder)")
    s.add_argument("--force", action="store_true", help="replace an existing --out file")
    _limit_options(s)
    s.set_defaults(run=cmd_report)
    avr_limits.add_parser(sub)
    return p


def _limit_options(command) -> None:
    """--time-limit and --memory-limit, on every command that derives."""
    command.add_argument("--time-limit", type=_seconds, default=DEFAULT_TIME_LIMIT, metavar="SECONDS",
                         help=f"stop a derivation (and rendering) that runs longer (default {DEFAULT_TIME_LIMIT:g} s)")
    command.add_argument("--memory-limit", type=_gib, default=DEFAULT_MEMORY_LIMIT, metavar="GIB",
                         help="stop a derivation (and rendering) that needs more memory, in GiB "
                              f"(default {DEFAULT_MEMORY_LIMIT:g})")


@contextlib.contextmanager
def _limited(args, what: str):
    """The command's time budget and memory cap around its derivation (show, latex, verify)."""
    with budget(args.time_limit, what), memory_cap(args.memory_limit, what):
        yield


def _urdf_options(command) -> None:
    command.add_argument("--free-joint", metavar="J",
                         help="a seven-joint arm: the joint its ik holds at the argument `free`, by number (1-7) "
                              "or name (default: the first that leaves a six-joint arm with a closed form)")
    command.add_argument("--task", metavar="ITEMS",
                         help="the task ik solves, replacing the description's (a URDF's is the pose): items "
                              "separated by commas among x, y, z, phi, pitch, roll, approach, pose "
                              "(x,y,z,pitch for a 4-joint arm; x,y,z,pitch,roll or x,y,z,approach for 5 joints)")
    command.add_argument("--no-dynamics", action="store_true",
                         help="leave out the equations of motion of an arm with inertial parameters (kinematics only)")
    command.add_argument("--base", metavar="LINK", help="URDF: the link the chain starts at (default: the root)")
    command.add_argument("--tip", metavar="LINK", help="URDF: the link the chain ends at (default: the only leaf)")
    command.add_argument("--no-snap", action="store_true",
                         help="URDF: keep angles and axes as written (default: snap those within 1e-8 of "
                              "multiples of pi/2 and of coordinate axes to them exactly)")


def _terminated(signum, frame):
    """SIGTERM as SystemExit: the scratch folders and temporary files of the run are removed on the
    way out (the same paths as an error takes), and what was in place stays as it was."""
    raise SystemExit(128 + signum)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    say = Progress(args.quiet)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminated) if main_thread else None
    try:
        return _run(args, say)
    except KeyboardInterrupt:  # Ctrl-C: the same way out as SIGTERM, with a line instead of a traceback
        print("kinegen: interrupted; the run's temporary files are removed (a package or a file is replaced "
              "whole or not at all)", file=sys.stderr)
        return 128 + signal.SIGINT
    finally:
        if main_thread and previous is not None:
            signal.signal(signal.SIGTERM, previous)


def console() -> None:
    """The ``kinegen`` command (and ``python -m codegen``): :func:`main`, then the process ends
    at once with its status.  A run that derived an arm holds a few hundred MB of SymPy objects
    that the interpreter's orderly exit frees one by one (0.2-0.4 s after a KR 210's package was
    written, 2026-11-26); nothing is left to do by then but flush the output (every file was
    written whole and moved into place, and every child process was waited for).  Tests call
    :func:`main`, which returns."""
    try:
        status = main()
    except SystemExit as exc:  # argparse's --help, --version and usage errors
        status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        if exc.code is not None and not isinstance(exc.code, int):
            print(exc.code, file=sys.stderr)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


def _run(args, say) -> int:
    try:
        return args.run(args, say)
    except (derivations.DescriptionError, InputError, gen.OutputExistsError, gen.SettingError,
            gen.NotFiniteError, derivations.UnknownRobotError) as exc:
        print(f"kinegen: error: {gen.terminal_text(exc, MESSAGE_LIMIT)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `kinegen list | head -1`: the reader is gone; nothing more to say
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # the machine, not the input or our code: a read-only or full disk, a bad path
        where = exc.filename if exc.filename is not None else "an output file"
        print(f"kinegen: error: {gen.terminal_text(where, ECHO_PATH)}: {exc.strerror or exc}; nothing was "
              "written", file=sys.stderr)
        return 2
    except BudgetExceeded as exc:
        print(f"kinegen: error: {exc}; nothing was written (--time-limit SECONDS allows more)", file=sys.stderr)
        return 2
    except MemoryCapExceeded as exc:
        print(f"kinegen: error: {exc}; nothing was written (--memory-limit GIB allows more)", file=sys.stderr)
        return 2
    except tex_report.ReportError as exc:
        print(f"kinegen: {exc}", file=sys.stderr)
        return 1
    except c_build.CompileError as exc:
        print(f"kinegen: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug of ours, not bad input (bad input is refused above, with exit status 2)
        message = " ".join(str(exc).split())[:300]
        print(f"kinegen: internal error: {type(exc).__name__}: {message} (please report it, with the command "
              "and the input file; KINEGEN_TRACEBACK=1 shows where)", file=sys.stderr)
        if os.environ.get("KINEGEN_TRACEBACK"):
            raise
        return 1

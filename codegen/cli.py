"""Command line: ``python -m codegen`` (installed as ``kinegen``).

    kinegen list                      registered robots
    kinegen generate [ROBOT ...]      write generated/ (numpy, C, build scripts)
    kinegen build [ROBOT ...]         strict-warning compile + cffi extension per robot
    kinegen sanitize [ROBOT ...]      run every C entry point under ASan + UBSan
    kinegen verify [ROBOT ...]        kernels against SymPy at 30 digits; summary table
    kinegen check                     fail when generated/ is not what the derivations give
    kinegen all                       generate, build, sanitize, verify (what `make` runs)
    kinegen avr3000-limits [--R 18.3in] [--T 0] [--rpm 4500,4500,5500]
                                      the AVR 3000 Matlab script: axis velocity and
                                      acceleration limits from motor speed limits

Progress goes to stderr; ``--quiet`` silences it.  Exit status: 0 on success,
1 when a check fails, 2 on bad input.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import time

import derivations

from . import avr_limits
from . import build as c_build
from . import generate as gen
from .verify import format_table, verify_model

__all__ = ["main"]


class Progress:
    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.start = time.perf_counter()

    def __call__(self, message: str):
        if not self.quiet:
            print(f"[{time.perf_counter() - self.start:6.1f} s] {message}", file=sys.stderr, flush=True)


def _robots(names: list[str]) -> list[str]:
    if not names:
        return list(derivations.ROBOTS)
    unknown = [n for n in names if n not in derivations.ROBOTS]
    if unknown:
        raise SystemExit(_usage_error(f"unknown robot {unknown[0]!r}; known robots: {', '.join(derivations.ROBOTS)}"))
    return names


def _usage_error(message: str) -> int:
    print(f"kinegen: error: {message}", file=sys.stderr)
    return 2


def cmd_list(args, say) -> int:
    for name in derivations.ROBOTS:
        print(name)
    return 0


def cmd_generate(args, say) -> int:
    names = _robots(args.robots)
    say(f"deriving and rendering {len(names)} robot(s)")
    tree = gen.render_tree(names, verbose=not args.quiet)
    if not args.robots:
        changed = gen.write_tree(tree)
    else:
        changed = gen.write_tree({k: v for k, v in tree.items() if "/" in k}, robots=names)
    say(f"generated/: {len(changed)} file(s) changed" + (": " + ", ".join(changed) if changed else ""))
    return 0


def cmd_build(args, say) -> int:
    for name in _robots(args.robots):
        package = gen.GENERATED / name
        say(f"{name}: compiling with {' '.join(c_build.STRICT_FLAGS)}")
        c_build.compile_strict(package, name)
        say(f"{name}: building the cffi extension")
        c_build.build_extension(package)
    return 0


def cmd_sanitize(args, say) -> int:
    for name in _robots(args.robots):
        model = derivations.load(name)
        context = gen.robot_context(model, "")
        say(f"{name}: sanitizer run (ASan + UBSan) of every entry point")
        c_build.sanitizer_run(gen.GENERATED / name, name, context["functions"], model.n)
    return 0


def _modules(name: str, backends: list[str]) -> dict:
    importlib.invalidate_caches()
    return {b: importlib.import_module(f"generated.{name}.{'numpy_kernels' if b == 'numpy' else 'c_kernels'}")
            for b in backends}


def cmd_verify(args, say) -> int:
    checks = []
    for name in _robots(args.robots):
        say(f"{name}: verifying against SymPy at 30 digits ({args.samples} points per kernel)")
        checks.extend(verify_model(derivations.load(name), _modules(name, args.backends), samples=args.samples))
    print(format_table(checks))
    failed = [c for c in checks if not c.ok]
    print(f"\n{len(checks) - len(failed)} passed, {len(failed)} failed "
          f"(tolerance {checks[0].tolerance:g} relative against SymPy; finite differences 1e-7)" if checks else "")
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


def cmd_all(args, say) -> int:
    for step in (cmd_generate, cmd_build, cmd_sanitize, cmd_verify):
        status = step(args, say)
        if status:
            return status
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kinegen", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="registered robots").set_defaults(run=cmd_list)
    for name, run, text in (
        ("generate", cmd_generate, "write generated/"),
        ("build", cmd_build, "compile the generated C (strict flags, cffi extension)"),
        ("sanitize", cmd_sanitize, "run every C entry point under ASan and UBSan"),
        ("verify", cmd_verify, "check the kernels against SymPy"),
        ("all", cmd_all, "generate, build, sanitize and verify"),
    ):
        s = sub.add_parser(name, help=text)
        s.add_argument("robots", nargs="*", help="robot names (default: all)")
        if name in ("verify", "all"):
            s.add_argument("--samples", type=int, default=6, help="points per kernel (default 6)")
            s.add_argument("--backends", type=lambda v: v.split(","), default=["numpy", "c"],
                           help="comma-separated backends (default numpy,c)")
        s.set_defaults(run=run)
    sub.add_parser("check", help="fail when generated/ is stale").set_defaults(run=cmd_check)
    avr_limits.add_parser(sub)
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    say = Progress(args.quiet)
    try:
        return args.run(args, say)
    except (derivations.DescriptionError, ValueError) as exc:
        return _usage_error(str(exc))
    except c_build.CompileError as exc:
        print(f"kinegen: {exc}", file=sys.stderr)
        return 1

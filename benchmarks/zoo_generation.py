"""Cold generation time of every arm of the zoo, with its C compile (issues #14, #25, #27).

Each arm runs in a fresh process with the derivation cache off (``KINEGEN_NO_CACHE=1``), on
every core the machine gives this process (the targets are for this 2-core machine; ``--one-core``
pins each run to one core where ``taskset`` exists), as a user runs it: ``python -m codegen
generate FILE --out DIR`` (the model, the rate kinematics, the common subexpressions, the
numpy and C text, the LaTeX, then the portable C compile).  The stage times come from the
command's own progress lines; "compile" runs from its "compiling the C kernels" line to its
"wrote" line.  Targets: a 6-joint arm in 10 s, a 7-joint arm in 20 s, the whole command.
The arms are the DH zoo (tests/data/arms), the URDF files of tests/data/urdf, and the
synthetic general 6R of tests/data/synthetic (every twist, offset and length an arbitrary
decimal: the case of issue #25, which stopped at the 120 s budget before).

    python benchmarks/zoo_generation.py [--out benchmarks/zoo.md] [--one-core] [ARM ...]
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ARMS = ROOT / "tests" / "data" / "arms"
STAGE = re.compile(r"\] (?P<arm>\w+): (?P<stage>[^:]+): (?P<seconds>[\d.]+) s$")
TARGETS = {6: 10.0, 7: 20.0}


# The URDF arms of tests/data/urdf (issue #16's 10 s target for a 6-joint URDF), with their tip links.
URDFS = ROOT / "tests" / "data" / "urdf"
SYNTHETIC = ROOT / "tests" / "data" / "synthetic"
URDF_TIPS = {"ur5": "tool0", "panda": "panda_hand_tcp"}


def cores(one_core: bool) -> int:
    """How many cores a run uses: one where pinned (and taskset exists), else the process's CPUs."""
    if one_core and _has_taskset():
        return 1
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def pinned(command: list[str], one_core: bool) -> list[str]:
    """``command`` run on one core (taskset) where asked and possible."""
    return ["taskset", "-c", "0", *command] if one_core and _has_taskset() else command


def time_arm(path: Path, one_core: bool = False) -> dict:
    with tempfile.TemporaryDirectory(prefix="kinegen-zoo-") as scratch:
        command = [sys.executable, "-m", "codegen", "generate", str(path), "--out", str(Path(scratch) / "pkg"),
                   "--time-limit", "600"]
        if path.suffix == ".urdf" and path.stem in URDF_TIPS:
            command += ["--tip", URDF_TIPS[path.stem]]
        command = pinned(command, one_core)
        env = dict(os.environ, KINEGEN_NO_CACHE="1", PYTHONPATH=str(ROOT))
        start = time.perf_counter()
        result = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
        total = time.perf_counter() - start
    stages = {}
    derive = None
    compiling = wrote = None
    for line in result.stderr.splitlines():
        match = STAGE.search(line)
        if match:
            stages[match["stage"]] = float(match["seconds"])
        clock = re.match(r"\[\s*([\d.]+) s\] (.*)$", line)
        if clock and "compiling the C kernels" in clock[2]:
            compiling = float(clock[1])
        elif clock and clock[2].startswith("wrote "):
            wrote = float(clock[1])
        found = re.search(r"\[derive\] \w+: ([\d.]+) s", line)
        if found:
            derive = float(found[1])
    if compiling is not None and wrote is not None:
        stages["compile"] = wrote - compiling
    moving = re.search(r"^joints: (.*)$", subprocess.run(
        [sys.executable, "-m", "codegen", "--quiet", "show", str(path), "--what", "summary"]
        + (["--tip", URDF_TIPS[path.stem]] if path.suffix == ".urdf" and path.stem in URDF_TIPS else []),
        cwd=ROOT, capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(ROOT))).stdout, re.M)
    return {"ok": result.returncode == 0, "total": total, "model": derive, "stages": stages,
            "joints": moving[1].count("(") if moving else None,
            "error": result.stderr.strip().splitlines()[-1] if result.returncode else ""}


def _cores_text(count: int) -> str:
    return "one core" if count == 1 else f"{count} cores"


def _has_taskset() -> bool:
    return subprocess.run(["sh", "-c", "command -v taskset"], capture_output=True).returncode == 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("arms", nargs="*", help="arm names (default: every file in tests/data/arms)")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "zoo.md")
    parser.add_argument("--one-core", action="store_true", help="pin each run to one core (taskset)")
    args = parser.parse_args(argv)
    every = sorted(ARMS.glob("*.toml")) + sorted(URDFS.glob("*.urdf")) + sorted(SYNTHETIC.glob("*.toml"))
    paths = every if not args.arms else [p for p in every if p.stem in args.arms or p.name in args.arms]
    columns = ["model", "rate kinematics", "common subexpressions of every kernel", "numpy kernels",
               "c kernels", "LaTeX", "compile"]
    rows = []
    for path in paths:
        timing = time_arm(path, args.one_core)
        joints = (len(tomllib.loads(path.read_text())["joint"]) if path.suffix == ".toml"
                  else timing.get("joints"))
        target = TARGETS.get(joints)
        verdict = "-" if target is None else ("met" if timing["ok"] and timing["total"] <= target else "missed")
        cells = [f"{timing['model']:.1f}" if timing["model"] is not None else "-"]
        cells += [f"{timing['stages'][c]:.1f}" if c in timing["stages"] else "-" for c in columns[1:]]
        rows.append(f"| {path.name if path.suffix == '.urdf' else path.stem} | {joints} | " + " | ".join(cells)
                    + f" | {timing['total']:.1f} | {target if target else '-'} | {verdict} |")
        print(rows[-1], flush=True)
        if not timing["ok"]:
            print(f"  {path.stem}: {timing['error']}", file=sys.stderr)
    load = os.getloadavg() if hasattr(os, "getloadavg") else ("?",) * 3
    header = ("| arm | joints | model | rates | CSE | numpy | C | LaTeX | compile | total (s) | target (s) | |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|")
    text = (f"# Cold generation of the zoo ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"load average {load[0]:.2f})\n\n`python benchmarks/zoo_generation.py`: each arm in a fresh process, "
            f"no cache, {_cores_text(cores(args.one_core))}, `kinegen generate` with its portable C compile. Stage times in seconds; total "
            "is the whole command, Python's start and imports included.  The stages are the parent process's "
            "wait in each, read off its progress lines: since 2026-11-26 the rates, the dynamics and the kernels "
            "that need no ik are derived and prepared in a forked process while the parent derives the ik "
            "(docs/architecture.md), so rates is the parent's wait for that process and CSE what is left after "
            "it (the ik kernel's).\n\n" + header + "\n" + "\n".join(rows)
            + "\n")
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

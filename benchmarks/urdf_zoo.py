"""Real URDF files as shipped (tests/data/urdf/zoo/): how long each arm takes to generate cold,
and how far its kernels are from Pinocchio's.

Each arm of ``ZOO`` (tests/urdf_zoo.py: the file, its ``--base`` and ``--tip``) runs three times,
each in a fresh process with an empty derivation cache (``KINEGEN_CACHE`` a new folder), on every
core the machine gives it (``--one-core``: pinned to one, where ``taskset`` exists):

1. ``python -m codegen generate FILE --base B --tip T --out DIR``: derive, render, compile the C;
2. the same with ``--no-build``: derivation and rendering alone;
3. the same with ``--no-snap --no-build``: the angles and axes as written.

The totals are wall times of the whole process (Python's start and imports included); derive +
render is run 2's own clock at its "wrote" progress line, and compile is run 1's from its
"compiling the C kernels" line to "wrote" (the progress lines on stderr start ``[  t s]``).

Where Pinocchio is importable, run 1's package (numpy backend) is compared with Pinocchio's model
of the same file (``buildModelFromUrdf``): the placement of the tip link's frame relative to the
base link's, and ``computeFrameJacobian`` at the tip in LOCAL_WORLD_ALIGNED (velocity of the tip's
origin, world axes) turned into the base link's axes, on 100 random configurations within the
joint limits; the columns give the largest absolute difference of any entry.  Pinocchio reads the
numbers as written, so with snapping on (run 1) an arm differs from it by about what snapping moved.

    python benchmarks/urdf_zoo.py [--out benchmarks/urdf_zoo.md] [--one-core] [ARM ...]
"""
from __future__ import annotations

import argparse
import importlib
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from zoo_generation import ROOT, _cores_text, cores, pinned

sys.path.insert(0, str(ROOT / "tests"))
from urdf_zoo import ZOO, XmlChain, ZooArm  # noqa: E402  (tests/ is not a package)

SAMPLES = 100
PROGRESS = re.compile(r"^\[\s*(?P<seconds>[\d.]+) s\] (?P<message>.*)$")


ONE_CORE = False  # --one-core


def generate(arm: ZooArm, out: Path, *options: str) -> dict:
    """One cold ``kinegen generate`` of the arm into ``out``: wall time, progress clock, messages."""
    with tempfile.TemporaryDirectory(prefix="kinegen-urdf-zoo-cache-") as cache:
        command = [sys.executable, "-m", "codegen", "generate", str(arm.path), "--base", arm.base,
                   "--tip", arm.tip, "--out", str(out), "--time-limit", "600", *options]
        command = pinned(command, ONE_CORE)
        env = dict(os.environ, KINEGEN_CACHE=cache, PYTHONPATH=str(ROOT))
        start = time.perf_counter()
        result = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
        total = time.perf_counter() - start
    lines = [(float(m["seconds"]), m["message"]) for m in map(PROGRESS.match, result.stderr.splitlines()) if m]

    def first(text: str):
        """(clock, message) of the first progress line containing ``text``, else (None, "")."""
        return next(((s, message) for s, message in lines if text in message), (None, ""))

    snapped = first("snapped to exact values: ")[1].split("snapped to exact values: ", 1)[-1]
    return {"ok": result.returncode == 0, "total": total, "wrote": first("wrote ")[0],
            "compiling": first("compiling the C kernels")[0], "snapped": len(snapped.split("; ")) if snapped else 0,
            "error": result.stderr.strip().splitlines()[-1] if result.returncode and result.stderr.strip() else ""}


def import_package(out: Path):
    sys.path.insert(0, str(out.parent))
    importlib.invalidate_caches()
    try:
        return importlib.import_module(out.name)
    finally:
        sys.path.remove(str(out.parent))


def pinocchio_errors(pin, arm: ZooArm, kernels) -> tuple[float, float]:
    """Largest |fk - Pinocchio| and |J - Pinocchio| over SAMPLES configurations within the limits.
    The chain's joints are set in Pinocchio's configuration vector (a continuous joint as its
    cosine and sine), every other joint at its neutral value (none of them moves base or tip)."""
    model = pin.buildModelFromUrdf(str(arm.path))
    data = model.createData()
    frames = []
    for link in (arm.base, arm.tip):
        if not model.existFrame(link, pin.FrameType.BODY):
            raise ValueError(f"Pinocchio has no frame for link {link!r}")
        frames.append(model.getFrameId(link, pin.FrameType.BODY))
    base, tip = frames
    chain = XmlChain(arm.path, arm.base, arm.tip)
    joints = [model.joints[model.getJointId(name)] for name in chain.moving]
    configurations = chain.configurations(SAMPLES, 29)
    fk, jacobian = kernels.fk(configurations), kernels.jacobian(configurations)
    fk_error = jacobian_error = 0.0
    for q, T, J in zip(configurations, fk, jacobian):
        full = pin.neutral(model)
        for joint, value in zip(joints, q):
            full[joint.idx_q:joint.idx_q + joint.nq] = [math.cos(value), math.sin(value)] if joint.nq == 2 else value
        pin.forwardKinematics(model, data, full)
        pin.updateFramePlacements(model, data)
        placement = data.oMf[base].actInv(data.oMf[tip]).homogeneous
        world = pin.computeFrameJacobian(model, data, full, tip, pin.LOCAL_WORLD_ALIGNED)[:, [j.idx_v for j in joints]]
        turn = data.oMf[base].rotation.T
        expected = np.vstack([turn @ world[:3], turn @ world[3:]])
        fk_error = max(fk_error, float(np.max(np.abs(T - placement))))
        jacobian_error = max(jacobian_error, float(np.max(np.abs(J - expected))))
    return fk_error, jacobian_error


def seconds(value) -> str:
    return f"{value:.1f}" if value is not None else "-"


def row(name: str, arm: ZooArm, pin) -> str:
    with tempfile.TemporaryDirectory(prefix="kinegen-urdf-zoo-") as scratch:
        built = generate(arm, Path(scratch) / f"zoo_{name}")
        derived = generate(arm, Path(scratch) / f"zoo_{name}_numpy", "--no-build")
        written = generate(arm, Path(scratch) / f"zoo_{name}_written", "--no-build", "--no-snap")
        for run, what in ((built, "generate"), (derived, "--no-build"), (written, "--no-snap")):
            if not run["ok"]:
                print(f"  {name} ({what}): {run['error']}", file=sys.stderr)
        compile_time = (built["wrote"] - built["compiling"]
                        if built["ok"] and built["compiling"] is not None else None)
        if pin is None:
            errors = ["pinocchio not installed"] * 2
        elif not built["ok"]:
            errors = ["generation failed"] * 2
        else:
            try:
                errors = [f"{e:.1e}" for e in pinocchio_errors(pin, arm, import_package(Path(scratch) / f"zoo_{name}"))]
            except Exception as exc:  # a file Pinocchio reads differently is a result to report, not a crash
                errors = [f"Pinocchio: {' '.join(str(exc).split())[:80]}"] * 2
    cells = [name, arm.source.split(":")[0], str(arm.joints),
             seconds(built["total"]) if built["ok"] else "failed",
             seconds(derived["wrote"]) if derived["ok"] else "failed", seconds(compile_time),
             seconds(written["total"]) if written["ok"] else "failed", *errors,
             str(built["snapped"]) if built["ok"] else "-"]
    return "| " + " | ".join(cells) + " |"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("arms", nargs="*", help=f"arm names (default: all of {', '.join(ZOO)})")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "urdf_zoo.md")
    parser.add_argument("--one-core", action="store_true", help="pin each run to one core (taskset)")
    args = parser.parse_args(argv)
    global ONE_CORE
    ONE_CORE = args.one_core
    unknown = [name for name in args.arms if name not in ZOO]
    if unknown:
        parser.error(f"unknown arm(s) {', '.join(unknown)}; the zoo has {', '.join(ZOO)}")
    try:
        import pinocchio as pin
    except ImportError:
        pin = None
    rows = []
    for name in args.arms or list(ZOO):
        rows.append(row(name, ZOO[name], pin))
        print(rows[-1], flush=True)
    load = os.getloadavg() if hasattr(os, "getloadavg") else ("?",) * 3
    header = ("| arm | source | joints | generate total (s) | derive+render (s) | compile (s) | --no-snap total (s) "
              "| fk error vs Pinocchio | Jacobian error vs Pinocchio | snapped |\n"
              "|---|---|---|---|---|---|---|---|---|---|")
    against = f"Pinocchio {pin.__version__}" if pin is not None else "Pinocchio (not installed)"
    text = (f"# Real URDF files: cold generation, and the kernels against {against} "
            f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {load[0]:.2f})\n\n"
            "`python benchmarks/urdf_zoo.py`: each arm of `tests/urdf_zoo.py` in fresh processes with an empty "
            f"cache, on {_cores_text(cores(args.one_core))}. generate total: `kinegen generate` with the C compile, the whole process; "
            "derive+render: the same with `--no-build`, to its \"wrote\" line; compile: the C compile of the "
            "first run; --no-snap total: `--no-build --no-snap`, the whole process. Errors: the largest absolute "
            f"difference of any entry of the numpy kernels' fk and geometric Jacobian (tip relative to base, "
            f"base axes) on {SAMPLES} configurations within the limits; Pinocchio reads the numbers as written, "
            "so a snapped arm differs from it by about what snapping moved. snapped: how many angles and axes "
            "snapping made exact.\n\n" + header + "\n" + "\n".join(rows) + "\n")
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

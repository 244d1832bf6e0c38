"""The automatic inverse kinematics of two zoo arms against the Robotics Toolbox, in one run.

For the UR5 (three parallel axes) and the KUKA KR5 (spherical wrist), from their files in
``tests/data/arms/``:

* the cold derivation: ``derivations.load`` and then ``derivations.ik.solve`` in a fresh
  process with an empty cache (the decomposition alone is ``solve``);
* the package generated with the default (vectorised) flags, as ``kinegen generate`` does;
* our ``ik`` (all 8 branches) per pose: numpy and C batched over 100,000 poses from Python,
  and inside C (a compiled driver, ``benchmarks/inside_c.py``), one pose per call and batched;
* the Toolbox on the same poses: ``ikine_LM`` (numeric, one solution, from q = 0) and, where
  it builds, ``analytic_ik`` (its SymPy closed form, new in 1.5) in a Python loop; each
  answer put through our fk, so the share within 1e-6 of the pose is in the table too
  (ikine_LM's own tolerance lets answers 1e-5 off count as a success).

Ratios are against our C batched figure of the same run.  Writes ``benchmarks/auto_ik.md``.
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

ARMS = {"ur5": "three parallel", "kuka_kr5": "spherical wrist"}

COLD = r"""
import json, sys, time
start = time.perf_counter()
import derivations
from derivations.ik import solve
imported = time.perf_counter()
model = derivations.load(sys.argv[1])
loaded = time.perf_counter()
solution = solve(model)
done = time.perf_counter()
print(json.dumps({"import": imported - start, "model": loaded - imported, "ik": done - loaded,
                  "family": solution.family, "branches": len(solution.branches)}))
"""


def cold_derivation(path: Path) -> dict:
    with tempfile.TemporaryDirectory(prefix="kinegen-cold-") as cache:
        env = dict(os.environ, KINEGEN_CACHE=cache, PYTHONPATH=str(REPO))
        run = subprocess.run([sys.executable, "-c", COLD, str(path)], env=env, capture_output=True, text=True,
                             check=True, cwd=REPO)
    return json.loads(run.stdout.strip().splitlines()[-1])


def per_pose(function, count: int, repeat: int = 5) -> float:
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        samples.append(time.perf_counter() - start)
    return float(np.median(samples)) / count


def targets(kernels, count: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (count, len(kernels.JOINTS)))
    return q, kernels.fk(q)


def rtb_robot(model):
    import roboticstoolbox as rtb
    import sympy as sp
    from spatialmath import SE3
    subs = dict(model.params)
    links = []
    for j in model.chain.joints:
        a, alpha, d, offset = (float(sp.sympify(v).subs(subs)) for v in (j.a, j.alpha, j.d, j.offset))
        links.append(rtb.RevoluteDH(a=a, alpha=alpha, d=d, offset=offset))
    robot = rtb.DHRobot(links, name=model.name)
    robot.base = SE3(np.array(model.chain.base.subs(subs).evalf(), dtype=float), check=False)
    robot.tool = SE3(np.array(model.chain.tool.subs(subs).evalf(), dtype=float), check=False)
    return robot, SE3, rtb.__version__


def toolbox(model, kernels, poses, loop: int, say) -> dict:
    """ikine_LM and analytic_ik on ``loop`` poses: seconds per pose and the share answered right."""
    try:
        robot, SE3, version = rtb_robot(model)
    except ImportError as exc:
        return {"missing": f"not installed ({exc.name})"}
    out = {"version": version}
    chosen = [SE3(p, check=False) for p in poses[:loop]]
    zero = np.zeros(len(kernels.JOINTS))

    def right(q, pose):
        return q is not None and np.abs(kernels.fk(np.asarray(q, float)) - pose).max() < 1e-6

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        answers = [robot.ikine_LM(p, q0=zero) for p in chosen]
        out["ikine_LM"] = (time.perf_counter() - start) / len(chosen)
        out["ikine_LM success"] = float(np.mean([a.success for a in answers]))
        out["ikine_LM right"] = float(np.mean([a.success and right(a.q, p) for a, p in zip(answers, poses)]))
        say("RTB ikine_LM done")
        try:
            start = time.perf_counter()
            solver = robot.analytic_ik()
            out["analytic_ik derivation"] = time.perf_counter() - start
            start = time.perf_counter()
            solutions = [solver.solve(p, joint_limits=False) for p in chosen]
            out["analytic_ik"] = (time.perf_counter() - start) / len(chosen)
            counts, right_counts = [], []
            for found, pose in zip(solutions, poses):
                found = list(found) if found is not None else []
                counts.append(len(found))
                right_counts.append(sum(right(q, pose) for q in found))
            out["analytic_ik solutions"] = float(np.mean(counts))
            out["analytic_ik right"] = float(np.mean(right_counts))
        except Exception as exc:  # the Toolbox says why it cannot, we report it
            out["analytic_ik"] = f"n/a ({type(exc).__name__}: {str(exc)[:120]})"
        say("RTB analytic_ik done")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="few poses, for a smoke run")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "auto_ik.md")
    args = parser.parse_args(argv)
    count = 2_000 if args.quick else 100_000
    loop = 20 if args.quick else 200

    def say(message):
        print(f"[auto-ik bench] {message}", file=sys.stderr, flush=True)

    import derivations
    import inside_c
    started = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None, microsecond=0)
    rows = {}
    with tempfile.TemporaryDirectory(prefix="kinegen-autoik-") as tmp:
        root = Path(tmp)
        for name, family in ARMS.items():
            path = REPO / "tests" / "data" / "arms" / f"{name}.toml"
            say(f"{name}: cold derivation")
            cold = cold_derivation(path)
            say(f"{name}: generate")
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(path), "--out",
                            str(root / name)], check=True, cwd=REPO,
                           env=dict(os.environ, PYTHONPATH=str(REPO)))
            generate = time.perf_counter() - start
            sys.path.insert(0, str(root))
            package = importlib.import_module(name)
            sys.path.remove(str(root))
            numpy_k, c_k = package.load("numpy"), package.load("c")
            q, poses = targets(numpy_k, count)
            row = {"family": family, "cold": cold, "generate": generate,
                   "numpy batch": per_pose(lambda: numpy_k.ik(poses), count),
                   "c batch": per_pose(lambda: c_k.ik(poses), count)}
            say(f"{name}: inside C")
            figures = inside_c.time_in_c(name, root / "build", count, 5 if args.quick else 15, module=numpy_k,
                                         root=root)
            row["in C single"] = figures[("ik", "single")] * 1e-9
            row["in C batch"] = figures[("ik", "batch")] * 1e-9
            say(f"{name}: Robotics Toolbox")
            row["rtb"] = toolbox(derivations.load(path), numpy_k, poses, loop, say)
            rows[name] = row
    ended = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None, microsecond=0)
    text = report(rows, started, ended, count, loop)
    print(text)
    args.out.write_text(text, encoding="utf-8")
    say(f"wrote {args.out}")
    return 0


def _time(seconds) -> str:
    if isinstance(seconds, str):
        return seconds
    if seconds < 1e-6:
        return f"{seconds * 1e9:.0f} ns"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.2f} us"
    return f"{seconds * 1e3:.2f} ms"


def report(rows, started, ended, count, loop) -> str:
    lines = [f"# Automatic IK against the Robotics Toolbox ({started} to {ended} UTC, load average "
             f"{os.getloadavg()[0]:.2f})", "",
             f"`python benchmarks/auto_ik.py` (part of `make bench`). Per pose; our figures over {count:,} random "
             f"poses, all 8 branches; the Toolbox's over {loop} of the same poses in a Python loop. Ratios: "
             "the row's time over our batched C time.", "",
             "| arm | family | cold derivation: model + IK (s) | generate with C compile (s) | what | per pose | ratio |",
             "|---|---|---|---|---|---|---|"]
    for name, row in rows.items():
        base = row["c batch"]
        cold = row["cold"]
        head = (f"| {name} | {row['family']} | {cold['model']:.2f} + {cold['ik']:.2f} | {row['generate']:.1f} |")
        entries = [("kinegen C, batched from Python", row["c batch"]), ("kinegen numpy, batched", row["numpy batch"]),
                   ("kinegen C inside C, one pose per call", row["in C single"]),
                   ("kinegen C inside C, batched", row["in C batch"])]
        rtb = row["rtb"]
        if "missing" in rtb:
            entries.append(("Robotics Toolbox", rtb["missing"]))
        else:
            entries.append((f"RTB {rtb['version']} ikine_LM from q = 0 (one solution; success "
                            f"{rtb['ikine_LM success']:.0%}, within 1e-6 of the pose {rtb['ikine_LM right']:.0%})",
                            rtb["ikine_LM"]))
            analytic = rtb.get("analytic_ik")
            if isinstance(analytic, float):
                entries.append((f"RTB analytic_ik (derived in {rtb['analytic_ik derivation']:.1f} s; "
                                f"{rtb['analytic_ik solutions']:.1f} solutions per pose, "
                                f"{rtb['analytic_ik right']:.1f} within 1e-6)", analytic))
            else:
                entries.append(("RTB analytic_ik", analytic))
        for i, (what, seconds) in enumerate(entries):
            ratio = f"{seconds / base:.1f}x" if isinstance(seconds, float) else ""
            lines.append((head if i == 0 else "| | | | |") + f" {what} | {_time(seconds)} | {ratio} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())

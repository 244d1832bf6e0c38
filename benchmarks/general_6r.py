"""The general 6R's ik (every real solution) on the Kinova Jaco and Mico: counts over 10,000 random plus
1,000 degenerate configurations in both backends, its time per pose, its derivation time cold,
and the Robotics Toolbox beside it (its generated Raghavan-Roth solver, ``analytic_ik().solve``,
and its numeric ``ik_LM``) where the bench environment has it.

* Backends: ``c`` is the whole ik in generated C (general_6r.c.j2: the coefficient matrices, the
  real roots of their 12 x 12 determinant on one loop from 17 samples, and only where those leave a
  doubt a companion linearisation less its 8 spurious eigenvalues +-i (16 x 16), balancing,
  Hessenberg reduction and Francis double-shift QR for the eigenvalues; the joints from each real
  root, the Newton polish, the deduplication), through
  cffi for a batch and the point module for one pose; ``numpy`` is the same method with LAPACK's
  ``eig`` and numpy (general_6r.py.j2), its equations, fk and Jacobian in numpy.
* Package: ``kinegen generate FILE`` (portable C99 -O2) of each arm's file, in a
  temporary folder; the derivation of the general 6R's equations timed alone in a fresh process
  with an empty derivation cache (``derivations.load``, then ``equations_function``).
* Counts (as tests/ik/test_general_6r.py, here on more poses): targets from the package's fk of
  RANDOM uniform configurations (every joint over the whole turn) and DEGENERATE with every joint
  at 0, +-pi/2 or pi; "wrong" a valid answer whose pose (the package's fk) is off by more than
  1e-9 in an entry of the 4 x 4, "no solution" a target without a valid answer, "missing" the
  generating configuration not among the valid answers (within 1e-6 rad per joint), also split
  into regular and singular generating configurations (smallest singular value of the Jacobian
  above or below 1e-6).
* Time: the best of REPEAT runs, batched (per pose) and one pose per call, in CPU time of this
  process and wall time.
* The Toolbox: a DHRobot of the same table; ``analytic_ik().solve(T)`` one pose per call on the
  first LOOP random targets, its solutions counted and held to our fk; ``ik_LM`` from a random
  seed, one solution per call.

Writes ``benchmarks/general_6r.md``.
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
ARMS = {"kinova_jaco": REPO / "tests" / "data" / "arms" / "kinova_jaco.toml",
        "kinova_mico": REPO / "tests" / "data" / "general_6r" / "kinova_mico.toml"}
RANDOM, DEGENERATE = 10_000, 1_000
REPEAT = 3
LOOP = 200
REACHED, SAME = 1e-9, 1e-6


def say(message):
    print(f"[general-6r bench] {message}", file=sys.stderr, flush=True)


def each(function, items) -> None:
    """``function`` called on each of ``items``, each result dropped as the next comes (as in peers_ik.py:
    a list of the results kept alive makes Python's cyclic collector run over them)."""
    for item in items:
        function(item)


def best(function, repeat: int = REPEAT) -> dict:
    cpu, wall = [], []
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        function()
        cpu.append(time.process_time() - start_cpu)
        wall.append(time.perf_counter() - start)
    return {"cpu": min(cpu), "wall": min(wall)}


def per(figures: dict, count: int) -> dict:
    return {k: v / count for k, v in figures.items()}


def configurations(seed: int = 6):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (RANDOM + DEGENERATE, 6))
    q[RANDOM:] = rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi], (DEGENERATE, 6))
    return q


def counts(kernels, Q, valid, q, poses) -> dict:
    reached = np.abs(kernels.fk(np.where(valid[..., None], Q, 0.0)) - poses[:, None]).max(axis=(-2, -1))
    difference = np.abs((Q - q[:, None, :] + np.pi) % (2 * np.pi) - np.pi).max(axis=-1)
    missing = np.where(valid, difference, np.inf).min(axis=-1) > SAME
    regular = np.linalg.svd(kernels.jacobian(q), compute_uv=False)[:, -1] > 1e-6
    out = {}
    for label, rows in (("random", slice(0, RANDOM)), ("degenerate", slice(RANDOM, None))):
        out[label] = {"poses": int(len(q[rows])), "wrong": int((valid[rows] & (reached[rows] > REACHED)).sum()),
                      "no solution": int((~valid[rows].any(axis=-1)).sum()),
                      "missing": int(missing[rows].sum()),
                      "missing at regular": int((missing & regular)[rows].sum()),
                      "singular": int((~regular[rows]).sum()),
                      "solutions per pose": float(valid[rows].sum(axis=-1).mean()),
                      "histogram": np.bincount(valid[rows].sum(axis=-1), minlength=17).tolist(),
                      "worst": float(np.where(valid[rows], reached[rows], 0).max())}
    return out


def toolbox(path, kernels, q, poses) -> dict:
    try:
        import roboticstoolbox as rtb
        import sympy as sp

        import derivations
    except ImportError as exc:
        return {"missing": f"not installed ({exc.name})"}
    model = derivations.load(path)
    subs = dict(model.params)
    links = [rtb.RevoluteDH(a=float(sp.sympify(j.a).subs(subs)), alpha=float(sp.sympify(j.alpha).subs(subs)),
                            d=float(sp.sympify(j.d).subs(subs)), offset=float(sp.sympify(j.offset).subs(subs)))
             for j in model.chain.joints]
    robot = rtb.DHRobot(links, name="jaco")
    out = {"version": rtb.__version__, "fk": float(max(np.abs(robot.fkine(row).A - kernels.fk(row)).max() for row in q[:20]))}
    try:
        start = time.perf_counter()
        solver = robot.analytic_ik()
        out["rr derivation"] = time.perf_counter() - start
        found, wrong, missing, seconds = [], 0, 0, []
        for i in range(LOOP):
            start = time.perf_counter()
            solution = solver.solve(poses[i])
            seconds.append(time.perf_counter() - start)
            answers = np.atleast_2d(np.asarray(solution.q, float)) if solution.success else np.zeros((0, 6))
            found.append(len(answers))
            if len(answers):
                wrong += int((np.abs(kernels.fk(answers) - poses[i]).max(axis=(-2, -1)) > REACHED).sum())
                gap = np.abs((answers - q[i] + np.pi) % (2 * np.pi) - np.pi).max(axis=-1).min()
            else:
                gap = np.inf
            missing += int(gap > SAME)
        out["rr"] = {"seconds": float(np.median(seconds)), "solutions per pose": float(np.mean(found)),
                     "wrong": wrong, "missing": missing, "poses": LOOP}
    except Exception as exc:  # a Toolbox without the solver, or one that refuses the arm
        out["rr"] = {"error": f"{type(exc).__name__}: {exc}"[:200]}
    rng = np.random.default_rng(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        answers = [robot.ik_LM(poses[i], q0=rng.uniform(-np.pi, np.pi, 6)) for i in range(LOOP)]
        seconds = (time.perf_counter() - start) / LOOP
    reached = [a.success and np.abs(kernels.fk(np.asarray(a.q, float)) - poses[i]).max() <= REACHED
               for i, a in enumerate(answers)]
    out["ik_LM"] = {"seconds": seconds, "success": float(np.mean([a.success for a in answers])),
                    "reached": float(np.mean(reached))}
    return out


def measure(root: Path, name: str) -> dict:
    sys.path.insert(0, str(root))
    package = importlib.import_module(name)
    numpy_k, c_k = package.load("numpy"), package.load("c")
    q = configurations()
    poses = c_k.fk(q)
    row = {}
    for label, kernels in (("numpy", numpy_k), ("c", c_k)):
        start = time.perf_counter()
        Q, valid = kernels.ik(poses)
        say(f"{label}: {len(q):,} poses in {time.perf_counter() - start:.1f} s")
        row[label] = counts(kernels, Q, valid, q, poses)
        sample = poses[:1000]
        row[label]["batched"] = per(best(lambda: kernels.ik(sample)), len(sample))
        row[label]["single"] = per(best(lambda: each(kernels.ik, sample[:200])), 200)
    row["rtb"] = toolbox(ARMS[name], c_k, q, poses)
    return row


def cold_derivation(path) -> float:
    """The general 6R's equations derived in a fresh process, with an empty derivation cache."""
    code = ("import time, derivations; from derivations.ik.general_6r import equations_function; "
            f"m = derivations.load({str(path)!r}); start = time.perf_counter(); equations_function(m); "
            "print(time.perf_counter() - start)")
    with tempfile.TemporaryDirectory() as cache:
        run = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, cwd=REPO,
                             env=dict(os.environ, PYTHONPATH=str(REPO), KINEGEN_CACHE=cache))
    return float(run.stdout.strip().splitlines()[-1])


def _time(seconds) -> str:
    if isinstance(seconds, dict):
        return f"{_time(seconds['cpu'])} ({_time(seconds['wall'])})"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.0f} us"
    return f"{seconds * 1e3:.2f} ms"


def report(rows, started, ended, load) -> str:
    lines = [f"# The general 6R: every real solution of the Kinova Jaco and Mico ({started} to {ended} UTC, load "
             f"average {load:.2f})", "",
             "`python benchmarks/general_6r.py` (part of `make bench`). Targets: the poses (the package's fk) of "
             f"{RANDOM:,} random configurations (every joint over the whole turn) and {DEGENERATE:,} degenerate ones "
             "(every joint at 0, +-pi/2 or pi). wrong: a valid answer off its pose by more than 1e-9 in an entry of "
             "the 4 x 4; no solution: a pose without a valid answer; missing: the generating configuration not among "
             "the valid answers (1e-6 rad per joint), in brackets those at a regular configuration (the Jacobian's "
             "smallest singular value above 1e-6); singular: the generating configurations that are not. Times: the "
             f"best of {REPEAT} runs over 1,000 poses (batched) or 200 calls of one pose, CPU time (wall time). "
             "Derivation: the general 6R's equations alone, in a fresh process with an empty cache; generate: the "
             "whole `kinegen generate` with its C compile. Backend c: the whole ik in generated C, no LAPACK (the "
             "real roots of the 12 x 12 determinant, a trigonometric polynomial of degree 8 from 17 samples, on one "
             "loop; where those leave a doubt, the eigenvalues as before: the 8 spurious ones +-i taken out, the "
             "other 16 by our own Hessenberg reduction and Francis double-shift QR); numpy: the eigenvalues with "
             "LAPACK's eig (issue #26's target for the C: at most 20 us per pose).", "",
             "| arm | backend | poses | wrong | no solution | missing (at regular) | singular | solutions per pose "
             "| worst FK error | batched, per pose | one pose per call | derivation, cold | generate |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, row in rows.items():
        for backend in ("numpy", "c"):
            for label in ("random", "degenerate"):
                c = row[backend][label]
                lines.append(f"| {name} | {backend}, {label} | {c['poses']:,} | {c['wrong']} | {c['no solution']} | "
                             f"{c['missing']} ({c['missing at regular']}) | {c['singular']} | "
                             f"{c['solutions per pose']:.2f} | {c['worst']:.1e} | {_time(row[backend]['batched'])} | "
                             f"{_time(row[backend]['single'])} | {row['derivation']:.1f} s | {row['generation']:.1f} s |")
    lines.append("")
    for name, row in rows.items():
        hist = row["c"]["random"]["histogram"]
        lines.append(f"Real solutions per random pose, {name} (C backend): "
                     + ", ".join(f"{k}: {n}" for k, n in enumerate(hist) if n) + ".")
    lines.append("")
    for name, row in rows.items():
        rtb = row["rtb"]
        if "missing" in rtb:
            lines.append(f"- {name}, the Robotics Toolbox: {rtb['missing']}.")
            continue
        rr = rtb.get("rr", {})
        head = (f"- {name}, the Robotics Toolbox {rtb['version']} (a DHRobot of the same table; its fk against ours: "
                f"{rtb['fk']:.1e}), one pose per call on the first {LOOP} random targets: ")
        if "error" in rr:
            head += f"`analytic_ik().solve` (Raghavan-Roth): {rr['error']}; "
        else:
            head += (f"`analytic_ik().solve` (its generated Raghavan-Roth, derived in {rtb['rr derivation']:.1f} s) "
                     f"{_time(rr['seconds'])} per pose (median), {rr['solutions per pose']:.2f} solutions per pose, "
                     f"{rr['wrong']} wrong, {rr['missing']} missing of {rr['poses']}; ")
        lm = rtb["ik_LM"]
        head += (f"`ik_LM` from a random seed (one solution) {_time(lm['seconds'])} per pose, success "
                 f"{lm['success']:.1%}, within 1e-9 {lm['reached']:.1%}.")
        lines.append(head)
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "general_6r.md")
    parser.add_argument("--name", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(measure(args.worker, args.name)))
        return 0
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    rows = {}
    for name, path in ARMS.items():
        with tempfile.TemporaryDirectory() as root:
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(path), "--time-limit", "900", "--out",
                            str(Path(root) / name)], check=True, cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)))
            generation = time.perf_counter() - start
            say(f"{name}: generated in {generation:.1f} s")
            run = subprocess.run([sys.executable, __file__, "--worker", root, "--name", name], check=True,
                                 capture_output=True, text=True, cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)))
            rows[name] = json.loads(run.stdout.strip().splitlines()[-1])
        rows[name]["generation"] = generation
        rows[name]["derivation"] = cold_derivation(path)
    ended = datetime.datetime.now(datetime.timezone.utc).strftime("%H:%M")
    args.out.write_text(report(rows, started, ended, os.getloadavg()[0]))
    say(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

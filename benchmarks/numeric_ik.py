"""The numeric inverse kinematics (ik_numeric) in C and in numpy against the Robotics Toolbox's
ik_LM, and the single call of ik with a 4 x 4 pose against the 12-vector, in one run.

For the Franka Panda (7 joints) and the Kinova Jaco (a general 6R), from their files in
``tests/data/arms/``, each package generated as ``kinegen generate`` does (portable C99 -O2):

* COUNT targets: the poses of random configurations within the joint limits (the Jaco's joints
  have none: -pi .. pi), each with a seed within 0.1 rad of its configuration (every joint moved by
  a uniform value in -0.1 .. 0.1);
* ours: ``ik_numeric(poses, seeds)`` of the C backend, batched from Python, and of numpy; the C
  one pose per call from Python; the share converged, and the largest difference between the
  answers' poses (the package's fk) and the targets over the converged ones (4 x 4 entries);
* the Toolbox's ``ik_LM`` (its C++ Levenberg-Marquardt) on the first LOOP of the same targets, from
  the same seeds, in a Python loop, on an ETS built here from the same DH table and checked against
  our fk: once as it comes (tol 1e-6, 30 iterations, 100 searches from random restarts), once at a
  tolerance that reaches 1e-10 (tol = RTB_TOLERANCE on its E = e^T W e / 2; one search of 100
  iterations from the seed, as ours).  Its success rate, and the share of its answers whose pose
  is within 1e-10 of the target by our fk.

For the UR5 (a closed form), built as ``kinegen generate`` does and with ``--fast``: ``ik`` of one
pose per call from Python, given as a 4 x 4 and as the 12-vector, each the best of several repeats
of many calls; and batched, the C kernel's own cost.

Times are the best of REPEAT runs in this process's CPU time, and in wall time (the machine is
shared: a process waiting for a core is not charged CPU time, and the best run is the least
disturbed); the load average is in the title.  Writes ``benchmarks/numeric_ik.md``.
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ARMS = ("franka_panda", "kinova_jaco")
SINGLE = "ur5"  # also built with --fast
SINGLE_MORE = ("kuka_kr5", "franka_panda")  # a spherical wrist; joint 7 held (ik(x, free))
REPEAT = 5
RTB_TOLERANCE = 1e-22
REACHED = 1e-10


def say(message):
    print(f"[numeric-ik bench] {message}", file=sys.stderr, flush=True)


def best(function, repeat: int = REPEAT) -> dict:
    """The best of ``repeat`` runs of ``function``: its CPU time (this process's, which a busy machine
    inflates far less than the wall time: a process waiting for a core is not charged) and wall time."""
    cpu, wall = [], []
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        function()
        cpu.append(time.process_time() - start_cpu)
        wall.append(time.perf_counter() - start)
    return {"cpu": min(cpu), "wall": min(wall)}


def per(figures: dict, count: int) -> dict:
    return {k: v / count for k, v in figures.items()}


def problems(kernels, count: int, seed: int = 26):
    """Configurations within the limits, their poses, and seeds within 0.1 rad of them."""
    rng = np.random.default_rng(seed)
    limits = np.array([lim if lim is not None else (-np.pi, np.pi) for lim in kernels.LIMITS])
    q = rng.uniform(limits[:, 0], limits[:, 1], (count, len(kernels.JOINTS)))
    return q, kernels.fk(q), q + rng.uniform(-0.1, 0.1, q.shape)


def rtb_ets(model):
    """The Toolbox's ETS of a revolute DH chain (standard or modified), its offsets, base, tool and limits."""
    import roboticstoolbox as rtb
    import sympy as sp
    subs = dict(model.params)

    def value(v):
        return float(sp.sympify(v).subs(subs))

    ets = rtb.ET.SE3(np.array(model.chain.base.subs(subs).evalf(), dtype=float))
    for joint in model.chain.joints:
        a, alpha, d, offset = value(joint.a), value(joint.alpha), value(joint.d), value(joint.offset)
        variable = rtb.ET.Rz(qlim=[float(v) for v in joint.limits]) if joint.limits is not None else rtb.ET.Rz()
        if model.chain.convention == "modified":
            parts = [rtb.ET.Rx(alpha), rtb.ET.tx(a), rtb.ET.Rz(offset), variable, rtb.ET.tz(d)]
        else:
            parts = [rtb.ET.Rz(offset), variable, rtb.ET.tz(d), rtb.ET.tx(a), rtb.ET.Rx(alpha)]
        for part in parts:
            if part.isjoint or not np.array_equal(part.A(), np.eye(4)):
                ets = ets * part
    return ets * rtb.ET.SE3(np.array(model.chain.tool.subs(subs).evalf(), dtype=float)), rtb.__version__


def toolbox(path: Path, kernels, q, poses, seeds, loop: int) -> dict:
    try:
        import derivations
        ets, version = rtb_ets(derivations.load(path))
    except ImportError as exc:
        return {"missing": f"not installed ({exc.name})"}
    out = {"version": version, "fk": float(max(np.abs(ets.fkine(row).A - kernels.fk(row)).max() for row in q[:20]))}
    settings = {"as it comes": dict(tol=1e-6), f"tol {RTB_TOLERANCE:g}": dict(tol=RTB_TOLERANCE, ilimit=100, slimit=1)}
    for label, options in settings.items():
        answers = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            seconds = per(best(lambda: answers.append([ets.ik_LM(poses[i], q0=seeds[i], joint_limits=True, **options)
                                                       for i in range(loop)]), 1), loop)
        answers = answers[0]
        reached = [a.success and np.abs(kernels.fk(np.asarray(a.q, float)) - poses[i]).max() <= REACHED
                   for i, a in enumerate(answers)]
        out[label] = {"seconds": seconds, "success": float(np.mean([a.success for a in answers])),
                      "reached": float(np.mean(reached)), "options": options}
    return out


def measure_numeric(root: Path, name: str, count: int, loop: int) -> dict:
    """The figures of one arm, in this process (a worker: one package per process)."""
    sys.path.insert(0, str(root))
    package = importlib.import_module(name)
    numpy_k, c_k = package.load("numpy"), package.load("c")
    q, poses, seeds = problems(c_k, count)
    c_k.ik_numeric(poses[:10], seeds[:10])
    found, converged = c_k.ik_numeric(poses, seeds)
    row = {"count": count, "joints": len(c_k.JOINTS),
           "c batch": per(best(lambda: c_k.ik_numeric(poses, seeds)), count),
           "c converged": float(converged.mean()),
           "c worst": float(np.abs(c_k.fk(found[converged]) - poses[converged]).max())}
    single = min(count, 2_000)
    row["c single"] = per(best(lambda: [c_k.ik_numeric(poses[i], seeds[i]) for i in range(single)]), single)
    part = min(count, 2_000)
    numpy_found, numpy_converged = numpy_k.ik_numeric(poses[:part], seeds[:part])
    row["numpy batch"] = per(best(lambda: numpy_k.ik_numeric(poses[:part], seeds[:part]), 3), part)
    row["numpy converged"] = float(numpy_converged.mean())
    row["numpy worst"] = float(np.abs(numpy_k.fk(numpy_found[numpy_converged]) - poses[:part][numpy_converged]).max())
    row["agree"] = float(np.mean(numpy_converged == converged[:part]))
    row["rtb"] = toolbox(REPO / "tests" / "data" / "arms" / f"{name}.toml", c_k, q, poses, seeds, loop)
    return row


def measure_single(root: Path, name: str, calls: int) -> dict:
    """ik of one pose per call from Python, C backend: a 4 x 4 and the 12-vector."""
    sys.path.insert(0, str(root))
    c_k = importlib.import_module(name).load("c")
    q, poses, _ = problems(c_k, 64)
    vectors = np.concatenate([poses[:, :3, 3], poses[:, :3, :3].reshape(-1, 9)], axis=-1)
    held = re.search(r"joint (\d+) free", c_k.IK_METHOD)  # ik(x, free): the held joint at its value
    free = None if held is None else [q[i, int(held[1]) - 1:int(held[1])] for i in range(len(q))]
    rows = {"method": c_k.IK_METHOD, "branches": len(c_k.BRANCHES)}
    rounds = max(1, calls // len(poses))
    for label, items in (("4 x 4", list(poses)), ("12-vector", list(vectors))):
        ik = c_k.ik
        if free is None:  # the call as users write it (no unpacking of an empty tuple: 0.1 us more)
            rows[label] = per(best(lambda: [ik(x) for _ in range(rounds) for x in items]), rounds * len(items))
        else:
            pairs = list(zip(items, free))
            rows[label] = per(best(lambda: [ik(x, f) for _ in range(rounds) for x, f in pairs]), rounds * len(items))
    batch = np.repeat(vectors, 1_000, axis=0)
    rest = () if free is None else (np.repeat(np.array(free), 1_000, axis=0),)
    valid = c_k.ik(batch, *rest)[1]
    assert valid.any(axis=-1).all(), "a pose of the single call's bench without a valid branch"
    rows["batched, per pose"] = per(best(lambda: c_k.ik(batch, *rest)), len(batch))
    return rows


def generate(path: Path, out: Path, *options: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(path), "--out", str(out), *options],
                   check=True, cwd=REPO, env=dict(os.environ, PYTHONPATH=str(REPO)))
    return time.perf_counter() - start


def worker(kind: str, root: Path, name: str, args) -> dict:
    """Run one measurement in a process of its own (each package imported alone)."""
    command = [sys.executable, __file__, "--worker", kind, str(root), name, "--count", str(args.count),
               "--loop", str(args.loop), "--calls", str(args.calls)]
    run = subprocess.run(command, check=True, capture_output=True, text=True, cwd=REPO,
                         env=dict(os.environ, PYTHONPATH=str(REPO)))
    return json.loads(run.stdout.strip().splitlines()[-1])


def _time(seconds) -> str:
    if isinstance(seconds, dict):  # CPU time (wall time)
        return f"{_time(seconds['cpu'])} ({_time(seconds['wall'])})"
    if seconds < 1e-6:
        return f"{seconds * 1e9:.0f} ns"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.2f} us"
    return f"{seconds * 1e3:.2f} ms"


def report(rows, single, started, ended, load, args) -> str:
    lines = [f"# Numeric inverse kinematics against the Robotics Toolbox ({started} to {ended} UTC, load average "
             f"{load:.2f})", "",
             f"`python benchmarks/numeric_ik.py` (part of `make bench`). Targets: the poses of {args.count:,} random "
             "configurations within the joint limits, each solved from a seed within 0.1 rad of its configuration "
             f"(the Toolbox: the first {args.loop} of them, same seeds, in a Python loop, one run). Per solve: "
             f"the best of {REPEAT} runs in CPU time (of this process), and in brackets in wall time, which the "
             "load of a shared machine inflates more. \"within 1e-10\": the answer's pose (our fk) within 1e-10 of the target in every entry "
             "of the 4 x 4. Our tolerance is 1e-12 on the residual itself (metres and radians); the Toolbox's `tol` "
             "bounds E = e^T W e / 2.", "",
             "| arm | what | per solve: CPU (wall) | converged | within 1e-10 | largest pose error |",
             "|---|---|---|---|---|---|"]
    for name, row in rows.items():
        head = f"| {name} ({row['joints']} joints) |"
        entries = [
            ("kinegen C, batched from Python", row["c batch"], row["c converged"], row["c converged"], row["c worst"]),
            ("kinegen C, one pose per call from Python", row["c single"], row["c converged"], row["c converged"],
             row["c worst"]),
            (f"kinegen numpy, batched (first 2,000; converged on the same items as C: {row['agree']:.2%})",
             row["numpy batch"], row["numpy converged"], row["numpy converged"], row["numpy worst"])]
        for i, (what, seconds, converged, reached, worst) in enumerate(entries):
            lines.append((head if i == 0 else "| |") + f" {what} | {_time(seconds)} | {converged:.2%} | "
                         f"{reached:.2%} | {worst:.1e} |")
        rtb = row["rtb"]
        if "missing" in rtb:
            lines.append(f"| | Robotics Toolbox ik_LM | {rtb['missing']} | | | |")
            continue
        for label in ("as it comes", f"tol {RTB_TOLERANCE:g}"):
            figures = rtb[label]
            options = ", ".join(f"{k}={v:g}" for k, v in figures["options"].items())
            lines.append(f"| | RTB {rtb['version']} ik_LM, {label} ({options}) | {_time(figures['seconds'])} | "
                         f"{figures['success']:.1%} (its success) | {figures['reached']:.1%} | |")
    lines += ["", f"The Toolbox's chains were built here from the same DH tables (their fk agrees with ours to "
              + ", ".join(f"{row['rtb']['fk']:.1e} ({name})" for name, row in rows.items() if 'fk' in row['rtb'])
              + ").", "",
              "## The single call: ik of one pose from Python (C backend, closed form, every branch)", "",
              "The same 64 poses (of configurations within the limits) called one at a time, as a 4 x 4 array and "
              "as the 12-vector (x, y, z, r11 .. r33), the held joint of a 7-joint arm given as `free` (an array of "
              "shape (1,)); and batched, for the cost of the C kernel itself.", "",
              "Times: CPU (wall), the best of several runs.", "",
              "| arm | method (branches) | build | 4 x 4, per call | 12-vector, per call | batched, per pose |",
              "|---|---|---|---|---|---|"]
    for (name, build), figures in single.items():
        lines.append(f"| {name} | {figures['method']} ({figures['branches']}) | {build} | {_time(figures['4 x 4'])} | "
                     f"{_time(figures['12-vector'])} | {_time(figures['batched, per pose'])} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="few targets, for a smoke run")
    parser.add_argument("--count", type=int, default=10_000)
    parser.add_argument("--loop", type=int, default=200)
    parser.add_argument("--calls", type=int, default=20_000)
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "numeric_ik.md")
    parser.add_argument("--worker", nargs=3, metavar=("KIND", "ROOT", "NAME"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.quick:
        args.count, args.loop, args.calls = 1_000, 20, 2_000
    if args.worker:
        kind, root, name = args.worker
        figures = (measure_numeric(Path(root), name, args.count, args.loop) if kind == "numeric"
                   else measure_single(Path(root), name, args.calls))
        print(json.dumps(figures))
        return 0
    started = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None, microsecond=0)
    rows = {}
    with tempfile.TemporaryDirectory(prefix="kinegen-numeric-ik-") as tmp:
        root = Path(tmp)
        for name in dict.fromkeys((*ARMS, SINGLE, *SINGLE_MORE)):
            say(f"{name}: generate")
            generate(REPO / "tests" / "data" / "arms" / f"{name}.toml", root / name)
        say(f"{SINGLE}: generate --fast")
        generate(REPO / "tests" / "data" / "arms" / f"{SINGLE}.toml", root / "fast" / SINGLE, "--fast")
        for name in ARMS:
            say(f"{name}: ik_numeric, C, numpy and the Toolbox")
            rows[name] = worker("numeric", root, name, args)
        say("the single call")
        single = {(name, build): worker("single", folder, name, args)
                  for name, build, folder in ((SINGLE, "portable C99 -O2 (the default)", root),
                                              (SINGLE, "--fast (-O3 -march=native, vectorised)", root / "fast"),
                                              *((name, "portable", root) for name in SINGLE_MORE))}
    ended = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None, microsecond=0)
    text = report(rows, single, started, ended, os.getloadavg()[0], args)
    print(text)
    args.out.write_text(text, encoding="utf-8")
    say(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

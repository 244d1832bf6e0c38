"""Our closed-form ik beside EAIK and ik-geo (issue #26, item 7), in one run: a UR5 and a KUKA KR5.

Both peers are analytic solvers by subproblem decomposition: EAIK (``eaik`` on the package index:
D. Ostermeier, J. Kuelz and M. Althoff, "Automatic Geometric Decomposition for Analytical Inverse
Kinematics", IEEE RA-L 10(10), 2025) and ik-geo (``ik-geo``: A. J. Elias and J. T. Wen, "IK-Geo:
Unified robot inverse kinematics using subproblem decomposition", Mechanism and Machine Theory 209,
2025, its Rust implementation's Python binding).  They are installed into the bench environment only
(pyproject's ``bench`` extra), never into the project's.

* Ours: ``kinegen generate FILE --no-dynamics`` of ``tests/data/arms/{ur5,kuka_kr5}.toml`` (portable
  C99 -O2), its C backend: batched (one call for every pose) and one 4 x 4 pose per call.
* EAIK: ``eaik.IK_DH.DhRobot(alpha, a, d)`` of the same DH table (its forward kinematics checked
  against ours first); batched ``IK_batched`` on one worker thread (and on 4, its default, for
  reference), one pose per call ``IK``.
* ik-geo: ``ik_geo.Robot.<family>(h, p)`` with the axes h and the offsets p of the arm at q = 0 taken
  from our ``frames`` (each axis's point moved to where it meets its neighbour, which ik-geo's
  families with intersecting axes need), the family ik-geo's name for the arm's structure
  (``three_parallel_two_intersecting`` for the UR5, ``spherical_two_parallel`` for the KR5); the
  rotation passed as ik-geo reads it (transposed); no batch call, so batched is one call per pose.
* Targets: the poses (our fk) of RANDOM uniform configurations (every joint over (-pi, pi]) and of
  DEGENERATE wrist-singular ones (q5 = 0, the others uniform).  For each library: wrong = an answer
  it gives as exact whose pose (our fk) is off by more than 1e-9 in an entry of the 4 x 4 (ik-geo
  and EAIK flag least-squares answers: those are counted apart, as "flagged LS", and are not
  wrong); no solution = a pose with no exact answer; missing = the generating configuration not
  among the exact answers that reach the pose within 1e-9 (within 1e-6 rad per joint; at a
  wrist-singular pose only the joints it fixes are compared: DETERMINED).
* Times: CPU time of this process, the best of REPEAT runs, per pose; one pose per call in a loop that
  drops each result as the next comes.
* One pose per call, interleaved: this machine's speed moves by up to 2 times within minutes, so
  the single call is also timed in ROUNDS rounds, each timing every library (and our 12-vector
  call) on the same SINGLE poses one after another, in an order shuffled per round.  Per library:
  the best and the median round; per round, the ratio of each peer's time to ours, whose median is
  the figure that does not depend on the machine's state (issue #26 states its 1 us target where
  EAIK took 4.4 to 5.1 us a call).

Writes ``benchmarks/peers_ik.md``.  A peer that is not installed is reported as such.
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ARMS = {"ur5": "three_parallel_two_intersecting", "kuka_kr5": "spherical_two_parallel"}
# The joints a wrist-singular pose (q5 = 0) still fixes: on the KR5 (spherical wrist) all but q4 and q6,
# whose sum (or difference) alone is fixed; on the UR5, whose axes 2, 3, 4 and 6 are then parallel,
# q1 and q5 (q2, q3, q4, q6 move along a continuum).
DETERMINED = {"ur5": [0, 4], "kuka_kr5": [0, 1, 2, 4]}
RANDOM, DEGENERATE = int(os.environ.get("PEERS_RANDOM", 10_000)), int(os.environ.get("PEERS_DEGENERATE", 1_000))
SINGLE = min(1_000, RANDOM)  # poses timed one per call
REPEAT = 3
ROUNDS = int(os.environ.get("PEERS_ROUNDS", 25))
REACHED, SAME = 1e-9, 1e-6


def say(message):
    print(f"[peers-ik bench] {message}", file=sys.stderr, flush=True)


def best(function, repeat: int = REPEAT) -> float:
    times = []
    for _ in range(repeat):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return min(times)


def each(function, items) -> None:
    """``function`` called on each of ``items``, each result dropped as the next comes, as a program that
    uses each answer does.  (A list of a thousand results kept alive made Python's cyclic collector
    run over them: a UR5 call then took 1.0 or 5.2 us by turns, against 0.85 us.)"""
    for item in items:
        function(item)


def configurations(seed: int = 26):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (RANDOM + DEGENERATE, 6))
    q[RANDOM:, 4] = 0.0  # the wrist singularity: axes 4 and 6 in line
    return q


def counts(kernels, answers, q, poses, determined) -> dict:
    """answers: per pose, (Q (k, 6) of the answers given as exact, number flagged least squares)."""
    out = {}
    for label, rows in (("random", range(RANDOM)), ("degenerate", range(RANDOM, RANDOM + DEGENERATE))):
        wrong = none = missing = flagged = total = 0
        for i in rows:
            Q, ls = answers[i]
            flagged += ls
            total += len(Q)
            if not len(Q):
                none += 1
                missing += 1
                continue
            error = np.abs(kernels.fk(Q) - poses[i]).max(axis=(-2, -1))
            wrong += int((error > REACHED).sum())
            good = Q[error <= REACHED]
            joints = [0, 1, 2, 3, 4, 5] if label == "random" else determined
            gap = np.abs((good[:, joints] - q[i, joints] + np.pi) % (2 * np.pi) - np.pi).max(axis=-1) \
                if len(good) else np.array([np.inf])
            missing += int(gap.min() > SAME)
        out[label] = {"poses": len(rows), "wrong": wrong, "no solution": none, "missing": missing,
                      "flagged LS": flagged, "answers per pose": total / len(rows)}
    return out


def ours(kernels, poses) -> tuple[list, dict]:
    Q, valid = kernels.ik(poses)
    answers = [(Q[i][valid[i]], 0) for i in range(len(poses))]
    sample = poses[:SINGLE]
    times = {"batched": best(lambda: kernels.ik(poses)) / len(poses),
             "single": best(lambda: each(kernels.ik, sample)) / len(sample)}
    vectors = [np.ascontiguousarray(np.concatenate([p[:3, 3], p[:3, :3].ravel()])) for p in sample]
    calls = {"ours": lambda: each(kernels.ik, sample), "ours, 12-vector": lambda: each(kernels.ik, vectors)}
    return answers, times, calls


def eaik_solver(model, kernels, poses):
    """(answers, info, the single calls over the first SINGLE poses), or (None, info, None)."""
    try:
        from eaik.IK_DH import DhRobot
        import eaik
    except ImportError as exc:
        return None, {"missing": f"not installed ({exc.name})"}, None
    import sympy as sp
    subs = dict(model.params)
    dh = np.array([[float(sp.sympify(v).subs(subs)) for v in (j.alpha, j.a, j.d, j.offset)] for j in model.chain.joints])
    info = {"version": getattr(eaik, "__version__", None) or _version("eaik")}
    if model.chain.convention != "standard" or np.abs(dh[:, 3]).max() > 0 or \
            np.abs(np.array(sp.Matrix(model.chain.base).subs(subs).evalf(), float) - np.eye(4)).max() > 0 or \
            np.abs(np.array(sp.Matrix(model.chain.tool).subs(subs).evalf(), float) - np.eye(4)).max() > 0:
        return None, dict(info, missing="a table EAIK's DhRobot does not take (offsets, base or tool)"), None
    robot = DhRobot(dh[:, 0], dh[:, 1], dh[:, 2])
    info["family"] = robot.getKinematicFamily()
    check = np.random.default_rng(0).uniform(-np.pi, np.pi, (20, 6))
    info["fk"] = float(max(np.abs(robot.fwdKin(row) - kernels.fk(row)).max() for row in check))

    def read(solution):
        Q = np.asarray(solution.Q, float).reshape(-1, 6)
        ls = np.asarray(solution.is_LS, bool).reshape(-1)
        return Q[~ls], int(ls.sum())

    answers = [read(s) for s in robot.IK_batched(poses, num_worker_threads=1)]
    sample = [p for p in poses[:SINGLE]]
    info["batched"] = best(lambda: robot.IK_batched(poses, num_worker_threads=1)) / len(poses)
    info["batched, 4 threads (wall)"] = _wall(lambda: robot.IK_batched(poses, num_worker_threads=4)) / len(poses)
    info["single"] = best(lambda: each(robot.IK, sample)) / len(sample)
    return answers, info, lambda: each(robot.IK, sample)


def _wall(function) -> float:
    times = []
    for _ in range(REPEAT):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def _version(name):
    from importlib import metadata
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "?"


def axis_points(frames, tool):
    """(h (6, 3), p (7, 3)) of ik-geo's product of exponentials at q = 0: axis i turns about h_i through
    c_i (standard DH: the z axis and origin of frame i - 1); where two consecutive axes meet, both
    points are moved to where they meet (ik-geo's families take p_i,i+1 = 0 for meeting axes)."""
    h = np.array([frames[i][:3, 2] for i in range(6)])
    c = [frames[i][:3, 3].copy() for i in range(6)]
    for i in range(5):
        cross = np.cross(h[i], h[i + 1])
        if np.linalg.norm(cross) < 1e-9:
            continue  # parallel
        # closest points of the two lines: c_i + s h_i and c_i+1 + t h_i+1
        d = c[i + 1] - c[i]
        A = np.array([[h[i] @ h[i], -h[i] @ h[i + 1]], [h[i] @ h[i + 1], -h[i + 1] @ h[i + 1]]])
        s, t = np.linalg.solve(A, [d @ h[i], d @ h[i + 1]])
        a, b = c[i] + s * h[i], c[i + 1] + t * h[i + 1]
        if np.linalg.norm(a - b) < 1e-9:
            c[i], c[i + 1] = a, a.copy()
    p = np.array([c[0]] + [c[i] - c[i - 1] for i in range(1, 6)] + [tool[:3, 3] - c[5]])
    return h, p


def ik_geo_solver(name, kernels, poses):
    """(answers, info, the single calls over the first SINGLE poses), or (None, info, None)."""
    try:
        import ik_geo
    except ImportError as exc:
        return None, {"missing": f"not installed ({exc.name})"}, None
    info = {"version": _version("ik-geo"), "family": ARMS[name]}
    zero = kernels.fk(np.zeros(6))
    h, p = axis_points(kernels.frames(np.zeros(6)), zero)
    robot = getattr(ik_geo.Robot, ARMS[name])(h, p)
    R0 = zero[:3, :3]

    def solve(pose):  # ik-geo's rotation is the transpose of ours, and its tool is unturned at q = 0
        return robot.get_ik((pose[:3, :3] @ R0.T).T, pose[:3, 3])

    def read(found):
        Q = np.array([s[0] for s in found if not s[1]], float).reshape(-1, 6)
        return Q, sum(1 for s in found if s[1])

    answers = [read(solve(pose)) for pose in poses]
    sample = poses[:SINGLE]
    info["single"] = best(lambda: each(solve, sample)) / len(sample)
    info["batched"] = info["single"]  # no batch call: one call per pose
    return answers, info, lambda: each(solve, sample)


def measure(root: Path, name: str) -> dict:
    sys.path.insert(0, str(root))
    package = importlib.import_module(name)
    import derivations
    kernels = package.load("c")
    model = derivations.load(REPO / "tests" / "data" / "arms" / f"{name}.toml")
    q = configurations()
    poses = kernels.fk(q)
    row = {}
    answers, times, calls = ours(kernels, poses)
    row["ours"] = dict(times, counts=counts(kernels, answers, q, poses, DETERMINED[name]), version="C backend")
    say(f"{name}: ours done")
    for label, solver in (("EAIK", lambda: eaik_solver(model, kernels, poses)),
                          ("ik-geo", lambda: ik_geo_solver(name, kernels, poses))):
        answers, info, call = solver()
        if answers is not None:
            info["counts"] = counts(kernels, answers, q, poses, DETERMINED[name])
            calls[label] = call
        row[label] = info
        say(f"{name}: {label} done")
    row["interleaved"] = interleaved(calls, SINGLE)
    say(f"{name}: {ROUNDS} interleaved rounds of single calls done")
    return row


def interleaved(calls: dict, size: int, rounds: int = ROUNDS, seed: int = 7) -> dict:
    """{label: per-round CPU time per call} of each of ``calls`` (each makes ``size`` calls), timed in
    ``rounds`` rounds that run every one once, in an order shuffled per round: times taken at the
    same moments, whose per-round ratios do not depend on how fast the machine runs that minute."""
    rng = np.random.default_rng(seed)
    labels = list(calls)
    for label in labels:  # once untimed: first-call costs (imports, caches) out of the rounds
        calls[label]()
    out = {label: [] for label in labels}
    for _ in range(rounds):
        for k in rng.permutation(len(labels)):
            start = time.process_time()
            calls[labels[k]]()
            out[labels[k]].append((time.process_time() - start) / size)
    return out


def _time(seconds) -> str:
    if seconds is None:
        return "-"
    if seconds < 1e-6:
        return f"{seconds * 1e9:.0f} ns"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.2f} us"
    return f"{seconds * 1e3:.2f} ms"


def report(rows, started, ended) -> str:
    lines = [f"# Our closed-form ik beside EAIK and ik-geo ({started} to {ended} UTC, load average "
             f"{os.getloadavg()[0]:.2f})", "",
             "`python benchmarks/peers_ik.py` (part of `make bench`; the peers in the bench environment only). "
             f"Targets: the poses of {RANDOM:,} random configurations and {DEGENERATE:,} wrist-singular ones (q5 = 0). "
             "wrong: an answer given as exact that misses its pose by more than 1e-9 in an entry of the 4 x 4 (our "
             "fk); flagged LS: answers the library itself marks least-squares (not counted wrong); no solution: a "
             "pose without an exact answer; missing: the generating configuration not among the exact answers that "
             "reach the pose (1e-6 rad per joint; at q5 = 0 only the joints the pose fixes: q1, q2, q3, q5 on the KR5, "
             "q1 and q5 on the UR5, whose axes 2, 3, 4 and 6 are then parallel). Times: CPU time per pose, best "
             f"of {REPEAT}; batched over every pose in one call (ik-geo has no batch call: one call per pose), one "
             f"pose per call over {SINGLE:,}.", "",
             "| arm | library | family | batched, per pose | one pose per call | random: wrong / no solution / "
             "missing / flagged LS | wrist-singular: wrong / no solution / missing / flagged LS | answers per "
             "random pose |",
             "|---|---|---|---|---|---|---|---|"]
    notes = []
    for name, row in rows.items():
        for label in ("ours", "EAIK", "ik-geo"):
            info = row[label]
            if "counts" not in info:
                lines.append(f"| {name} | {label} | - | - | - | {info.get('missing', '-')} | | |")
                continue
            c = info["counts"]
            cells = [f"{c[k]['wrong']} / {c[k]['no solution']} / {c[k]['missing']} / {c[k]['flagged LS']}"
                     for k in ("random", "degenerate")]
            family = info.get("family", "closed form (family of our derivation)" if label == "ours" else "-")
            lines.append(f"| {name} | {label} {info.get('version', '')} | {family} | {_time(info['batched'])} | "
                         f"{_time(info['single'])} | {cells[0]} | {cells[1]} | "
                         f"{c['random']['answers per pose']:.2f} |")
            if label == "EAIK":
                notes.append(f"- {name}: EAIK's forward kinematics against ours {info['fk']:.1e}; its batch on 4 "
                             f"threads {_time(info['batched, 4 threads (wall)'])} per pose (wall time).")
    return "\n".join(lines + [""] + notes + [""] + interleaved_report(rows)) + "\n"


def interleaved_report(rows) -> list[str]:
    lines = [f"## One pose per call, interleaved ({ROUNDS} rounds)", "",
             f"Each round times every library on the same {SINGLE:,} poses, one 4 x 4 per call (ours also on the "
             "12-vector), in an order shuffled per round; CPU time per call. ratio: per round, the library's time "
             "over ours (the 4 x 4) in that round, the median of the rounds: it does not move with the machine's "
             "speed, which the best and median rounds do.", "",
             "| arm | library | best round | median round | slowest round | median ratio to ours |",
             "|---|---|---|---|---|---|"]
    notes = []
    for name, row in rows.items():
        rounds = {label: np.array(times) for label, times in row["interleaved"].items()}
        for label, times in rounds.items():
            ratio = np.median(times / rounds["ours"])
            lines.append(f"| {name} | {label} | {_time(times.min())} | {_time(np.median(times))} | "
                         f"{_time(times.max())} | {ratio:.2f} |")
        if "EAIK" in rounds:
            ratio = np.median(rounds["EAIK"] / rounds["ours"])
            notes.append(f"- {name}: EAIK's call takes {ratio:.2f} times ours in the same rounds; where EAIK takes "
                         f"4.4 to 5.1 us a call (issue #26's figures), ours takes {4.4 / ratio:.2f} to "
                         f"{5.1 / ratio:.2f} us (the issue's target: at most 1 us).")
    return lines + [""] + notes


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "peers_ik.md")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--name", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        import json
        print(json.dumps(measure(args.worker, args.name)))
        return 0
    import json
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    rows = {}
    env = dict(os.environ, PYTHONPATH=str(REPO))
    with tempfile.TemporaryDirectory(prefix="kinegen-peers-") as root:
        for name in ARMS:
            path = REPO / "tests" / "data" / "arms" / f"{name}.toml"
            subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(path), "--no-dynamics", "--out",
                            str(Path(root) / name)], check=True, cwd=REPO, env=env)
            say(f"{name}: generated")
            run = subprocess.run([sys.executable, __file__, "--worker", root, "--name", name], check=True,
                                 capture_output=True, text=True, cwd=REPO, env=env)
            rows[name] = json.loads(run.stdout.strip().splitlines()[-1])
    ended = datetime.datetime.now(datetime.timezone.utc).strftime("%H:%M")
    args.out.write_text(report(rows, started, ended), encoding="utf-8")
    say(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

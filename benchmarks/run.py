"""Benchmarks: our kernels against what a user would pick instead, in one run, as ratios.

    python benchmarks/run.py            # the full run (what `make bench` does)
    python benchmarks/run.py --quick    # a small smoke run: few poses, no cold derivation

Times, in one process on this machine, with a warm-up call and the median of
repeated samples, the contenders of a row sampled in turn (so that a drift of
the shared machine's speed does not land in their ratios):

* batched, per pose: our C and numpy ``fk``, ``jacobian``, ``ik`` against
  ``sympy.lambdify(..., cse=True)`` of the same expressions, the Robotics Toolbox
  for Python and Pinocchio (the peers loop in Python where they have no batch call);
* one pose per call from Python, the same set;
* inside C: a driver compiled here calls the generated C with no Python around it;
* derivation: ``python -m codegen generate`` (what ``make generate`` runs) from an
  empty derivation cache, per robot and for all robots.

Prints one report and writes it (``--out``, default ``benchmarks/results.md``)
with the machine, the versions and the date; every figure is also given as a
speed-up over the lambdify baseline and over the best peer.
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import sympy  # noqa: E402

import contenders as peers  # noqa: E402
import inside_c  # noqa: E402

ROBOTS = ("puma560", "adept_three", "planar_3r")
MODES = {"batch": "Batched: one call for many poses, time per pose",
         "single": "One pose per call from Python, time per call"}
OURS = ("kinegen C", "kinegen numpy")
BASELINE = "lambdify(cse=True)"
NOT_COMPARED = ("RTB analytic_ik", "Pinocchio, result as numpy")  # no fk/Jacobian of their own to compare


# -- timing -----------------------------------------------------------------------------------

def _calls_per_sample(run: peers.Run, min_time: float) -> tuple[int, float]:
    """(calls, seconds): how many calls of ``run`` one sample makes to last at least ``min_time``."""
    run.call()  # warm-up: first-call caches, page faults of the outputs
    number, elapsed = 1, 0.0
    while True:
        start = time.perf_counter()
        for _ in range(number):
            run.call()
        elapsed = time.perf_counter() - start
        if elapsed >= min_time or number >= 1 << 20:
            return number, elapsed
        number = max(2 * number, int(number * 1.2 * min_time / max(elapsed, 1e-9)))


def interleaved(runs: list[peers.Run], repeat: int, min_time: float) -> list[float]:
    """Median time per pose of each run, their samples taken in turn.

    Each of ``repeat`` rounds takes one sample (at least ``min_time``) of every run,
    so that all of them see the machine in the same states: on a shared machine
    its speed drifts by tens of percent within a minute, which would otherwise
    land in the ratios.  A run whose sample takes over a second stops after
    ``max(3, repeat // 2)`` samples.
    """
    plans = [_calls_per_sample(run, min_time) for run in runs]
    samples: list[list[float]] = [[] for _ in runs]
    for round_ in range(repeat):
        for run, (number, elapsed), taken in zip(runs, plans, samples):
            if elapsed >= 1.0 and round_ >= max(3, repeat // 2):
                continue
            start = time.perf_counter()
            for _ in range(number):
                run.call()
            taken.append((time.perf_counter() - start) / number)
    return [statistics.median(taken) / run.items for run, taken in zip(runs, samples)]


def seconds_per_pose(run: peers.Run, repeat: int, min_time: float) -> float:
    """Median over ``repeat`` samples of the time per pose; each sample lasts at least ``min_time``."""
    return interleaved([run], repeat, min_time)[0]


def format_time(seconds: float) -> str:
    if seconds < 1e-6:
        return f"{seconds * 1e9:.3g} ns"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.3g} µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def format_ratio(ratio: float) -> str:
    return f"{ratio:.3g}×"


# -- the run ----------------------------------------------------------------------------------

def machine() -> dict[str, str]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cc = os.environ.get("CC", "cc")
    try:
        compiler = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    except (OSError, IndexError):
        compiler = "unknown"
    return {"cpu": cpu, "cores": str(os.cpu_count()), "system": f"{platform.system()} {platform.release()}",
            "python": platform.python_version(), "compiler": compiler}


def load_average() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "unknown"


def time_everything(robots, count, loop, slow_loop, repeat, min_time, say):
    rtb = peers.RoboticsToolbox()
    contenders = [peers.Kinegen("c"), peers.Kinegen("numpy"), peers.Lambdify(), rtb,
                  peers.RoboticsToolboxAnalytic(rtb), peers.Pinocchio(), peers.Pinocchio(with_result=True)]
    figures, agreement = {}, {}
    for robot in robots:
        work = peers.workload(robot, count, loop, slow_loop)
        agreement[robot] = peers.agreement(contenders, work)
        for mode in MODES:
            for kernel in peers.KERNELS:
                runs = {}
                for c in contenders:
                    try:
                        made = c.make(work, kernel, mode)
                        if isinstance(made, peers.Run):
                            made.call()  # one call first: a peer that fails is reported, not fatal
                            runs[c.name] = made
                    except Exception as exc:
                        made = peers.Missing(f"failed: {type(exc).__name__}: {exc}"[:80])
                    figures[(mode, robot, kernel, c.name)] = made
                say(f"{mode:6s} {robot} {kernel}: {', '.join(runs)}, in turn")
                for name, seconds in zip(runs, interleaved(list(runs.values()), repeat, min_time)):
                    figures[(mode, robot, kernel, name)] = (seconds, runs[name].note)
    return contenders, figures, agreement


def rtb_c_source(contenders) -> tuple[str | None, str]:
    """The Robotics Toolbox's generated C for the Puma 560's closed form, or why there is none."""
    analytic = next(c for c in contenders if isinstance(c, peers.RoboticsToolboxAnalytic))
    if analytic.toolbox.missing:
        return None, analytic.toolbox.missing
    try:
        return analytic.solver("puma560").generate("c", name="rtb_ikine"), ""
    except Exception as exc:
        return None, f"{type(exc).__name__}: {exc}"


def time_derivation(robots, say) -> dict[str, float]:
    """Wall seconds of ``python -m codegen generate [ROBOT]`` with an empty derivation cache."""
    seconds = {}
    for target in [*robots, None]:
        with tempfile.TemporaryDirectory(prefix="kinegen-cold-cache-") as cache:
            env = dict(os.environ, KINEGEN_CACHE=cache)
            command = [sys.executable, "-m", "codegen", "generate", "--quiet", *([target] if target else [])]
            say(f"derivation: {' '.join(command[1:])} (cold cache)")
            start = time.perf_counter()
            subprocess.run(command, cwd=REPO, env=env, check=True, capture_output=True)
            seconds[target or "all"] = time.perf_counter() - start
    return seconds


# -- the report -------------------------------------------------------------------------------

def cell(figures, key, baseline, best):
    value = figures.get(key)
    if value is None:
        return "—"
    if isinstance(value, peers.Missing):
        return value.reason or "—"
    seconds, note = value
    parts = [format_time(seconds)]
    if baseline:
        parts.append(format_ratio(baseline / seconds))
    if best:
        parts.append(format_ratio(best / seconds))
    return " · ".join(parts) + ("¹" if note else "")


def timing_table(figures, mode, robots, names) -> list[str]:
    lines = ["| robot | kernel | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for robot in robots:
        for kernel in peers.KERNELS:
            baseline = figures.get((mode, robot, kernel, BASELINE))
            baseline = baseline[0] if isinstance(baseline, tuple) else None
            peer_times = [v[0] for n in names if n not in OURS
                          for v in [figures.get((mode, robot, kernel, n))] if isinstance(v, tuple)]
            best = min(peer_times) if peer_times else None
            cells = [cell(figures, (mode, robot, kernel, n), baseline, best) for n in names]
            lines.append(f"| {robot} | {kernel} | " + " | ".join(cells) + " |")
    return lines


def best_peer_name(figures, mode, robot, kernel, names):
    best = None
    for n in names:
        v = figures.get((mode, robot, kernel, n))
        if n not in OURS and isinstance(v, tuple) and (best is None or v[0] < best[1]):
            best = (n, v[0])
    return best


def targets(figures, in_c, derivation, names) -> list[str]:
    """The issue's targets for the Puma 560, measured in this run."""
    def get(mode, kernel, name):
        v = figures.get((mode, "puma560", kernel, name))
        return v[0] if isinstance(v, tuple) else None

    rows = []

    def ratio_row(what, ours, theirs, bar):
        if ours is None or theirs is None:
            rows.append(f"| {what} | not measured | ≥ {bar}× | — |")
            return
        r = theirs / ours
        rows.append(f"| {what} | {format_ratio(r)} ({format_time(ours)} vs {format_time(theirs)}) | ≥ {bar}× | "
                    f"{'met' if r >= bar else 'NOT met'} |")

    def below_row(what, value, bar):
        if value is None:
            rows.append(f"| {what} | not measured | < {format_time(bar)} | — |")
            return
        rows.append(f"| {what} | {format_time(value)} | < {format_time(bar)} | {'met' if value < bar else 'NOT met'} |")

    for kernel in ("fk", "jacobian"):
        ratio_row(f"batched C {kernel} vs lambdify", get("batch", kernel, "kinegen C"), get("batch", kernel, BASELINE), 10)
    for kernel in ("fk", "jacobian"):
        ratio_row(f"batched numpy {kernel} vs lambdify", get("batch", kernel, "kinegen numpy"),
                  get("batch", kernel, BASELINE), 1.5)
    below_row("batched C ik (all branches), per pose", get("batch", "ik", "kinegen C"), 1e-6)
    c_ik = in_c.get("puma560", {}).get(("ik", "single"))
    below_row("ik inside C, per call", None if c_ik is None else c_ik * 1e-9, 1e-6)
    ours = get("single", "fk", "kinegen C")
    for peer in ("Pinocchio", "Pinocchio, result as numpy"):
        pin = get("single", "fk", peer)
        what = f"single-call fk from Python vs {peer}"
        if pin is None or ours is None:
            rows.append(f"| {what} | not measured | ≤ 2× its time | — |")
        else:
            rows.append(f"| {what} | {format_time(ours)} vs {format_time(pin)} ({format_ratio(ours / pin)} its time) "
                        f"| ≤ 2× | {'met' if ours <= 2 * pin else 'NOT met'} |")
    all_seconds = derivation.get("all")
    below_row("`make generate`, all robots, cold cache", all_seconds, 60.0)
    return ["| target (Puma 560) | measured | bar | |", "|---|---|---|---|", *rows]


def report(info, versions, settings, figures, names, agreement, in_c, rtb_c_note, derivation, started, ended):
    lines = [
        "# Benchmarks",
        "",
        f"Generated by `make bench` (`benchmarks/run.py{' --quick' if settings['quick'] else ''}`) "
        f"on {started:%Y-%m-%d %H:%M} UTC. Re-run it to reproduce; figures on a shared machine move by "
        "tens of percent between runs, the ratios (measured in the same run) much less.",
        "",
        f"- machine: {info['cpu']}, {info['cores']} cores, {info['system']}",
        f"- load average (1, 5, 15 min) at the start: {settings['load_start']}; at the end: {load_average()}",
        f"- Python {info['python']}, " + ", ".join(f"{k} {v}" for k, v in versions.items()),
        f"- compiler: {info['compiler']}; generated C built with `{' '.join(settings['flags'])}`",
        f"- batched: {settings['count']} poses per call (the peers' Python loops: "
        f"{settings['loop']} poses, numerical IK {settings['slow_loop']}); each figure is the median of "
        f"{settings['repeat']} samples of at least {settings['min_time'] * 1e3:.0f} ms after a warm-up call, "
        "the contenders of a row sampled in turn",
        f"- run time: {ended - started}",
        "",
        "Each cell: time · speed-up over lambdify(cse=True) · speed-up over the best peer "
        "(their time / this time, so above 1× is faster). ¹ a Python loop over the poses: "
        "the tool has no batched call. \"Pinocchio\" is the computation alone (forwardKinematics, "
        "computeJointJacobians), its results left in its data structure; \"Pinocchio, result as numpy\" "
        "also reads the pose (`data.oMi[...].homogeneous`) or the tool Jacobian (`getFrameJacobian`) out, "
        "as our kernels return them. The best peer is the fastest of all the peers' columns.",
        "",
    ]
    for mode, title in MODES.items():
        lines += [f"## {title}", "", *timing_table(figures, mode, settings["robots"], names), ""]
    lines += ["## Inside C (a driver compiled with the library's flags, no Python)", "",
              "| robot | kernel | one pose per call | batched, per pose |", "|---|---|---|---|"]
    for robot in settings["robots"]:
        c = in_c.get(robot)
        if isinstance(c, str):
            lines.append(f"| {robot} | — | {c} | |")
            continue
        for kernel in peers.KERNELS:
            single, batch = c.get((kernel, "single")), c.get((kernel, "batch"))
            if single is None:
                lines.append(f"| {robot} | {kernel} | n/a (no ik yet) | |")
            else:
                lines.append(f"| {robot} | {kernel} | {single:.1f} ns | {batch:.1f} ns |")
        rtb = c.get(("rtb_analytic_ik", "single"))
        if robot == "puma560":
            if rtb is not None:
                ours = c.get(("ik", "single"))
                ratio = f" (kinegen C ik: {format_ratio(rtb / ours)} faster)" if ours else ""
                lines.append(f"| {robot} | RTB analytic_ik generated C, all solutions | {rtb:.1f} ns{ratio} | — |")
            else:
                lines.append(f"| {robot} | RTB analytic_ik generated C | n/a ({rtb_c_note}) | — |")
    lines += ["", "## Derivation: `python -m codegen generate` from an empty cache", "",
              "| robots | seconds |", "|---|---|"]
    if derivation:
        lines += [f"| {k} | {v:.1f} |" for k, v in derivation.items()]
    else:
        lines.append("| — | skipped (--quick) |")
    lines += ["", "## Targets", "", *targets(figures, in_c, derivation, names), "",
              "## Same arm? Largest difference from our C fk and Jacobian at three poses", "",
              "| robot | " + " | ".join(n for n in names if n not in OURS and n not in NOT_COMPARED) + " |",
              "|---|" + "---|" * len([n for n in names if n not in OURS and n not in NOT_COMPARED])]
    for robot, errors in agreement.items():
        row = []
        for n in names:
            if n in OURS or n in NOT_COMPARED:
                continue
            row.append(f"{errors[n]:.1e}" if n in errors else "not installed")
        lines.append(f"| {robot} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a small smoke run: few poses, no cold derivation")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results.md")
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS))
    parser.add_argument("--count", type=int, help="poses per batched call (default 100000; --quick 2000)")
    parser.add_argument("--no-derivation", action="store_true", help="skip the cold-cache derivation timing")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)

    def say(message):
        if not args.quiet:
            print(f"[bench] {message}", file=sys.stderr, flush=True)

    quick = args.quick
    settings = {
        "quick": quick, "robots": args.robots, "load_start": load_average(),
        "count": args.count or (2000 if quick else 100_000), "loop": 50 if quick else 1000,
        "slow_loop": 5 if quick else 50, "repeat": 3 if quick else 7, "min_time": 0.002 if quick else 0.05,
    }
    started = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None)
    settings["flags"] = inside_c.library_flags(args.robots[0])
    contenders, figures, agreement = time_everything(args.robots, settings["count"], settings["loop"],
                                                     settings["slow_loop"], settings["repeat"],
                                                     settings["min_time"], say)
    names = [c.name for c in contenders]
    source, rtb_c_note = rtb_c_source(contenders) if "puma560" in args.robots else (None, "")
    in_c = {}
    with tempfile.TemporaryDirectory(prefix="kinegen-bench-") as build:
        for robot in args.robots:
            say(f"inside C: {robot}")
            try:
                in_c[robot] = inside_c.time_in_c(robot, Path(build), 2000 if quick else 100_000,
                                                 5 if quick else 15, source if robot == "puma560" else None)
            except Exception as exc:
                in_c[robot] = f"failed: {exc}"[:200]
    derivation = {} if (quick or args.no_derivation) else time_derivation(args.robots, say)
    versions = {"numpy": np.__version__, "sympy": sympy.__version__}
    for c in contenders:
        label = {"RTB": "roboticstoolbox-python", "Pinocchio": "pin"}.get(c.name)
        if label and getattr(c, "version", None):
            versions[label] = c.version
        elif label and getattr(c, "missing", None):
            versions[label] = c.missing
    ended = datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None, microsecond=0)
    started = started.replace(microsecond=0)
    text = report(machine(), versions, settings, figures, names, agreement, in_c, rtb_c_note, derivation,
                  started, ended)
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    say(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

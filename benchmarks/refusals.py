"""How long, and how much memory, each refusal of work that only a budget used to stop takes
(issue #28, class D4): the command a user runs, in a fresh process, its wall time to exit 2 and
its peak resident memory (the child's own ``ru_maxrss`` from ``os.wait4``).

    python benchmarks/refusals.py [--out benchmarks/refusals.md]

Also one valid file whose structure checks used to be quadratic.  The promise is exit 2 with a one-line message in at most 5 s and 100 MB, for every command
that derives (`generate`, `show`, `latex`, `verify`).  A Python process with SymPy and numpy
imported is most of the memory figure.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LIMIT_SECONDS = 5.0
LIMIT_MB = 100.0


def revolute_line(n: int) -> str:
    """A URDF chain of ``n`` revolute joints l0 -> l1 -> ... -> ln."""
    links = "".join(f'<link name="l{i}"/>' for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" '
                     f'velocity="1"/></joint>' for i in range(n))
    return f'<robot name="r">{links}{joints}</robot>'


def fixed_line(n: int, ring: bool = False) -> str:
    """A URDF of ``n`` fixed joints in a line, or closed into a ring (a loop)."""
    links = "".join(f'<link name="l{i}"/>' for i in range(n + 1))
    joints = "".join(f'<joint name="f{i}" type="fixed"><parent link="l{i}"/>'
                     f'<child link="l{(i + 1) % n if ring else i + 1}"/></joint>' for i in range(n))
    return f'<robot name="r">{links}{joints}</robot>'


def cases(folder: Path) -> list[tuple[str, list[str]]]:
    """(what, argv after `python -m codegen`) of each refusal, its files written into ``folder``."""
    (folder / "long.urdf").write_text(revolute_line(200))
    (folder / "fixed4000.urdf").write_text(fixed_line(4000) .replace(
        "</robot>", '<link name="tip"/><joint name="j" type="revolute"><parent link="l4000"/>'
                    '<child link="tip"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" '
                    'velocity="1"/></joint></robot>'))
    (folder / "ring.urdf").write_text(fixed_line(4000, ring=True))
    (folder / "huge.urdf").write_text("<robot name='r'>" + " " * (11 << 20) + "</robot>")
    params = "".join(f"l{i} = 0.1\n" for i in range(1, 7))
    (folder / "expands.toml").write_text(
        f'name = "arm"\n[params]\n{params}[[joint]]\ntype = "R"\na = "(l1+l2+l3+l4+l5+l6)**64"\n')
    os.mkfifo(folder / "fifo")
    (folder / "fifo.toml").write_text('name = "arm"\nurdf = "fifo"\n')
    (folder / "zero.toml").write_text('name = "arm"\nurdf = "/dev/zero"\n')
    out = ["--out", str(folder / "pkg")]
    found = []
    for what, file in [("200 revolute joints (URDF)", "long.urdf"), ("a ring of 4,000 fixed joints (URDF)", "ring.urdf"),
                       ("an 11 MiB URDF", "huge.urdf"), ("(l1+...+l6)**64 in a TOML field", "expands.toml"),
                       ("urdf = a FIFO (TOML)", "fifo.toml"), ("urdf = /dev/zero (TOML)", "zero.toml")]:
        found.append((what, "generate", ["generate", str(folder / file), *out]))
        found.append((what, "show", ["show", str(folder / file)]))
    # not a refusal: a valid file, whose structure checks (once quadratic: 16 s) must be quick
    found.append(("4,000 fixed joints, then one revolute (URDF, valid: exit 0)", "show",
                  ["show", str(folder / "fixed4000.urdf")]))
    found.append(("(l1+...+l6)**64 in a TOML field", "latex", ["latex", str(folder / "expands.toml")]))
    return found


def run(argv: list[str]) -> tuple[int, float, float, str]:
    """(exit status, seconds, peak MB, first line of stderr) of ``python -m codegen argv``."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    start = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-m", "codegen", "--quiet", *argv], cwd=ROOT, env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    stderr = process.stderr.read()
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    return process.returncode, seconds, usage.ru_maxrss / 1024.0, (stderr.strip().splitlines() or [""])[0]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "refusals.md")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="kinegen-refusals-") as folder:
        for what, command, argv in cases(Path(folder)):
            status, seconds, megabytes, message = run(argv)
            written = (Path(folder) / "pkg").exists()
            expected = 0 if "valid" in what else 2
            ok = status == expected and seconds <= LIMIT_SECONDS and megabytes <= LIMIT_MB and not written
            rows.append(f"| {what} | `{command}` | {status} | {seconds:.2f} | {megabytes:.0f} | "
                        f"{'yes' if written else 'no'} | {'ok' if ok else 'OVER'} | {message[:90].replace('|', '/')} |")
            print(rows[-1], flush=True)
    text = "\n".join([
        "# Refusals of work only a budget used to stop (issue #28, D4)",
        "",
        f"Written by `benchmarks/refusals.py` on {date.today().isoformat()} ({os.cpu_count()} cores): each command in a",
        f"fresh process; the promise is exit 2 in at most {LIMIT_SECONDS:g} s and {LIMIT_MB:g} MB, nothing written.",
        "",
        "| input | command | exit | seconds | peak MB | wrote | | message |",
        "|---|---|---|---|---|---|---|---|",
        *rows, ""])
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0 if all(r.split("|")[7].strip() == "ok" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())

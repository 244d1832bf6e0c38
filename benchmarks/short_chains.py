"""The closed-form ik of short chains and of the tasks 4- to 6-joint arms reach in full (issue #26, item 2).

Per arm of ``tests/ik/test_ik_short_chains.py`` (the README's cylindrical R P P, the Stanford arm's
R R P position chain, the AL5D from its DH table and its URDF, the SO-101 URDF, a UR5 and a KR5
with x, y, z, approach):

* the cold derivation in a fresh process with the derivation cache off: ``derivations.load``
  (the model with its ik), then ``derivations.ik.solve`` alone;
* the package from ``kinegen generate`` (portable C, as a user's package builds);
* 10,000 random configurations and 1,000 degenerate ones (every revolute joint at 0, +-pi/2 or
  pi, every prismatic one at an end or the middle of its range), their targets and the answers
  through the test file's own forward kinematics (a DH product, or the URDF read with
  ElementTree): wrong (a valid branch off by more than 1e-9), no solution, missing (the
  generating configuration not among the valid branches, up to what a singular configuration
  leaves free), in both backends;
* ik per pose, batched over the 11,000 targets from Python (median of 5), numpy and C.

Writes ``benchmarks/short_chains.md``.  Run with the project's environment (it reads the tests'
helpers, which import pytest): ``.venv/bin/python benchmarks/short_chains.py``.
"""
from __future__ import annotations

import datetime
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))  # and its layer folders: the helpers import one another
sys.path[1:1] = [str(p) for p in sorted((REPO / "tests").iterdir()) if p.is_dir() and p.name not in ("data", "__pycache__")]

import test_ik_short_chains as t  # noqa: E402

RANDOM, DEGENERATE = 10_000, 1_000
OUT = REPO / "benchmarks" / "short_chains.md"

COLD = r"""
import json, sys, time
start = time.perf_counter()
import derivations
from derivations.ik import solve
imported = time.perf_counter()
options = json.loads(sys.argv[2])
model = derivations.load(sys.argv[1], **options)
loaded = time.perf_counter()
solution = solve(model)
done = time.perf_counter()
print(json.dumps({"model": loaded - imported, "ik": done - loaded, "family": solution.family}))
"""


def position_case(name, text, title, source, branches, folder: Path):
    path = folder / f"{name}.toml"
    path.write_text(f"# {source}\n{text}")
    arm = t.read_arm(path)
    return t.Case(title, source, "position", branches, (path, {}), arm.types,
                  lambda q: t.dh_fk(arm, q)[..., :3, 3], limits=arm.limits, cli=(str(path),))


def cold(case) -> dict:
    path, options = case.load
    options = {k: v for k, v in options.items()}
    env = dict(os.environ, KINEGEN_NO_CACHE="1", PYTHONPATH=str(REPO))
    run = subprocess.run([sys.executable, "-c", COLD, str(path), json.dumps(options)], env=env, cwd=REPO,
                         capture_output=True, text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def generate(name, case, folder: Path):
    out = folder / name
    subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", *case.cli, "--out", str(out), "--force"],
                   cwd=REPO, check=True, env=dict(os.environ, PYTHONPATH=str(REPO)), capture_output=True, text=True)
    sys.path.insert(0, str(folder))
    importlib.invalidate_caches()
    package = importlib.import_module(out.name)
    sys.path.remove(str(folder))
    return package


def configurations(case, seed):
    saved = t.RANDOM, t.DEGENERATE
    t.RANDOM, t.DEGENERATE = RANDOM, DEGENERATE
    try:
        return t.configurations(case.types, case.limits, seed)
    finally:
        t.RANDOM, t.DEGENERATE = saved


def round_trip(case, kernels, q, x):
    free = {} if case.free is None else {"free": q[:, case.free]}
    Q, valid = kernels.ik(x, **free)
    reached = np.stack([case.target(np.where(valid[:, b, None], Q[:, b], 0.0)) for b in range(Q.shape[1])], axis=1)
    miss = reached - x[:, None, :]
    names = list(kernels.TASK)
    angles = [i for i, n in enumerate(names) if n in ("pitch", "roll")]
    miss[..., angles] = t.wrap(miss[..., angles])
    error = np.where(valid, np.abs(miss).max(axis=-1), 0.0)
    difference = Q - q[:, None, :]
    revolute = [i for i, kind in enumerate(case.types) if kind == "R"]
    difference[..., revolute] = t.wrap(difference[..., revolute])
    difference = np.abs(difference)
    if case.free_joints is not None:
        mask = case.free_joints(q)
        difference[np.broadcast_to(mask[:, None, :], difference.shape)] = 0.0
    found = (valid & (difference.max(axis=-1) < t.JOINT_TOLERANCE)).any(axis=-1)
    outside = ((np.abs(Q[..., revolute]) > np.pi).any(axis=-1) & valid).sum()
    return {"wrong": int((error > t.FK_TOLERANCE).sum()), "no solution": int((~valid.any(axis=-1)).sum()),
            "missing": int((~found).sum()), "not wrapped": int(outside), "worst": float(error.max())}


def per_pose(kernels, case, q, x, repeat=5):
    free = {} if case.free is None else {"free": q[:, case.free]}
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        kernels.ik(x, **free)
        samples.append(time.perf_counter() - start)
    return float(np.median(samples)) / len(x) * 1e6


def main() -> int:
    rows = []
    with tempfile.TemporaryDirectory(prefix="kinegen-short-") as tmp:
        folder = Path(tmp)
        cases = {
            "cylindrical_rpp": position_case("cylindrical_rpp", t.CYLINDRICAL, "Cylindrical R P P (README)",
                                             "Kumar, Fig. 10 (the README's example)", 2, folder),
            "stanford_rrp": position_case("stanford_rrp", t.STANFORD, "Stanford arm, joints 1-3 (R R P)",
                                          "Paul, Stanford AIM-177, Fig. 2.3", 4, folder),
            **t.CASES,
            # the other six-joint arms of the zoo with x, y, z, approach (joint 6 free), in the bench only
            **{f"{name}_approach": t._dh_case(name, "x,y,z,approach", f"{title}, approach",
                                               "position and approach, joint 6 free", 8,
                                               approach_singular=([1, 2, 3], 1) if name.startswith("ur") else ([3], 3))
               for name, title in (("abb_irb140", "ABB IRB 140"), ("meca500", "Meca500"), ("ur10", "UR10"))},
        }
        for name, case in cases.items():
            times = cold(case)
            try:
                package = generate(f"sc_{name}", case, folder)
            except subprocess.CalledProcessError as error:  # said in the table, the other arms still run
                rows.append({"name": name, "title": case.title, "family": times["family"], "branches": case.branches,
                             "model": times["model"], "ik": times["ik"],
                             "failed": (error.stderr or "").strip().splitlines()[-1:] or ["generate failed"]})
                print(json.dumps(rows[-1]), flush=True)
                continue
            q = configurations(case, zlib.crc32(f"bench {name}".encode()))
            x = case.target(q)
            row = {"name": name, "title": case.title, "family": times["family"], "branches": case.branches,
                   "model": times["model"], "ik": times["ik"]}
            for backend in ("numpy", "c"):
                kernels = package.load(backend)
                row[backend] = round_trip(case, kernels, q, x)
                row[f"{backend} us"] = per_pose(kernels, case, q, x)
            print(json.dumps(row), flush=True)
            rows.append(row)
    write(rows)
    return 0 if all("failed" not in r and r[b][k] == 0 for r in rows for b in ("numpy", "c")
                    for k in ("wrong", "no solution", "missing", "not wrapped")) else 1


def write(rows):
    lines = [
        "# Short chains and the tasks 4- to 6-joint arms reach in full",
        "",
        f"Written by `benchmarks/short_chains.py` on {datetime.date.today().isoformat()} ({os.cpu_count()} CPUs; "
        "part of `make bench`). Per arm: the cold derivation in a fresh process with the cache off "
        "(`derivations.load`, the model with its ik; then `derivations.ik.solve` alone); "
        f"{RANDOM:,} random and {DEGENERATE:,} degenerate configurations through the test file's own forward "
        "kinematics (wrong: a valid branch off by more than 1e-9; missing: the generating configuration not among "
        "the valid branches, up to what a singular configuration leaves free); ik per pose batched over those "
        "targets from Python (portable C, as `kinegen generate` builds it).",
        "",
        "| arm | family | branches | model + ik, cold (s) | ik alone (s) | numpy (us/pose) | C (us/pose) | "
        "wrong / no solution / missing (numpy; C) | worst FK error |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['title']} | {r['family']} | {r['branches']} | {r['model']:.2f} | {r['ik']:.2f} | "
                         f"generate failed: {r['failed'][0]} | | | |")
            continue
        counts = "; ".join(f"{r[b]['wrong']} / {r[b]['no solution']} / {r[b]['missing']}" for b in ("numpy", "c"))
        worst = max(r["numpy"]["worst"], r["c"]["worst"])
        lines.append(f"| {r['title']} | {r['family']} | {r['branches']} | {r['model']:.2f} | {r['ik']:.2f} | "
                     f"{r['numpy us']:.2f} | {r['c us']:.2f} | {counts} | {worst:.1e} |")
    OUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT.relative_to(REPO)}")


if __name__ == "__main__":
    sys.exit(main())

"""Any description compiles (issue #14, item 1), and generation is bounded (item 6).

A seeded spread of synthetic chains: 1 to 8 joints, revolute and prismatic mixed,
standard and modified DH, every task choice a chain allows, with and without tool and
base frames, parameters and plain numbers.  Each is derived and rendered, and its C
(every layout: plain, blocked, SIMD) and its one-point file are compiled under
``-std=c99 -Wall -Wextra -Werror -pedantic``: a helper emitted where nothing calls it,
a name declared twice or an unused variable stops the compile.  The chains' kernels are
then checked where a check is cheap: fk of the generated numpy module against a DH
product written here.
"""
from __future__ import annotations

import math
import random
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

import numpy as np
import pytest

import derivations
from codegen.backends.c_backend import STRICT_FLAGS
from codegen.generate import render_robot

ROOT = Path(__file__).resolve().parents[1]
LAYOUTS = {"plain": [], "blocked": ["-DKINEGEN_BLOCKED"], "simd": ["-DKINEGEN_SIMD", "-fopenmp-simd"]}
ANGLES = ["0", "pi/2", "-pi/2", "pi", "pi/2", "0"]  # the twists real arms use (the zoo has pi/3 too)


def synthetic(seed: int) -> tuple[str, dict]:
    """A description text and what it says (for the test's own fk): joints 1 + seed % 8."""
    rng = random.Random(seed)
    n = 1 + seed % 8
    convention = "modified" if seed % 3 == 1 else "standard"
    types = [rng.choice("RRRP") for _ in range(n)]
    planar = seed % 5 == 2  # every axis along z: the planar tasks (phi) apply
    joints, spec = [], []
    params = {"l1": 0.3, "l2": 0.25}
    for i, kind in enumerate(types):
        a = rng.choice(["0", "l1", "l2", "0.2", "0.15"])
        alpha = "0" if planar else rng.choice(ANGLES)
        if planar and kind == "P":
            alpha = "0"
        fixed = rng.choice(["0", "l1", "0.1", "-0.05"])
        offset = rng.choice(["0", "pi/2", "0.05"]) if kind == "R" else rng.choice(["0", "0.1"])
        lines = [f'type = "{kind}"', f'a = "{a}"', f'alpha = "{alpha}"', f'offset = "{offset}"']
        lines.append(f'd = "{fixed}"' if kind == "R" else f'theta = "{rng.choice(["0", "pi/2"])}"')
        joints.append("[[joint]]\n" + "\n".join(lines))
        spec.append(dict(type=kind, a=a, alpha=alpha, d=fixed if kind == "R" else "0",
                         theta="0" if kind == "R" else lines[-1].split('"')[1], offset=offset))
    if planar and all(t == "R" for t in types):
        task = rng.choice([["x", "y", "phi"], ["x", "y"], ["phi"]])
    else:
        task = rng.choice([["pose"], ["x", "y", "z"], ["x", "y"], ["z"], ["pose"]])
    tool = seed % 2 == 0
    base = seed % 4 == 3
    text = [f'name = "chain{seed}"', f'convention = "{convention}"', f"task = {task!r}".replace("'", '"'),
            "[params]", "l1 = 0.3", "l2 = 0.25"]
    text += joints
    if tool:
        text.append('[tool]\nxyz = [0, 0.02, "l2"]\nrpy = [0, "pi/2", 0]')
    if base and not planar:
        text.append('[base]\nxyz = [0.1, 0, 0.5]\nrpy = ["pi", 0, "pi/4"]')
    return "\n".join(text) + "\n", dict(convention=convention, joints=spec, params=params,
                                        tool=tool, base=base and not planar)


SEEDS = list(range(8))  # one chain of each length 1..8: both conventions, tools, a base, planar tasks


def _value(text: str, params: dict) -> float:
    return float(eval(text, {"__builtins__": {}, "pi": math.pi}, dict(params)))  # our own strings only


def _rot(axis: str, t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    m = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def _trans(x, y, z) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def independent_fk(info: dict, q: np.ndarray) -> np.ndarray:
    """The DH product written out here (not the project's chain code)."""
    p = info["params"]
    T = _trans(0.1, 0, 0.5) @ _rot("z", math.pi / 4) @ _rot("y", 0) @ _rot("x", math.pi) if info["base"] else np.eye(4)
    for joint, qi in zip(info["joints"], q):
        a, alpha = _value(joint["a"], p), _value(joint["alpha"], p)
        offset = _value(joint["offset"], p)
        if joint["type"] == "R":
            theta, d = qi + offset, _value(joint["d"], p)
        else:
            theta, d = _value(joint["theta"], p), qi + offset
        if info["convention"] == "standard":
            T = T @ _rot("z", theta) @ _trans(0, 0, d) @ _trans(a, 0, 0) @ _rot("x", alpha)
        else:
            T = T @ _rot("x", alpha) @ _trans(a, 0, 0) @ _rot("z", theta) @ _trans(0, 0, d)
    if info["tool"]:
        T = T @ _trans(0, 0.02, p["l2"]) @ _rot("y", math.pi / 2)
    return T


def _compile(args: list[str]):
    result = subprocess.run(["cc", *STRICT_FLAGS, "-O0", *args], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-3000:]


@pytest.mark.parametrize("seed", SEEDS)
def test_synthetic_chain_generates_and_compiles_strictly(seed, tmp_path):
    text, info = synthetic(seed)
    path = tmp_path / f"chain{seed}.toml"
    path.write_text(text)
    model = derivations.load(path)
    files = render_robot(model, path, latex=True)
    package = tmp_path / model.name
    package.mkdir()
    for name, content in files.items():
        (package / name).write_text(content)
    for layout, flags in LAYOUTS.items():
        _compile([*flags, "-c", str(package / f"{model.name}.c"), "-o", str(tmp_path / f"{layout}.o")])
    _compile(["-DKINEGEN_PYTHON_MODULE", "-I", str(package), "-isystem", sysconfig.get_paths()["include"],
              "-isystem", np.get_include(), "-c", str(package / f"{model.name}_point.c"), "-o", str(tmp_path / "point.o")])
    sys.path.insert(0, str(tmp_path))
    try:
        module = __import__(model.name)
    finally:
        sys.path.remove(str(tmp_path))
    q = np.random.default_rng(seed).uniform(-1.5, 1.5, (20, model.n))
    expected = np.stack([independent_fk(info, row) for row in q])
    assert np.abs(module.fk(q) - expected).max() < 1e-12
    frames = module.frames(q)
    assert frames.shape == (20, model.n + 1 + info["tool"], 4, 4)


def test_the_spread_covers_what_the_issue_lists():
    infos = [synthetic(seed) for seed in SEEDS]
    counts = {len(info["joints"]) for _, info in infos}
    assert counts == set(range(1, 9))
    assert {info["convention"] for _, info in infos} == {"standard", "modified"}
    assert any(info["tool"] for _, info in infos) and any(not info["tool"] for _, info in infos)
    assert any(info["base"] for _, info in infos)
    kinds = [{j["type"] for j in info["joints"]} for _, info in infos]
    assert any(k == {"R", "P"} for k in kinds)
    tasks = {text.split("task = ")[1].split("\n")[0] for text, _ in infos}
    assert len(tasks) >= 4


def test_generate_stops_at_its_time_limit_naming_the_stage(tmp_path):
    """A derivation past --time-limit exits 2 with the stage named, and writes nothing."""
    text, _ = synthetic(7)  # 8 joints
    path = tmp_path / "slow.toml"
    path.write_text(text)
    out = tmp_path / "out_package"
    result = subprocess.run([sys.executable, "-m", "codegen", "generate", str(path), "--out", str(out),
                             "--time-limit", "0.5", "--no-build"], cwd=ROOT, capture_output=True, text=True,
                            timeout=120, env={"KINEGEN_NO_CACHE": "1", "PATH": "/usr/bin:/bin",
                                              "PYTHONPATH": str(ROOT)})
    assert result.returncode == 2, result.stderr
    assert "time budget of 0.5 s while" in result.stderr
    assert "nothing was written" in result.stderr
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["slow.toml"]


@pytest.mark.parametrize("limit", ["0", "-3", "abc", "inf"])
def test_time_limit_must_be_a_positive_number(limit, tmp_path):
    result = subprocess.run([sys.executable, "-m", "codegen", "generate", "x.toml", "--time-limit", limit],
                            cwd=tmp_path, capture_output=True, text=True, timeout=60,
                            env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)})
    assert result.returncode == 2
    assert "--time-limit" in result.stderr and "seconds" in result.stderr


def test_base_frame_puts_the_arm_in_the_world(tmp_path):
    """[base] with rpy = (pi, 0, 0): a one-link arm mounted upside down reaches down, and its
    frames and Jacobian are in the world frame (z axis of joint 1 is -z)."""
    path = tmp_path / "hanging.toml"
    path.write_text(textwrap.dedent('''
        name = "hanging"
        [[joint]]
        type = "R"
        a = 0.5
        [base]
        xyz = [0, 0, 2]
        rpy = ["pi", 0, 0]
    '''))
    model = derivations.load(path)
    import sympy as sp
    q1 = model.q[0]
    assert model.frames[0] == sp.Matrix([[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 2], [0, 0, 0, 1]])
    assert sp.simplify(model.fk[:3, 3] - sp.Matrix([sp.cos(q1) / 2, -sp.sin(q1) / 2, 2])) == sp.zeros(3, 1)
    assert list(model.jacobian[3:, 0]) == [0, 0, -1]

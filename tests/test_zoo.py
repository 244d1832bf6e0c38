"""The zoo of real arms (issue #14): every description in tests/data/arms/ against an
independent forward kinematics written here.

Nothing below uses the project's parser, chains or kernels to compute an expected value:
the TOML is read with ``tomllib``, its expression strings are evaluated by the small
evaluator of this file (floats, ``pi``, ``deg``, ``sin``, ``cos``, ``tan``, ``sqrt`` and the
file's own parameters, on a restricted ``ast``), and the pose is a plain numpy product of
the textbook link transforms:

- standard DH:  A_i = Rot(z, theta_i) Trans(z, d_i) Trans(x, a_i) Rot(x, alpha_i),
  joint i turning about / sliding along z_{i-1};
- modified DH (Craig): A_i = Rot(x, alpha_{i-1}) Trans(x, a_{i-1}) Rot(z, theta_i) Trans(z, d_i),
  joint i about / along z_i (the file's a, alpha of joint i are Craig's a_{i-1}, alpha_{i-1});
- T = Base A_1 ... A_n Tool, Base and Tool from xyz and rpy = Rz(yaw) Ry(pitch) Rx(roll).

The geometric Jacobian [v; w] of the tool point comes from the same frames by the
cross-product rule, and is itself held to central finite differences of this file's fk
(linear part) and of the rotation's log map (angular part).

Three paths are compared with it:

1. ``test_source_table``: each file carries the numbers its cited source prints (the
   source's own lists are copied here, in its units), so a transcription slip fails.
2. ``test_model_*``: ``derivations.load(file)`` (the SymPy model, not the kernels),
   its fk and jacobian lambdified, on 200 random configurations within the joint limits.
3. ``test_generated_*``: each arm generated once per session (``python -m codegen generate
   FILE --out DIR``), imported, and its numpy and C (backend "c") fk and jacobian checked on
   the same configurations; then the rate kernels (``test_rates_*``): joint velocities from
   task rates against the pseudo-inverse of this file's Jacobian, the manipulability against
   its determinant, the singular flag against its condition number, and the flag's
   invariance under scaling the arm by 10.  The C is built as ``generate`` builds it by default
   (portable C99 -O2: the same expressions, a fraction of the compile time) except for the
   Cobra 600, which gets the vectorised build of ``generate --fast``.

Tolerance: 1e-12 on the max-norm error of each output, relative to max(1, max |expected|)
(rotation entries are unit scale, positions and Jacobian entries at most a few metres).
"""
from __future__ import annotations

import ast
import fcntl
import importlib
import math
import os
import re
import subprocess
import sys
import time
import tomllib
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from conftest import shared_folder

ROOT = Path(__file__).resolve().parents[1]
ARMS_DIR = Path(__file__).resolve().parent / "data" / "arms"
ARM_FILES = sorted(ARMS_DIR.glob("*.toml"))
SAMPLES = 200
TOLERANCE = 1e-12
GENERATE_TIMEOUT = 600  # seconds per arm, compile included
VECTORISED = {"adept_cobra600"}  # arms built with --fast (the SIMD layout); the rest portable C99


# --------------------------------------------------------------------------- evaluator

_FUNCTIONS = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "sqrt": math.sqrt,
              "deg": lambda x: x * math.pi / 180}
_BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
           ast.Div: lambda a, b: a / b, ast.Pow: lambda a, b: a ** b}


def evaluate(value, names: dict[str, float]) -> float:
    """A description field as a float: a number, or an expression of ``names``, pi and _FUNCTIONS."""
    if isinstance(value, bool):
        raise ValueError(f"boolean {value!r} is not a number")
    if isinstance(value, (int, float)):
        return float(value)
    return _node(ast.parse(value.strip(), mode="eval").body, names)


def _node(node, names):
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.Name):
        if node.id == "pi":
            return math.pi
        return names[node.id]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _node(node.operand, names)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _BINARY[type(node.op)](_node(node.left, names), _node(node.right, names))
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCTIONS
            and len(node.args) == 1 and not node.keywords):
        return _FUNCTIONS[node.func.id](_node(node.args[0], names))
    raise ValueError(f"not allowed in a description: {ast.dump(node)}")


def test_evaluator_reads_the_forms_the_files_use():
    names = {"d1": 0.5}
    assert evaluate("pi/2", names) == math.pi / 2
    assert evaluate("deg(-170)", names) == -170 * math.pi / 180
    assert evaluate("-(d1 + sin(deg(30))/sin(deg(60))*d1)", names) == pytest.approx(-0.5 * (1 + 1 / math.sqrt(3)))
    assert evaluate(0.25, names) == 0.25
    for bad in ("__import__('os')", "d1.real", "open('x')", "[1][0]"):
        with pytest.raises((ValueError, KeyError)):
            evaluate(bad, names)


def _stack(rows):
    return np.moveaxis(np.array(rows, dtype=float), (0, 1), (-2, -1))


def rot_x(t):
    t = np.asarray(t, dtype=float)
    c, s, o, z = np.cos(t), np.sin(t), np.ones_like(t), np.zeros_like(t)
    return _stack([[o, z, z, z], [z, c, -s, z], [z, s, c, z], [z, z, z, o]])


def rot_y(t):
    t = np.asarray(t, dtype=float)
    c, s, o, z = np.cos(t), np.sin(t), np.ones_like(t), np.zeros_like(t)
    return _stack([[c, z, s, z], [z, o, z, z], [-s, z, c, z], [z, z, z, o]])


def rot_z(t):
    t = np.asarray(t, dtype=float)
    c, s, o, z = np.cos(t), np.sin(t), np.ones_like(t), np.zeros_like(t)
    return _stack([[c, -s, z, z], [s, c, z, z], [z, z, o, z], [z, z, z, o]])


def trans(x, y, z):
    x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
    out = np.broadcast_to(np.eye(4), x.shape + (4, 4)).copy()
    out[..., 0, 3], out[..., 1, 3], out[..., 2, 3] = x, y, z
    return out


# --------------------------------------------------------------------------- arms

@dataclass
class Arm:
    path: Path
    name: str
    convention: str
    task: list
    params: dict
    types: list          # "R" / "P"
    a: np.ndarray
    alpha: np.ndarray
    d: np.ndarray        # constant d of revolute joints (unused for prismatic)
    theta: np.ndarray    # constant theta of prismatic joints (unused for revolute)
    offset: np.ndarray
    limits: list         # (low, high) or None
    base: np.ndarray
    tool: np.ndarray
    has_base: bool

    @property
    def n(self):
        return len(self.types)


def read_arm(path: Path) -> Arm:
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    params = {k: evaluate(v, {}) for k, v in data.get("params", {}).items()}
    joints = data["joint"]
    field = lambda key: np.array([evaluate(j.get(key, 0), params) for j in joints])  # noqa: E731
    limits = [None if "limits" not in j else tuple(evaluate(v, {}) for v in j["limits"]) for j in joints]

    def frame(table):
        if table is None:
            return np.eye(4)
        xyz = [evaluate(v, params) for v in table.get("xyz", [0, 0, 0])]
        roll, pitch, yaw = (evaluate(v, params) for v in table.get("rpy", [0, 0, 0]))
        out = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
        out[:3, 3] = xyz
        return out

    return Arm(path=path, name=data["name"], convention=data.get("convention", "standard"),
               task=data.get("task", ["pose"]), params=params, types=[j["type"] for j in joints],
               a=field("a"), alpha=field("alpha"), d=field("d"), theta=field("theta"), offset=field("offset"),
               limits=limits, base=frame(data.get("base")), tool=frame(data.get("tool")),
               has_base="base" in data)


ARMS = {p.stem: read_arm(p) for p in ARM_FILES}
NAMES = list(ARMS)


def test_the_zoo_is_complete():
    """At least 12 arms; every family issue #14 asks for is present; names are the file stems."""
    assert len(ARMS) >= 12
    for stem, arm in ARMS.items():
        assert arm.name == stem
        assert arm.path.read_text(encoding="utf-8").startswith("#"), f"{stem}: no source comment at the top"
        assert arm.name not in sys.stdlib_module_names
    counts = {stem: arm.n for stem, arm in ARMS.items()}
    assert any(arm.n == 7 and arm.convention == "modified" for arm in ARMS.values())    # Panda
    assert sum(n == 7 for n in counts.values()) >= 2                                     # + LWR 4
    assert any("P" in arm.types and arm.n == 6 for arm in ARMS.values())                 # Stanford
    assert any(arm.task == ["x", "y", "z", "phi"] for arm in ARMS.values())              # SCARA
    assert any(arm.n in (4, 5) and arm.task == ["x", "y", "z"] for arm in ARMS.values())  # hobby arm
    assert any(arm.has_base for arm in ARMS.values())
    assert any(not np.allclose(arm.tool, np.eye(4)) for arm in ARMS.values())


# --------------------------------------------------------------------------- independent kinematics

def link_frames(arm: Arm, q: np.ndarray) -> list[np.ndarray]:
    """[Base, Base A1, ..., Base A1..An] for q of shape (N, n) (the tool not applied)."""
    q = np.asarray(q, dtype=float)
    frames = [np.broadcast_to(arm.base, q.shape[:-1] + (4, 4)).copy()]
    for i, kind in enumerate(arm.types):
        if kind == "R":
            theta, d = q[..., i] + arm.offset[i], np.full(q.shape[:-1], arm.d[i])
        else:
            theta, d = np.full(q.shape[:-1], arm.theta[i]), q[..., i] + arm.offset[i]
        zero = np.zeros(q.shape[:-1])
        if arm.convention == "standard":
            link = rot_z(theta) @ trans(zero, zero, d) @ trans(zero + arm.a[i], zero, zero) @ rot_x(zero + arm.alpha[i])
        else:
            link = rot_x(zero + arm.alpha[i]) @ trans(zero + arm.a[i], zero, zero) @ rot_z(theta) @ trans(zero, zero, d)
        frames.append(frames[-1] @ link)
    return frames


def fk(arm: Arm, q) -> np.ndarray:
    return link_frames(arm, q)[-1] @ arm.tool


def jacobian(arm: Arm, q) -> np.ndarray:
    """Geometric Jacobian [v; w] of the tool point in the base (world) frame, by cross products."""
    frames = link_frames(arm, q)
    p = (frames[-1] @ arm.tool)[..., :3, 3]
    columns = []
    for i, kind in enumerate(arm.types):
        frame = frames[i] if arm.convention == "standard" else frames[i + 1]
        z, o = frame[..., :3, 2], frame[..., :3, 3]
        if kind == "R":
            columns.append(np.concatenate([np.cross(z, p - o), z], axis=-1))
        else:
            columns.append(np.concatenate([z, np.zeros_like(z)], axis=-1))
    return np.stack(columns, axis=-1)


def rotation_log(r: np.ndarray) -> np.ndarray:
    """The rotation vector of R (angle below pi)."""
    cos = np.clip((np.trace(r, axis1=-2, axis2=-1) - 1) / 2, -1, 1)
    angle = np.arccos(cos)
    axis = np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], -1)
    scale = np.where(angle < 1e-8, 0.5, angle / (2 * np.sin(np.maximum(angle, 1e-300))))
    return axis * scale[..., None]


def configurations(arm: Arm, count: int = SAMPLES) -> np.ndarray:
    """Random joint values within the limits (revolute without limits: -pi .. pi), seeded per arm."""
    rng = np.random.default_rng(zlib.crc32(arm.name.encode()))
    lows, highs = [], []
    for kind, lim in zip(arm.types, arm.limits):
        low, high = lim if lim is not None else ((-math.pi, math.pi) if kind == "R" else (-0.5, 0.5))
        lows.append(low)
        highs.append(high)
    return rng.uniform(lows, highs, size=(count, arm.n))


def relative_error(got, expected) -> float:
    got, expected = np.asarray(got, dtype=float), np.asarray(expected, dtype=float)
    assert got.shape == expected.shape, (got.shape, expected.shape)
    scale = np.maximum(1.0, np.abs(expected).reshape(len(expected), -1).max(axis=1))
    return float((np.abs(got - expected).reshape(len(expected), -1).max(axis=1) / scale).max())


@pytest.mark.parametrize("name", NAMES)
def test_independent_jacobian_is_the_derivative_of_independent_fk(name):
    """The oracle checks itself: cross-product Jacobian against central differences of fk."""
    arm = ARMS[name]
    q = configurations(arm, 20)
    expected = jacobian(arm, q)
    h = 1e-6
    T = fk(arm, q)
    numeric = np.empty_like(expected)
    for j in range(arm.n):
        step = np.zeros(arm.n)
        step[j] = h
        plus, minus = fk(arm, q + step), fk(arm, q - step)
        numeric[..., :3, j] = (plus[..., :3, 3] - minus[..., :3, 3]) / (2 * h)
        # angular velocity in the world frame: log(R(q+h) R(q-h)^T) / 2h
        numeric[..., 3:, j] = rotation_log(plus[..., :3, :3] @ np.swapaxes(minus[..., :3, :3], -1, -2)) / (2 * h)
    assert relative_error(numeric, expected) < 1e-8
    # and fk is a proper rigid transform
    np.testing.assert_allclose(T[..., :3, :3] @ np.swapaxes(T[..., :3, :3], -1, -2),
                               np.broadcast_to(np.eye(3), T.shape[:-2] + (3, 3)), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(T[..., :3, :3]), 1, atol=1e-14)


def test_independent_fk_knows_the_conventions():
    """Hand checks of the oracle itself on one-link chains whose pose is obvious."""
    std = Arm(Path("x"), "one", "standard", ["pose"], {}, ["R"], np.array([0.3]), np.array([math.pi / 2]),
              np.array([0.2]), np.zeros(1), np.zeros(1), [None], np.eye(4), np.eye(4), False)
    T = fk(std, np.array([[math.pi / 2]]))[0]
    # turn pi/2 about z, rise 0.2, then 0.3 along the turned x (= y), then twist about it
    np.testing.assert_allclose(T[:3, 3], [0, 0.3, 0.2], atol=1e-15)
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-15)
    mod = Arm(Path("x"), "one", "modified", ["pose"], {}, ["P"], np.array([0.3]), np.array([math.pi / 2]),
              np.zeros(1), np.zeros(1), np.zeros(1), [None], np.eye(4), np.eye(4), False)
    T = fk(mod, np.array([[0.5]]))[0]
    # twist about x first (z -> -y), slide 0.3 along x, then 0.5 along the new z (= -y)
    np.testing.assert_allclose(T[:3, 3], [0.3, -0.5, 0], atol=1e-15)
    flip = rot_z(0.1) @ rot_y(0.2) @ rot_x(0.3)
    np.testing.assert_allclose(flip[:3, 0], [math.cos(0.1) * math.cos(0.2), math.sin(0.1) * math.cos(0.2),
                                             -math.sin(0.2)], atol=1e-15)


# --------------------------------------------------------------------------- the sources' numbers

# Each source's DH table as it prints it (its units, its order), to hold the files to it.
# standard: rows (theta offset, d, a, alpha); modified: rows (alpha_{i-1}, a_{i-1}, d_i, theta offset).
_pi, _deg, _mm = math.pi, math.pi / 180, 1e-3
_s = math.sin(30 * _deg) / math.sin(60 * _deg)  # Kinova's sin(aa)/sin(2 aa), aa = 30 deg
SOURCE_TABLES = {
    # UR article, UR5 / UR10 / UR3: d, a, alpha lists
    "ur5": ("standard", list(zip([0] * 6, [0.089159, 0, 0, 0.10915, 0.09465, 0.0823],
                                 [0, -0.425, -0.39225, 0, 0, 0], [_pi / 2, 0, 0, _pi / 2, -_pi / 2, 0]))),
    "ur10": ("standard", list(zip([0] * 6, [0.1273, 0, 0, 0.163941, 0.1157, 0.0922],
                                  [0, -0.612, -0.5723, 0, 0, 0], [_pi / 2, 0, 0, _pi / 2, -_pi / 2, 0]))),
    "ur3_inverted": ("standard", list(zip([0] * 6, [0.1519, 0, 0, 0.11235, 0.08535, 0.0819],
                                          [0, -0.24365, -0.21325, 0, 0, 0], [_pi / 2, 0, 0, _pi / 2, -_pi / 2, 0]))),
    # RTB KR5.py: L1..L6
    "kuka_kr5": ("standard", [(0, 0.4, 0.18, _pi / 2), (0, 0.135, 0.6, _pi), (0, 0.135, 0.12, -_pi / 2),
                              (0, 0.62, 0, _pi / 2), (0, 0, 0, -_pi / 2), (0, 0, 0, 0)]),
    # ARTE IRB140 parameters.m: theta, d, a, alpha strings
    "abb_irb140": ("standard", list(zip([0, -_pi / 2, 0, 0, 0, _pi], [0.352, 0, 0, 0.380, 0, 0.065],
                                        [0.070, 0.360, 0, 0, 0, 0], [-_pi / 2, 0, -_pi / 2, _pi / 2, -_pi / 2, 0]))),
    # ARTE LR_MATE_200iC parameters.m
    "fanuc_lrmate200ic": ("standard", list(zip([0, -_pi / 2, 0, 0, 0, 0], [0.33, 0, 0, 0.320, 0, 0.08],
                                               [0.075, 0.300, 0.075, 0, 0, 0],
                                               [-_pi / 2, 0, -_pi / 2, _pi / 2, -_pi / 2, 0]))),
    # RTB Stanford.py (joint 3 prismatic: its theta -pi/2 stands in the offset column here)
    "stanford_arm": ("standard", [(0, 0.412, 0, -_pi / 2), (0, 0.154, 0, _pi / 2), (-_pi / 2, None, 0.0203, 0),
                                  (0, 0, 0, -_pi / 2), (0, 0, 0, _pi / 2), (0, 0, 0, 0)]),
    # De Luca's LWR 4 exercise (RTB LWR4.py)
    "kuka_lwr4": ("standard", list(zip([0] * 7, [0, 0, 0.40, 0, 0.39, 0, 0], [0] * 7,
                                       [_pi / 2, -_pi / 2, -_pi / 2, _pi / 2, _pi / 2, -_pi / 2, 0]))),
    # RTB Cobra600.py
    "adept_cobra600": ("standard", [(0, 0.387, 0.325, 0), (0, 0, 0.275, _pi), (0, None, 0, 0), (0, 0, 0, 0)]),
    # Kinova's Jaco table with RTB's offsets (RTB Jaco.py)
    "kinova_jaco": ("standard", [(0, 0.2755, 0, _pi / 2), (-_pi / 2, 0, 0.4100, _pi), (_pi / 2, -0.0098, 0, _pi / 2),
                                 (0, -(0.2073 + _s * 0.0743), 0, 2 * 30 * _deg),
                                 (-_pi, -(_s * 0.0743 + _s * 0.0743), 0, 2 * 30 * _deg),
                                 (100 * _deg, -(_s * 0.0743 + 0.1687), 0, _pi)]),
    # Franka's table (a_{i-1}, d_i, alpha_{i-1}); the flange's 0.107 on joint 7
    "franka_panda": ("modified", [(0, 0, 0.333, 0), (-_pi / 2, 0, 0, 0), (_pi / 2, 0, 0.316, 0),
                                  (_pi / 2, 0.0825, 0, 0), (-_pi / 2, -0.0825, 0.384, 0), (_pi / 2, 0, 0, 0),
                                  (_pi / 2, 0.088, 0.107, 0)]),
    # RTB Meca500.py, in mm
    "meca500": ("modified", [(0, 0, 135 * _mm, 0), (-90 * _deg, 0, 0, -90 * _deg), (0, 135 * _mm, 0, 0),
                             (-90 * _deg, 38 * _mm, 120 * _mm, 0), (90 * _deg, 0, 0, 0),
                             (-90 * _deg, 0, 70 * _mm, 180 * _deg)]),
    # RTB AL5D.py: a, d, alpha, offset lists
    "lynxmotion_al5d": ("modified", list(zip([_pi, _pi / 2, _pi, _pi], [0, 0.002, 0.14679, 0.17751],
                                             [-0.06858, 0, 0, 0], [_pi / 2, _pi, -0.0427, -0.0427 - _pi / 2]))),
}
SOURCE_TOOLS = {  # tool transforms the sources give: xyz, rpy
    "franka_panda": ([0, 0, 0.103], [0, 0, -_pi / 4]),
    "lynxmotion_al5d": ([0.07719, 0, 0], [0, 0, 0]),
}
SOURCE_BASES = {"ur3_inverted": ([0, 0, 0], [_pi, 0, 0])}


@pytest.mark.parametrize("name", NAMES)
def test_source_table(name):
    """The file holds the numbers of the table its header cites (within 1e-15)."""
    assert name in SOURCE_TABLES, f"{name}: add the source's table to SOURCE_TABLES"
    arm = ARMS[name]
    convention, rows = SOURCE_TABLES[name]
    assert arm.convention == convention and len(rows) == arm.n
    for i, row in enumerate(rows):
        if convention == "standard":
            offset, d, a, alpha = row
        else:
            alpha, a, d, offset = row
        joint_offset = arm.offset[i] if arm.types[i] == "R" else arm.theta[i]
        assert joint_offset == pytest.approx(offset, abs=1e-15), (name, i + 1, "offset/theta")
        if d is not None:
            assert arm.types[i] == "R" and arm.d[i] == pytest.approx(d, abs=1e-15), (name, i + 1, "d")
        else:
            assert arm.types[i] == "P" and arm.offset[i] == 0
        assert arm.a[i] == pytest.approx(a, abs=1e-15), (name, i + 1, "a")
        assert arm.alpha[i] == pytest.approx(alpha, abs=1e-15), (name, i + 1, "alpha")
    for table, attr in ((SOURCE_TOOLS, "tool"), (SOURCE_BASES, "base")):
        xyz, (roll, pitch, yaw) = table.get(name, ([0, 0, 0], [0, 0, 0]))
        expected = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
        expected[:3, 3] = xyz
        np.testing.assert_allclose(getattr(arm, attr), expected, atol=1e-15, err_msg=f"{name} {attr}")


def test_ceiling_mounted_ur3_hangs_down():
    """The inverted UR3: joint 1's axis points down the world z, and the arm stays below the mount."""
    arm = ARMS["ur3_inverted"]
    frames = link_frames(arm, configurations(arm, 50))
    np.testing.assert_allclose(frames[0][..., :3, 2], np.broadcast_to([0, 0, -1], (50, 3)), atol=1e-15)
    np.testing.assert_allclose(frames[1][..., 2, 3], -0.1519, atol=1e-15)  # the shoulder 0.1519 m below the mount


# --------------------------------------------------------------------------- path 2: the SymPy model

ARM_PARAMS = [pytest.param(name, id=name) for name in NAMES]
_MODELS: dict = {}
LOAD_TIMES: dict = {}


def model_functions(name):
    """fk and jacobian of ``derivations.load(file)``, lambdified at the default parameters (cached)."""
    if name not in _MODELS:
        import sympy as sp

        import derivations
        start = time.perf_counter()
        model = derivations.load(ARMS[name].path)
        LOAD_TIMES[name] = time.perf_counter() - start
        defaults = {symbol: sp.Float(value, 30) for symbol, value in model.params.items()}
        args = list(model.q)
        _MODELS[name] = (model, sp.lambdify(args, model.explicit(model.fk).subs(defaults), "numpy"),
                         sp.lambdify(args, model.explicit(model.jacobian).subs(defaults), "numpy"))
    return _MODELS[name]


def _evaluate_matrix(function, q):
    return np.array([np.array(function(*row), dtype=float) for row in q])


@pytest.mark.parametrize("name", ARM_PARAMS)
def test_model_fk_matches_the_independent_product(name):
    arm = ARMS[name]
    model, fk_model, _ = model_functions(name)
    assert model.n == arm.n and list(model.joint_types) == arm.types
    q = configurations(arm)
    assert relative_error(_evaluate_matrix(fk_model, q), fk(arm, q)) < TOLERANCE


@pytest.mark.parametrize("name", ARM_PARAMS)
def test_model_jacobian_matches_the_independent_cross_products(name):
    arm = ARMS[name]
    _, _, jacobian_model = model_functions(name)
    q = configurations(arm)
    assert relative_error(_evaluate_matrix(jacobian_model, q), jacobian(arm, q)) < TOLERANCE


@pytest.mark.parametrize("name", ARM_PARAMS)
def test_model_limits_and_task_are_the_files(name):
    arm = ARMS[name]
    model, _, _ = model_functions(name)
    for mine, theirs in zip(arm.limits, model.limits):
        assert (mine is None) == (theirs is None)
        if mine is not None:
            assert theirs == pytest.approx(mine, abs=1e-15)
    if arm.task == ["pose"]:
        assert len(model.task_names) == 12
    else:
        assert list(model.task_names) == arm.task


# --------------------------------------------------------------------------- path 3: generated packages

_PACKAGES: dict = {}


@pytest.fixture(scope="session")
def generated_root(tmp_path_factory):
    """One folder of packages for the whole run: under pytest-xdist the workers share it
    (each arm generated once, under a lock), instead of generating every arm per worker."""
    return shared_folder(tmp_path_factory, "zoo_packages")


def generated_package(name, root: Path):
    """Generate the arm's package once per session with the CLI, import it; an error names the stage."""
    if name not in _PACKAGES:
        with open(root / f"{name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # another worker may be generating this arm
            _generate_once(name, root)
    package = _PACKAGES[name]
    if isinstance(package, str):
        pytest.fail(f"{name}: {package}", pytrace=False)
    return package


def _generate_once(name, root: Path):
    """Generate ``name`` into ``root`` unless a worker already did, then import it into _PACKAGES."""
    out = root / name
    failure = root / f"{name}.failed"
    if failure.exists():
        _PACKAGES[name] = failure.read_text()
        return
    if not out.exists():
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        fast = ["--fast"] if name in VECTORISED else []
        start = time.perf_counter()
        try:
            result = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(ARMS[name].path),
                                     "--out", str(out), *fast], cwd=ROOT, env=env, capture_output=True, text=True,
                                    timeout=GENERATE_TIMEOUT)
        except subprocess.TimeoutExpired:
            failure.write_text(f"generate did not finish in {GENERATE_TIMEOUT} s")
            _PACKAGES[name] = failure.read_text()
            return
        else:
            if result.returncode != 0:
                failure.write_text(f"generate exited {result.returncode} after {time.perf_counter() - start:.0f} s:\n"
                                   + result.stderr[-3000:])
                _PACKAGES[name] = failure.read_text()
                return
    sys.path.insert(0, str(root))
    importlib.invalidate_caches()
    try:
        _PACKAGES[name] = importlib.import_module(name)
    finally:
        sys.path.remove(str(root))


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", ARM_PARAMS)
def test_generated_fk_and_jacobian(name, backend, generated_root):
    arm = ARMS[name]
    package = generated_package(name, generated_root)
    kernels = package.load(backend)
    q = configurations(arm)
    assert relative_error(kernels.fk(q), fk(arm, q)) < TOLERANCE
    assert relative_error(kernels.jacobian(q), jacobian(arm, q)) < TOLERANCE
    # one configuration at a time too (the C backend's single-point path)
    assert relative_error(np.array([kernels.fk(row) for row in q[:10]]), fk(arm, q[:10])) < TOLERANCE
    assert relative_error(np.array([kernels.jacobian(row) for row in q[:10]]), jacobian(arm, q[:10])) < TOLERANCE
    # in the tool frame (the Toolbox's jacobe, Pinocchio's LOCAL): both halves turned by R^T
    R_T = np.swapaxes(fk(arm, q)[..., :3, :3], -1, -2)
    J = jacobian(arm, q)
    expected = np.concatenate([R_T @ J[..., :3, :], R_T @ J[..., 3:, :]], axis=-2)
    assert relative_error(kernels.jacobian_tool(q), expected) < TOLERANCE


def test_latex_writes_the_rate_rows_out_where_they_are_short(generated_root):
    """The forward rate map row by row for a UR5; the general 6R (the Jaco), whose frames do not
    cancel, is written as a program: its LaTeX says so and prints no expanded rows (they would run
    to hundreds of operations each)."""
    from derivations.chain_program import EXPLICIT_MAX_TERMS
    ur5 = generated_package("ur5", generated_root).__path__[0]
    jaco = generated_package("kinova_jaco", generated_root).__path__[0]
    ur5_tex = (Path(ur5) / "ur5.tex").read_text()
    jaco_tex = (Path(jaco) / "kinova_jaco.tex").read_text()
    assert "Forward rate map $\\dot x = J_x \\dot q$:" in ur5_tex and "\\dot{x} &=" in ur5_tex
    assert "The product is not expanded: its link transforms do not cancel" in jaco_tex
    assert "\\dot{x} &=" not in jaco_tex and "T_{11} &=" not in jaco_tex
    import sympy as sp

    import derivations
    jaco_model = derivations.load(ARMS["kinova_jaco"].path)
    explicit = jaco_model.chain.link_frames(jaco_model.q)[-1]  # what the expanded form would print
    assert max(len(sp.Add.make_args(e)) for e in explicit) > EXPLICIT_MAX_TERMS


# --------------------------------------------------------------------------- rate kernels

def task_rows(arm: Arm, J: np.ndarray) -> np.ndarray:
    """The rows of the geometric Jacobian that the arm's task rates are (this file's own choice):
    the twist for a pose task (whose kernels take the 12 pose rates and turn them into the
    twist), v for x, y, z and the z rotation rate for phi."""
    if arm.task == ["pose"]:
        return J
    rows = {"x": 0, "y": 1, "z": 2, "phi": 5}
    return J[..., [rows[t] for t in arm.task], :]


def pose_rates(T: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """The 12 pose-task rates (p_dot, then R_dot row by row) of a motion with the given twist."""
    w = twist[..., 3:]
    W = np.zeros(w.shape[:-1] + (3, 3))
    W[..., 0, 1], W[..., 0, 2], W[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    W = W - np.swapaxes(W, -1, -2)
    R_dot = W @ T[..., :3, :3]
    return np.concatenate([twist[..., :3], R_dot.reshape(R_dot.shape[:-2] + (9,))], axis=-1)


def reach(arm: Arm) -> float:
    """L: the sum of |a|, of |d| (revolute) or |offset| (prismatic), and the tool offset."""
    total = float(np.abs(arm.a).sum())
    total += sum(abs(d) if t == "R" else abs(o) for t, d, o in zip(arm.types, arm.d, arm.offset))
    total += float(np.linalg.norm(arm.tool[:3, 3]))
    return total or 1.0


def scales(arm: Arm, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """(row scale, column scale) that make A dimensionless: 1/L on length rows, L on prismatic columns."""
    L = reach(arm)
    lengths = [1, 1, 1, 0, 0, 0] if arm.task == ["pose"] else [0 if t == "phi" else 1 for t in arm.task]
    assert len(lengths) == rows
    return L ** -np.array(lengths, float), L ** np.array([t == "P" for t in arm.types], float)


def rate_setup(arm: Arm, count: int = 100):
    q = configurations(arm, count)
    qd = np.random.default_rng(7).uniform(-1, 1, q.shape)
    J = jacobian(arm, q)
    A = task_rows(arm, J)
    rows, cols = scales(arm, A.shape[-2])
    An = rows[:, None] * A * cols[None, :]
    return q, qd, J, A, An, cols


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", ARM_PARAMS)
def test_rates_joint_velocity_is_the_pseudo_inverse(name, backend, generated_root):
    """joint_velocity(q, x_dot of q_dot): the exact q_dot of a square arm, the minimum-norm
    solution (prismatic rates in units of L) of a redundant one, numpy's pinv of this file's
    Jacobian being the reference, wherever that Jacobian's condition number is below 1e3; and
    no singular flag there."""
    arm = ARMS[name]
    kernels = generated_package(name, generated_root).load(backend)
    q, qd, J, A, An, cols = rate_setup(arm)
    xd = pose_rates(fk(arm, q), (J @ qd[..., None])[..., 0]) if arm.task == ["pose"] else (A @ qd[..., None])[..., 0]
    got, singular = kernels.joint_velocity(q, xd)
    condition = np.linalg.cond(An)
    regular = condition < 1e3
    assert regular.sum() >= 80, f"{name}: only {regular.sum()} of 100 configurations are well conditioned"
    assert not singular[regular].any()
    # min ||y|| subject to An y = An (qd / cols), then q_dot = cols y
    expected = cols * np.einsum("kij,kj->ki", np.linalg.pinv(An), np.einsum("kij,kj->ki", An, qd / cols))
    error = np.abs(got - expected)[regular].max() / max(1.0, np.abs(expected[regular]).max())
    assert error < 1e-14 * condition[regular].max() * 100, (name, error, condition[regular].max())
    if A.shape[-2] >= arm.n:  # not redundant: the generating q_dot itself comes back
        assert np.abs(got - qd)[regular].max() < 1e-14 * condition[regular].max() * 100


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", ARM_PARAMS)
def test_rates_manipulability_and_the_flag(name, backend, generated_root):
    """manipulability = sqrt(det(A A^T)) (or A^T A when A is tall) of this file's Jacobian rows;
    the flag is set where cond(An) > 1e4 (decided here with a margin of 10 either way)."""
    arm = ARMS[name]
    kernels = generated_package(name, generated_root).load(backend)
    q, qd, J, A, An, cols = rate_setup(arm)
    gram = A @ np.swapaxes(A, -1, -2) if A.shape[-2] <= A.shape[-1] else np.swapaxes(A, -1, -2) @ A
    w, singular = kernels.manipulability(q)
    np.testing.assert_allclose(w, np.sqrt(np.abs(np.linalg.det(gram))), rtol=1e-9, atol=1e-15)
    condition = np.linalg.cond(An)
    assert not singular[condition < 1e3].any()
    assert singular[condition > 1e5].all()


def test_rates_singular_flag_is_the_same_for_an_arm_ten_times_larger(generated_root):
    """The UR5 and the UR5 with every length times 10 flag the same configurations, among them
    its three singular families (wrist q5 = 0, elbow q3 = 0, shoulder: wrist centre over the base
    axis), and their manipulabilities differ by exactly 10^3 (three length rows).  The larger arm
    is the UR5's own kernels given every [params] length of the file times 10 as keywords: a
    description's parameters stay symbols in every kernel, so that is the code a description with
    the larger numbers generates (without generating a second package)."""
    arm = ARMS["ur5"]
    assert set(arm.params) == {"d1", "a2", "a3", "d4", "d5", "d6"}  # the file's six lengths, all of them
    larger = {name: 10.0 * value for name, value in arm.params.items()}
    package = generated_package("ur5", generated_root)
    q = configurations(arm, 200)
    q[:20, 4] = 0.0                  # wrist: axes 4 and 6 in line
    q[20:40, 2] = 0.0                # elbow stretched
    for backend in ("numpy", "c"):
        kernels = package.load(backend)
        assert set(kernels.PARAMS) == set(larger)
        w, flag = kernels.manipulability(q)
        w10, flag10 = kernels.manipulability(q, **larger)
        assert (flag == flag10).all()
        assert flag[:40].all() and flag[40:].sum() <= 2
        np.testing.assert_allclose(w10[40:], 1e3 * w[40:], rtol=1e-9)


# --------------------------------------------------------------------------- automatic inverse kinematics (#15)

# What derivations.ik.decompose finds for each arm: its family, or the structure it lacks.
IK_FAMILY = {
    "abb_irb140": "spherical wrist", "fanuc_lrmate200ic": "spherical wrist", "kuka_kr5": "spherical wrist",
    "meca500": "spherical wrist", "stanford_arm": "spherical wrist",
    "ur10": "three parallel", "ur3_inverted": "three parallel", "ur5": "three parallel",
    "adept_cobra600": "parallel axes", "kuka_lwr4": "spherical wrist, joint 3 free",
    "franka_panda": "reversed spherical wrist, joint 7 free",
}
IK_LACKS = {
    "kinova_jaco": "no three consecutive axes meet in a point (axes 4, 5, 6) and axes 2, 3, 4 are not parallel",
    "lynxmotion_al5d": "a position task with 4 joints",
}
IK_PARAMS = [pytest.param(name, id=name) for name in IK_FAMILY]
IK_RANDOM, IK_DEGENERATE = 10_000, 1_000
IK_FK_TOLERANCE = 1e-9     # metres and rotation entries (phi modulo 2 pi)
IK_JOINT_TOLERANCE = 1e-6  # a double root (arm stretched, wrist centre over the shoulder) costs sqrt(eps)
IK_SINGULAR = 1e-12        # |sin q5| at or below this: the wrist's free sum (see ik_joint_distance)


def test_the_ik_tables_cover_the_zoo():
    assert set(IK_FAMILY) | set(IK_LACKS) == set(ARMS)


@pytest.mark.parametrize("name", NAMES)
def test_ik_family_or_what_the_arm_lacks(name):
    """The family the decomposition finds, its plan naming a subproblem for every joint; or the
    structure the arm lacks, said in the model (and by `kinegen show`), and no ik kernel."""
    import derivations
    model = derivations.load(ARMS[name].path)
    if name in IK_FAMILY:
        assert model.ik_plan[0] == f"family: {IK_FAMILY[name]}"
        plan = "\n".join(model.ik_plan)
        for i in range(1, model.n + 1):
            assert f"q{i}" in plan
        names = [b.name for b in model.ik]  # (names only: a failing comparison of whole branches prints megabytes)
        assert len(set(names)) == len(names) == (2 if name == "adept_cobra600" else 8), names
        assert model.ik_unsupported == ""
    else:
        assert len(model.ik) == 0, model.ik_plan
        assert IK_LACKS[name] in model.ik_unsupported, model.ik_unsupported
        assert "ik" not in [f.name for f in model.functions()]


def ik_configurations(arm: Arm, rng) -> np.ndarray:
    """IK_RANDOM uniform configurations (revolute joints over the whole turn), then IK_DEGENERATE with
    every revolute joint at 0, +-pi/2 or pi (wrist singular, arm stretched or folded, shoulder over
    the base) and every prismatic joint at an end or the middle of its range."""
    count = IK_RANDOM + IK_DEGENERATE
    q = np.empty((count, arm.n))
    for i, (kind, lim) in enumerate(zip(arm.types, arm.limits)):
        if kind == "R":
            q[:, i] = rng.uniform(-math.pi, math.pi, count)
            q[IK_RANDOM:, i] = rng.choice([0.0, math.pi / 2, -math.pi / 2, math.pi], IK_DEGENERATE)
        else:
            low, high = lim
            q[:, i] = rng.uniform(low, high, count)
            q[IK_RANDOM:, i] = rng.choice([low, (low + high) / 2, high], IK_DEGENERATE)
    return q


def ik_target(arm: Arm, T: np.ndarray) -> np.ndarray:
    """The task vector of poses T (..., 4, 4), from this file's fk: the pose (x, y, z, r11 .. r33) or
    x, y, z, phi for the SCARA."""
    if arm.task == ["pose"]:
        return np.concatenate([T[..., :3, 3], T[..., :3, :3].reshape(T.shape[:-2] + (9,))], axis=-1)
    assert arm.task == ["x", "y", "z", "phi"]
    return np.concatenate([T[..., :3, 3], np.arctan2(T[..., 1, 0], T[..., 0, 0])[..., None]], axis=-1)


def wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def ik_joint_distance(name, Q, q):
    """max |Q - q| per branch (revolute joints modulo 2 pi), up to what q leaves free: at a wrist
    singularity (|sin q5| <= IK_SINGULAR) a spherical wrist fixes only q4 + q6 or q4 - q6 (axes 4 and
    6 in line, either sense), and a UR only q1 and q5 (axis 6 joins the parallel axes 2 to 4); with
    the wrist centre on axis 1 (within 1e-9 m) a spherical wrist's q1 is free, and q4 to q6 follow it."""
    types = ARMS[name].types
    difference = Q - q[:, None, :]
    for i, kind in enumerate(types):
        if kind == "R":
            difference[..., i] = wrap(difference[..., i])
    difference = np.abs(difference)
    w = len(types) - 2  # the wrist's middle joint (0-based): q5 of a six-joint arm, q6 of the LWR 4
    singular = np.abs(np.sin(q[:, w])) <= IK_SINGULAR
    if IK_FAMILY[name].startswith("spherical wrist"):
        # the wrist centre on axis 1 (the shoulder singularity): q1 is free, and the wrist follows it
        axis, origin, centre = wrist_geometry(ARMS[name], q, w - 1)
        offset = centre - origin
        shoulder = np.linalg.norm(offset - axis * np.sum(offset * axis, axis=-1, keepdims=True), axis=-1) <= 1e-9
        plus = np.abs(wrap(Q[..., w - 1] + Q[..., w + 1] - (q[:, w - 1] + q[:, w + 1])[:, None]))
        minus = np.abs(wrap(Q[..., w - 1] - Q[..., w + 1] - (q[:, w - 1] - q[:, w + 1])[:, None]))
        difference[singular, :, w - 1] = np.minimum(plus, minus)[singular]
        difference[singular, :, w + 1] = 0.0
        difference[shoulder, :, 0] = 0.0
        difference[shoulder, :, w - 1:] = 0.0
    elif IK_FAMILY[name].startswith("reversed spherical wrist"):
        # the shoulder (axes 1, 2, 3 meeting at s) is the reversed arm's wrist: with axes 1 and 3 in line
        # only q1 + q3 or q1 - q3 is fixed; with s on axis 5 or 6 (axis 5 in line with axis 3 at q4 = 0)
        # that joint is free and the shoulder follows it
        in_line = np.abs(np.sin(q[:, 1])) <= IK_SINGULAR
        plus = np.abs(wrap(Q[..., 0] + Q[..., 2] - (q[:, 0] + q[:, 2])[:, None]))
        minus = np.abs(wrap(Q[..., 0] - Q[..., 2] - (q[:, 0] - q[:, 2])[:, None]))
        difference[in_line, :, 0] = np.minimum(plus, minus)[in_line]
        difference[in_line, :, 2] = 0.0
        _, _, shoulder = wrist_geometry(ARMS[name], q, 0)
        frames = link_frames(ARMS[name], q)
        shift = 0 if ARMS[name].convention == "standard" else 1
        for j in (4, 5):
            z, o = frames[j + shift][..., :3, 2], frames[j + shift][..., :3, 3]
            offset = shoulder - o
            across = np.linalg.norm(offset - z * np.sum(offset * z, axis=-1, keepdims=True), axis=-1)
            difference[across <= 1e-9] = 0.0
    elif IK_FAMILY[name] == "three parallel":
        difference[singular, :, 1:4] = 0.0
        difference[singular, :, 5] = 0.0
    return difference.max(axis=-1)


def wrist_geometry(arm: Arm, q, first: int):
    """Axis 1 (unit direction, a point) and the point where the wrist's first two axes (0-based
    ``first`` and the next) meet, from this file's frames (joint i turns about z of frame i-1 in
    standard DH, of frame i in modified DH)."""
    frames = link_frames(arm, q)
    shift = 0 if arm.convention == "standard" else 1
    (z1, o1), (z4, o4), (z5, o5) = ((frames[i + shift][..., :3, 2], frames[i + shift][..., :3, 3])
                                    for i in (0, first, first + 1))
    # the closest points of the lines o4 + s z4 and o5 + t z5 (they meet: a spherical wrist)
    w = o4 - o5
    b = np.sum(z4 * z5, axis=-1)
    d, e = np.sum(z4 * w, axis=-1), np.sum(z5 * w, axis=-1)
    s = (b * e - d) / np.maximum(1 - b * b, 1e-300)
    return z1, o1, o4 + s[..., None] * z4


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", IK_PARAMS)
def test_ik_round_trip(name, backend, generated_root):
    """FK(IK(x)) = x by this file's own forward kinematics, over IK_RANDOM + IK_DEGENERATE
    configurations: no valid branch off the target, no target without a valid branch, the
    generating configuration among the branches (up to a singularity's free sum), every
    revolute value in (-pi, pi], nothing NaN."""
    arm = ARMS[name]
    kernels = generated_package(name, generated_root).load(backend)
    q = ik_configurations(arm, np.random.default_rng(zlib.crc32(f"ik {name}".encode())))
    x = ik_target(arm, fk(arm, q))
    free = re.search(r"joint (\d) free", IK_FAMILY[name])
    if free:  # a seven-joint arm: the free joint's value is ik's second argument, and it comes back
        j = int(free.group(1)) - 1
        Q, valid = kernels.ik(x, free=q[:, j])
        assert np.abs(wrap(Q[..., j] - q[:, None, j]))[valid].max() == 0.0
    else:
        Q, valid = kernels.ik(x)
    assert Q.shape == (len(q), len(kernels.BRANCHES), arm.n) and valid.shape == Q.shape[:2]
    reached = ik_target(arm, fk(arm, np.where(valid[..., None], Q, 0.0)))
    miss = np.abs(reached - x[:, None, :])
    if arm.task != ["pose"]:
        miss[..., 3] = np.abs(wrap(miss[..., 3]))
    error = np.where(valid, miss.max(axis=-1), 0.0)
    distance = np.where(valid, ik_joint_distance(name, Q, q), np.inf).min(axis=-1)
    revolute = [i for i, kind in enumerate(arm.types) if kind == "R"]
    counts = {
        "wrong": int((error > IK_FK_TOLERANCE).sum()),
        "no solution": int((~valid.any(axis=-1)).sum()),
        "missing": int((distance > IK_JOINT_TOLERANCE).sum()),
        "not wrapped": int(((np.abs(Q[..., revolute]) > np.pi).any(axis=-1) & valid).sum()),
        "nan": int((~np.isfinite(Q[valid])).sum()),
    }
    assert counts == dict.fromkeys(counts, 0), (counts, float(error.max()))
    # one pose at a time too: the single-point path gives the same branches
    for row in range(0, len(q), len(q) // 7):
        Q1, valid1 = kernels.ik(x[row], free=q[row, j]) if free else kernels.ik(x[row])
        np.testing.assert_array_equal(valid1, valid[row])
        np.testing.assert_allclose(np.where(valid1[:, None], Q1, 0), np.where(valid1[:, None], Q[row], 0),
                                   rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["ur5", "kuka_kr5"])
def test_ik_unreachable_targets_have_no_valid_branch(name, generated_root):
    """A pose whose position lies 5 m from the base (both arms reach under 1 m) has no valid branch,
    in both backends."""
    arm = ARMS[name]
    T = fk(arm, configurations(arm, 50))
    T[:, :3, 3] *= 5.0 / np.linalg.norm(T[:, :3, 3], axis=-1, keepdims=True)
    for backend in ("numpy", "c"):
        _, valid = generated_package(name, generated_root).load(backend).ik(ik_target(arm, T))
        assert not valid.any()


def test_verify_holds_the_free_joint_ik_to_sympy(generated_root):
    """`kinegen verify` on a seven-joint arm: the ik kernel, given the target and the free joint's
    value of the same configuration, against its SymPy steps at 30 digits, both backends."""
    import derivations
    from codegen.verify import verify_model
    package = generated_package("kuka_lwr4", generated_root)
    model = derivations.load(ARMS["kuka_lwr4"].path)
    checks = [c for c in verify_model(model, {"numpy": package.load("numpy"), "c": package.load("c")}, samples=2)
              if c.kernel == "ik"]
    assert len(checks) == 2 and all(c.ok and c.points >= 8 for c in checks), checks


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_hostile_d11_the_free_joint_is_taken_as_documented_and_refused_past_its_limit(backend, generated_root):
    """``free`` of shape (N, 1) (as documented) gives N answers, not N x N (issue #26, item 6), the
    free joint comes back as given, and a value past 1e4 (1e16 marked wrong branches valid; issue
    #28, D11) is refused naming it."""
    k = generated_package("kuka_lwr4", generated_root).load(backend)
    q = np.random.default_rng(11).uniform(-1.0, 1.0, (6, 7))
    x = k.task(q)
    Q_column, valid_column = k.ik(x, free=q[:, 2:3])
    Q_flat, valid_flat = k.ik(x, free=q[:, 2])
    assert Q_column.shape == Q_flat.shape == (6, 8, 7) and valid_column.shape == (6, 8)
    np.testing.assert_array_equal(Q_column, Q_flat)
    assert np.allclose(Q_column[valid_column][:, 2], np.repeat(q[:, 2], valid_column.sum(axis=1)), atol=1e-12)
    for value in (1e16, -1e308, np.array([[0.1], [2e4]])):
        with pytest.raises(ValueError, match="free .* is beyond 10000 in size"):
            k.ik(x[:1] if np.ndim(value) == 0 else x[:2], free=value)

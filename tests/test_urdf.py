"""URDF input (derivations/urdf.py): real arms from their published URDFs, checked against a
forward kinematics written here from the XML alone, and every malformed file refused.

The independent computation reads each file with the standard library's ElementTree and
composes, per joint on the chain, ``Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`` of its origin and
the motion about or along its axis (Rodrigues' formula, in floating point).  Its geometric
Jacobian takes, for each moving joint, the world axis and origin of that joint's frame (a mimic
joint adds its column, times its multiplier, to its leader's).  It reads the angles as written,
or rounded to the nearest multiple of pi/2 where they are within 1e-8 of one (the rule the
README states for snapping; the UR5's file writes pi as 3.14159265, the iiwa's as
3.14159265359), and is compared with the model made with snapping off and on respectively.
"""
from __future__ import annotations

import fcntl
import importlib
import math
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from codegen.cli import main

ROOT = Path(__file__).resolve().parents[1]
URDF_DIR = Path(__file__).resolve().parent / "data" / "urdf"
TOLERANCE = 1e-12
SAMPLES = 100

# name -> (file, tip link, package folder); base is the root link in each.
ROBOTS = {
    "ur5": ("ur5.urdf", "tool0"),
    "panda": ("panda.urdf", "panda_hand_tcp"),
    "iiwa14": ("iiwa14.urdf", None),
    "stanford": ("stanford.urdf", None),
    "pantograph_mimic": ("pantograph_mimic.urdf", None),
}


# --------------------------------------------------------------------------- the independent FK

def _numbers(text: str | None, default):
    return [float(v) for v in text.split()] if text else list(default)


def _rotation(roll, pitch, yaw):
    cr, sr, cp, sp_, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp_], [0, 1, 0], [-sp_, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _snapped(angle: float) -> float:
    nearest = round(angle / (math.pi / 2)) * (math.pi / 2)
    return nearest if abs(angle - nearest) <= 1e-8 else angle


def _origin(joint, snap: bool):
    element = joint.find("origin")
    xyz = _numbers(element.get("xyz") if element is not None else None, (0, 0, 0))
    rpy = _numbers(element.get("rpy") if element is not None else None, (0, 0, 0))
    rpy = [_snapped(a) for a in rpy] if snap else rpy
    T = np.eye(4)
    T[:3, :3] = _rotation(*rpy)
    T[:3, 3] = xyz
    return T


def _motion(kind, axis, value):
    T = np.eye(4)
    if kind == "prismatic":
        T[:3, 3] = axis * value
        return T
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    T[:3, :3] = np.eye(3) + math.sin(value) * K + (1 - math.cos(value)) * K @ K
    return T


class XmlChain:
    """The chain root -> tip of a URDF, read with ElementTree."""

    def __init__(self, path: Path, tip: str | None, snap: bool = True):
        self.snap = snap
        tree = ET.parse(path).getroot()
        joints = tree.findall("joint")
        by_child = {j.find("child").get("link"): j for j in joints}
        parents = {j.find("parent").get("link") for j in joints}
        if tip is None:
            (tip,) = [c for c in by_child if c not in parents]
        chain, link = [], tip
        while link in by_child:
            chain.append(by_child[link])
            link = by_child[link].find("parent").get("link")
        self.joints = list(reversed(chain))
        self.moving = [j.get("name") for j in self.joints
                       if j.get("type") != "fixed" and j.find("mimic") is None]

    @property
    def n(self):
        return len(self.moving)

    def walk(self, q):
        """(the tip transform, per moving joint and mimic joint: (name, leader, multiplier, axis, point))."""
        value = dict(zip(self.moving, q))
        T = np.eye(4)
        axes = []
        for joint in self.joints:
            T = T @ _origin(joint, self.snap)
            kind = joint.get("type")
            if kind == "fixed":
                continue
            axis_element = joint.find("axis")
            axis = np.array(_numbers(axis_element.get("xyz") if axis_element is not None else None, (1, 0, 0)))
            axis = axis / np.linalg.norm(axis)
            mimic = joint.find("mimic")
            if mimic is not None:
                leader, multiplier = mimic.get("joint"), float(mimic.get("multiplier", "1"))
                angle = multiplier * value[leader] + float(mimic.get("offset", "0"))
            else:
                leader, multiplier, angle = joint.get("name"), 1.0, value[joint.get("name")]
            axes.append((leader, multiplier, kind, T[:3, :3] @ axis, T[:3, 3].copy()))
            T = T @ _motion(kind, axis, angle)
        return T, axes

    def fk(self, q):
        return self.walk(q)[0]

    def jacobian(self, q):
        T, axes = self.walk(q)
        J = np.zeros((6, self.n))
        for leader, multiplier, kind, z, o in axes:
            column = (np.concatenate([z, np.zeros(3)]) if kind == "prismatic"
                      else np.concatenate([np.cross(z, T[:3, 3] - o), z]))
            J[:, self.moving.index(leader)] += multiplier * column
        return J


def configurations(n: int, seed: int, count: int = SAMPLES) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-math.pi, math.pi, (count, n))


def relative_error(got, expected) -> float:
    return float(np.max(np.abs(np.asarray(got) - expected)) / max(1.0, float(np.max(np.abs(expected)))))


def test_the_independent_jacobian_is_the_derivative_of_the_independent_fk():
    """The check's own check: its Jacobian against central differences of its FK (mimic included)."""
    for name, (filename, tip) in ROBOTS.items():
        chain = XmlChain(URDF_DIR / filename, tip)
        for q in configurations(chain.n, 7, 5):
            T, J = chain.fk(q), chain.jacobian(q)
            h = 1e-6
            for j in range(chain.n):
                dq = np.zeros(chain.n)
                dq[j] = h
                Tp, Tm = chain.fk(q + dq), chain.fk(q - dq)
                v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
                spin = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T[:3, :3].T
                w = np.array([spin[2, 1], spin[0, 2], spin[1, 0]])
                assert np.allclose(np.concatenate([v, w]), J[:, j], atol=1e-7), (name, j)


# --------------------------------------------------------------------------- the model, exact

_MODELS: dict = {}


def model(name: str, snap: bool = True):
    key = (name, snap)
    if key not in _MODELS:
        import derivations
        filename, tip = ROBOTS[name]
        _MODELS[key] = derivations.load(URDF_DIR / filename, tip=tip, snap=snap)
    return _MODELS[key]


def _lambdified(m, what):
    import sympy as sp
    return sp.lambdify(list(m.q), getattr(m, what), "numpy")


# As written, the Panda's and the iiwa's pi/2 (to 16 and 12 digits) would be general angles: a
# general 7R, whose derivation is what snapping saves. The UR5's and the pantograph's are checked.
@pytest.mark.parametrize("name, snap", [(n, True) for n in ROBOTS] + [("ur5", False), ("pantograph_mimic", False)])
def test_model_fk_and_jacobian_match_the_xml(name, snap):
    filename, tip = ROBOTS[name]
    chain = XmlChain(URDF_DIR / filename, tip, snap=snap)
    m = model(name, snap=snap)
    assert m.n == chain.n
    fk, jacobian = _lambdified(m, "fk"), _lambdified(m, "jacobian")
    for q in configurations(chain.n, 11, 20):
        assert relative_error(np.array(fk(*q), dtype=float), chain.fk(q)) < TOLERANCE
        assert relative_error(np.array(jacobian(*q), dtype=float), chain.jacobian(q)) < TOLERANCE


def test_snapping_makes_the_written_angles_exact_and_says_so():
    import sympy as sp
    snapped, written = model("ur5"), model("ur5", snap=False)
    assert "shoulder_lift_joint origin rpy[1] 1.570796325 -> pi/2" in snapped.notes["snapped"]
    assert "snapped" not in written.notes
    assert snapped.fk.has(sp.pi) or not any(sp.Float(1.570796325) == a for a in snapped.fk.atoms(sp.Number))
    # As written, cos(1.570796325) = 1.8e-9 couples terms the snapped model keeps apart.
    assert not written.fk.has(sp.pi) and written.fk.atoms(sp.cos) != snapped.fk.atoms(sp.cos)
    q = configurations(6, 3, 1)[0]
    difference = relative_error(np.array(_lambdified(snapped, "fk")(*q), dtype=float),
                                np.array(_lambdified(written, "fk")(*q), dtype=float))
    assert 1e-11 < difference < 1e-8
    # The snapped model keeps the UR5's three parallel axes exactly: joints 2, 3, 4 share an axis direction.
    axes = snapped.chain.joint_axes(snapped.chain.link_frames(snapped.q))
    directions = [sp.simplify(axes[k][0]) for k in (1, 2, 3)]
    assert directions[0] == directions[1] == directions[2]


def test_the_ur5_urdf_is_its_dh_twin_on_a_base_turned_half_a_turn():
    """ur_description's base_link is the UR controller's base turned by pi about z (its own
    base_link-base_fixed_joint says so), and tool0 is the controller's flange: T_urdf = Rz(pi) T_dh."""
    from test_zoo import ARMS
    from test_zoo import fk as dh_fk
    snapped = model("ur5")
    fk = _lambdified(snapped, "fk")
    q = configurations(6, 5, 50)
    turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    expected = np.einsum("ij,njk->nik", turn, dh_fk(ARMS["ur5"], q))
    assert relative_error(np.array([fk(*row) for row in q], dtype=float), expected) < TOLERANCE


def test_the_stanford_urdf_is_its_dh_twin():
    from test_zoo import ARMS
    from test_zoo import fk as dh_fk
    fk = _lambdified(model("stanford"), "fk")
    q = configurations(6, 6, 50)
    q[:, 2] = np.abs(q[:, 2]) / 3  # the boom's slide, in metres
    assert relative_error(np.array([fk(*row) for row in q], dtype=float), dh_fk(ARMS["stanford_arm"], q)) < TOLERANCE


def test_limits_come_from_the_limit_elements():
    panda = model("panda")
    assert panda.limits[3] == pytest.approx((-3.0718, -0.0698), abs=0)
    assert model("pantograph_mimic").limits[0] is None  # a continuous joint
    assert model("stanford").joint_types[2] == "P" and model("stanford").limits[2] == pytest.approx((0.3048, 1.27))


def test_fixed_joints_mid_chain_and_a_prismatic_finger():
    """The Panda to its left finger: two fixed joints (link8, the hand) between joint 7 and the finger's slide."""
    import derivations
    m = derivations.load(URDF_DIR / "panda.urdf", tip="panda_leftfinger")
    chain = XmlChain(URDF_DIR / "panda.urdf", "panda_leftfinger")
    assert m.joint_types == ("R",) * 7 + ("P",)
    fk, jacobian = _lambdified(m, "fk"), _lambdified(m, "jacobian")
    for q in configurations(8, 13, 10):
        q[7] = abs(q[7]) / 100
        assert relative_error(np.array(fk(*q), dtype=float), chain.fk(q)) < TOLERANCE
        assert relative_error(np.array(jacobian(*q), dtype=float), chain.jacobian(q)) < TOLERANCE


WRAPPER = """
name = "ur5_gripper"
urdf = "{urdf}"
tip_link = "tool0"
[params]
tcp = 0.15
[tool]
xyz = [0, 0, "tcp"]
rpy = [0, 0, "pi/2"]
[base]
xyz = [0.5, 0, 0]
rpy = [0, 0, "pi"]
"""


def test_a_description_over_a_urdf_adds_a_task_parameters_and_tool_and_base_frames(tmp_path):
    """The TOML form: urdf = FILE, then this file's own [params], [tool] and [base] (the tool length a
    keyword parameter of every kernel). Expected: the XML's chain between the two frames written here."""
    import sympy as sp

    import derivations
    path = tmp_path / "gripper.toml"
    path.write_text(WRAPPER.format(urdf=URDF_DIR / "ur5.urdf"))
    m = derivations.load(path)
    assert m.name == "ur5_gripper" and [str(p) for p in m.params] == ["tcp"]
    chain = XmlChain(URDF_DIR / "ur5.urdf", "tool0")
    fk = sp.lambdify([*m.q, *m.params], m.fk, "numpy")
    base = np.array([[-1.0, 0, 0, 0.5], [0, -1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    for tcp in (0.15, 0.3):
        tool = np.array([[0.0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, tcp], [0, 0, 0, 1]])
        for q in configurations(6, 23, 5):
            assert relative_error(np.array(fk(*q, tcp), dtype=float), base @ chain.fk(q) @ tool) < TOLERANCE
    path.write_text(WRAPPER.format(urdf=URDF_DIR / "ur5.urdf") + '[[joint]]\ntype = "R"\n')
    with pytest.raises(derivations.DescriptionError, match="unknown field 'joint' with 'urdf'"):
        derivations.load(path)


# --------------------------------------------------------------------------- generated packages

_PACKAGES: dict = {}


@pytest.fixture(scope="session")
def urdf_root(tmp_path_factory, worker_id):
    base = tmp_path_factory.getbasetemp()
    root = (base.parent if worker_id != "master" else base) / "urdf_packages"
    root.mkdir(exist_ok=True)
    return root


def package(name: str, root: Path):
    """``kinegen generate FILE.urdf --tip ... --out urdf_NAME`` once per session (shared by the workers)."""
    folder = f"urdf_{name}"
    if folder not in _PACKAGES:
        with open(root / f"{folder}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            out = root / folder
            if not out.exists():
                filename, tip = ROBOTS[name]
                command = [sys.executable, "-m", "codegen", "--quiet", "generate", str(URDF_DIR / filename),
                           "--out", str(out)] + (["--tip", tip] if tip else [])
                env = dict(os.environ, PYTHONPATH=str(ROOT), KINEGEN_PORTABLE="1")
                result = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
                assert result.returncode == 0, result.stderr[-3000:]
        sys.path.insert(0, str(root))
        importlib.invalidate_caches()
        try:
            _PACKAGES[folder] = importlib.import_module(folder)
        finally:
            sys.path.remove(str(root))
    return _PACKAGES[folder]


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize("name", [n for n in ROBOTS if n != "ur5"] + ["ur5"])
def test_generated_fk_and_jacobian_match_the_xml(name, backend, urdf_root):
    filename, tip = ROBOTS[name]
    chain = XmlChain(URDF_DIR / filename, tip)
    kernels = package(name, urdf_root).load(backend)
    q = configurations(chain.n, 17)
    if name == "stanford":
        q[:, 2] = np.abs(q[:, 2]) / 3
    expected_fk = np.array([chain.fk(row) for row in q])
    expected_jacobian = np.array([chain.jacobian(row) for row in q])
    assert relative_error(kernels.fk(q), expected_fk) < TOLERANCE
    assert relative_error(kernels.jacobian(q), expected_jacobian) < TOLERANCE
    assert kernels.fk(q).shape == (SAMPLES, 4, 4) and kernels.jacobian(q).shape == (SAMPLES, 6, chain.n)


def test_generated_ur5_from_urdf_is_its_dh_twin_in_both_backends(urdf_root):
    from test_zoo import ARMS
    from test_zoo import fk as dh_fk
    q = configurations(6, 19)
    turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    expected = np.einsum("ij,njk->nik", turn, dh_fk(ARMS["ur5"], q))
    for backend in ("numpy", "c"):
        assert relative_error(package("ur5", urdf_root).load(backend).fk(q), expected) < TOLERANCE


def test_the_latex_lists_the_urdf_joints_not_a_dh_table(urdf_root):
    tex = (Path(package("ur5", urdf_root).__path__[0]) / "ur5.tex").read_text()
    assert "shoulder\\_pan\\_joint & revolute" in tex and "\\frac{89159}{1000000}" in tex
    assert "Denavit" not in tex and "(A_{6})_{11}" not in tex or "A_{6}" in tex


# --------------------------------------------------------------------------- malformed files

MINIMAL = """<?xml version="1.0"?>
<robot name="two">
  <link name="a"/><link name="b"/><link name="c"/>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="b"/><child link="c"/>
    <origin xyz="0.2 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""

BAD = {
    "not_xml": ("this is not < xml", "not a valid URDF"),
    "loop": (MINIMAL.replace('<parent link="a"/><child link="b"/>', '<parent link="c"/><child link="b"/>'),
             "loop"),
    "missing_parent": (MINIMAL.replace('<parent link="b"/>', '<parent link="nowhere"/>'),
                       "joint 'j2': its parent link 'nowhere' is not defined"),
    "zero_axis": (MINIMAL.replace('<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>\n</robot>',
                                  '<axis xyz="0 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>\n</robot>'),
                  "joint 'j2': axis [0.0, 0.0, 0.0] has zero length"),
    "nan_origin": (MINIMAL.replace('xyz="0.2 0 0"', 'xyz="nan 0 0"'), "joint 'j2': origin xyz[0] is nan"),
    "floating": (MINIMAL.replace('name="j2" type="revolute"', 'name="j2" type="floating"'),
                 "joint 'j2': type 'floating'"),
    "entity": ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaa">]>' + MINIMAL.split("?>", 1)[1],
               "entity declaration"),
    "no_joints": ('<robot name="x"><link name="a"/></robot>', "no joints"),
    "two_leaves": (MINIMAL.replace("</robot>", '<link name="d"/><joint name="j3" type="fixed"><parent link="a"/>'
                                                '<child link="d"/></joint></robot>'), "2 leaf links below 'a' (c, d): give --tip"),
    "mimic_off_chain": ((URDF_DIR / "panda.urdf").read_text(), "mimics 'panda_finger_joint1', which is not a moving joint"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_malformed_urdf_is_refused_with_exit_2_and_nothing_written(case, tmp_path, capsys):
    text, message = BAD[case]
    path = tmp_path / f"{case}.urdf"
    path.write_text(text)
    extra = ["--tip", "panda_rightfinger"] if case == "mimic_off_chain" else []
    start = time.perf_counter()
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), *extra]) == 2
    assert time.perf_counter() - start < 30
    err = capsys.readouterr().err
    assert message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_a_50_mb_urdf_is_refused_unread(tmp_path, capsys):
    path = tmp_path / "huge.urdf"
    with open(path, "wb") as handle:
        handle.write(MINIMAL.encode())
        handle.seek(50 * 2**20)
        handle.write(b"\n")
    start = time.perf_counter()
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg")]) == 2
    assert time.perf_counter() - start < 5
    assert "more than the 10485760 a URDF may have here" in capsys.readouterr().err
    assert not (tmp_path / "pkg").exists()


def test_a_xacro_file_is_told_how_to_expand(tmp_path, capsys):
    path = tmp_path / "arm.urdf.xacro"
    path.write_text(MINIMAL)
    assert main(["--quiet", "generate", str(path)]) == 2
    assert "expand it first" in capsys.readouterr().err

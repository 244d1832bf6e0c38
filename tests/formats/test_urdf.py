"""URDF input (derivations/urdf.py): real arms from their published URDFs, checked against a
forward kinematics written here from the XML alone, and every malformed file refused.

The independent computation reads each file with the standard library's ElementTree and
composes, per joint on the chain, ``Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`` of its origin and
the motion about or along its axis (Rodrigues' formula, in floating point).  Its geometric
Jacobian takes, for each moving joint, the world axis and origin of that joint's frame (a mimic
joint adds its column, times its multiplier, to its leader's).  It reads the angles as written,
or snapped by the rule the README states: to the nearest multiple of pi/4 or pi/6 where they
are within 1e-8 of it or are its correctly rounded form at the places written, with at least 3
significant digits (the UR5's file writes pi as 3.14159265, the iiwa's as 3.14159265359, the
Panda's hand turns by -0.7853981633974483); it is compared with the model made with snapping
off and on respectively.  The axes of these files are coordinate axes, read as written.

The reader's own rules (which elements it skips, how it writes numbers, what it refuses) are
held by the tests after the generated packages, mostly on small files written inline.
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
from conftest import shared_folder

ROOT = Path(__file__).resolve().parents[2]
URDF_DIR = Path(__file__).resolve().parents[1] / "data" / "urdf"
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


def _places(text: str) -> tuple[int, int]:
    """(significant digits, places after the point of the last digit) of a decimal as written."""
    mantissa, _, exponent = text.lower().lstrip("+-").partition("e")
    whole, _, fraction = mantissa.partition(".")
    return len((whole + fraction).lstrip("0")), len(fraction) - int(exponent or 0)


def _snapped(text: str) -> float:
    """The angle written ``text``, snapped: the nearest multiple of pi/4 or pi/6 when within 1e-8
    of it, or when ``text`` is that angle rounded to the places written (3 significant digits and
    2 places at least); else the number as written."""
    value = float(text)
    k = round(value / (math.pi / 12))
    special = k * math.pi / 12
    if k % 2 and k % 3:
        return value
    digits, places = _places(text)
    if abs(value - special) <= 1e-8 or (digits >= 3 and places >= 2 and round(special, places) == value):
        return special
    return value


def _origin(joint, snap: bool):
    element = joint.find("origin")
    xyz = _numbers(element.get("xyz") if element is not None else None, (0, 0, 0))
    written = element.get("rpy") if element is not None else None
    rpy = [(_snapped if snap else float)(text) for text in written.split()] if written else [0, 0, 0]
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
                offset = mimic.get("offset", "0")
                offset = _snapped(offset) if self.snap and kind != "prismatic" else float(offset)
                angle = multiplier * value[leader] + offset
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
    """``m.what`` as a numpy function of q (a model written as a program: its steps substituted)."""
    import sympy as sp
    return sp.lambdify(list(m.q), m.explicit(getattr(m, what)), "numpy")


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
    """As written, an angle is a float whose cosine is a number at once: the model holds
    cos(1.570796325) = 1.8e-9 (and its double where two such turns meet) as coefficients, and
    no cosine of a constant (it held cos(314159265/200000000) when angles were exact rationals)."""
    import sympy as sp
    snapped, written = model("ur5"), model("ur5", snap=False)
    assert "shoulder_lift_joint origin rpy[1] 1.570796325 -> pi/2" in snapped.notes["snapped"]
    assert "snapped" not in written.notes
    assert snapped.fk.has(sp.pi) or not any(sp.Float(1.570796325) == a for a in snapped.fk.atoms(sp.Number))
    written_fk, snapped_fk = written.explicit(written.fk), snapped.explicit(snapped.fk)
    assert not written_fk.has(sp.pi) and all(f.args[0].free_symbols for f in written_fk.atoms(sp.cos, sp.sin))
    assert any(0 < abs(f) < 1e-8 for f in written_fk.atoms(sp.Float)) and not snapped_fk.atoms(sp.Float)
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
    fk = sp.lambdify([*m.q, *m.params], m.explicit(m.fk), "numpy")
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
def urdf_root(tmp_path_factory):
    return shared_folder(tmp_path_factory, "urdf_packages")


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
    # Numbers are XML Schema decimals: not Python's 0.1_5, other scripts' digits, nan, inf, 1e400.
    "python_underscore": (MINIMAL.replace('xyz="0.2 0 0"', 'xyz="0.1_5 0 0"'),
                          "joint 'j2': origin xyz[0] '0.1_5' is not a number"),
    "arabic_indic_digits": (MINIMAL.replace('xyz="0.2 0 0" rpy="0 0 0"', 'xyz="0.2 0 0" rpy="0 \u0661.\u0665 0"'),
                            "joint 'j2': origin rpy[1] '\u0661.\u0665' is not a number"),
    "inf_limit": (MINIMAL.replace('lower="-1" upper="1" effort="1" velocity="1"/></joint>\n</robot>',
                                  'lower="-1" upper="inf" effort="1" velocity="1"/></joint>\n</robot>'),
                  "joint 'j2': limit upper is inf (expected a finite number)"),
    "xyz_1e400": (MINIMAL.replace('xyz="0.2 0 0"', 'xyz="1e400 0 0"'),
                  "joint 'j2': origin xyz[0] '1e400' is more than 1e+300 in size"),
    "rpy_1e308": (MINIMAL.replace('xyz="0.2 0 0" rpy="0 0 0"', 'xyz="0.2 0 0" rpy="0 0 1e308"'),
                  "joint 'j2': origin rpy[2] '1e308' is more than 1e+300 in size"),
    "mimic_multiplier": (MINIMAL.replace('effort="1" velocity="1"/></joint>\n</robot>',
                                         'effort="1" velocity="1"/><mimic joint="j1" multiplier="two"/></joint>\n</robot>'),
                         "joint 'j2': mimic multiplier 'two' is not a number"),
    "two_numbers_in_xyz": (MINIMAL.replace('xyz="0.2 0 0"', 'xyz="0.2 0"'), "joint 'j2': origin xyz needs 3 numbers"),
    # Structure: what ROS refuses too, named.
    "duplicate_joint": (MINIMAL.replace('name="j2"', 'name="j1"'), "joint 'j1' is defined twice"),
    "duplicate_link": (MINIMAL.replace('<link name="c"/>', '<link name="c"/><link name="b"/>'),
                       "link 'b' is defined twice"),
    "link_without_name": (MINIMAL.replace('<link name="c"/>', '<link name="c"/><link/>'),
                          "<link> number 4 has no name"),
    "joint_without_name": (MINIMAL.replace('name="j2" ', ""), "<joint> number 2 has no name"),
    "joint_without_type": (MINIMAL.replace('name="j2" type="revolute"', 'name="j2"'), "joint 'j2': no type"),
    "joint_of_unknown_type": (MINIMAL.replace('name="j2" type="revolute"', 'name="j2" type="ball"'),
                              "joint 'j2': type 'ball' (a URDF joint is revolute, continuous, prismatic, fixed"),
    "joint_without_child": (MINIMAL.replace('<child link="c"/>', ""), "joint 'j2': no <child link=\"...\"/>"),
    "two_origins": (MINIMAL.replace('<origin xyz="0.2 0 0" rpy="0 0 0"/>',
                                    '<origin xyz="0.2 0 0"/><origin xyz="0.3 0 0"/>'),
                    "joint 'j2': 2 <origin> elements"),
    "not_a_robot": (MINIMAL.replace("<robot", "<model").replace("</robot>", "</model>"),
                    "not a valid URDF: the root element is <model>, not <robot>"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_malformed_urdf_is_refused_with_exit_2_and_nothing_written(case, tmp_path, capsys):
    text, message = BAD[case]
    path = tmp_path / f"{case}.urdf"
    path.write_text(text)
    extra = ["--tip", "panda_rightfinger"] if case == "mimic_off_chain" else []
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), *extra]) == 2
    assert time.process_time() - start < 30
    err = capsys.readouterr().err
    assert message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_a_50_mb_urdf_is_refused_unread(tmp_path, capsys):
    path = tmp_path / "huge.urdf"
    with open(path, "wb") as handle:
        handle.write(MINIMAL.encode())
        handle.seek(50 * 2**20)
        handle.write(b"\n")
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg")]) == 2
    assert time.process_time() - start < 5
    assert "more than the 10485760 a URDF may have here" in capsys.readouterr().err
    assert not (tmp_path / "pkg").exists()


def test_a_xacro_file_is_told_how_to_expand(tmp_path, capsys):
    path = tmp_path / "arm.urdf.xacro"
    path.write_text(MINIMAL)
    assert main(["--quiet", "generate", str(path)]) == 2
    assert "expand it first" in capsys.readouterr().err


# --------------------------------------------------------------------------- the reader's rules

def one_joint(rpy: str = "0 0 0", axis: str = "0 0 1", xyz: str = "0 0 0.1", extra: str = "") -> str:
    """A robot of one revolute joint j1 (links a -> b) with the given origin and axis."""
    return (f'<robot name="one"><link name="a"/><link name="b"/>{extra}'
            f'<joint name="j1" type="revolute"><parent link="a"/><child link="b"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/><limit lower="-1" upper="1"/></joint></robot>')


def parsed(text: str, snap: bool = True):
    from derivations.urdf import parse_urdf
    return parse_urdf(text, "inline.urdf", snap=snap)


QUIRKS = """<?xml version="1.0"?>
<robot name="quirky" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <material name="plain"><texture/></material>
  <link name="a">
    <visual><geometry><mesh filename="package://nowhere/a.dae" scale="one two"/></geometry>
      <material name="skin"><color rgba="red"/><texture/></material></visual>
    <collision><geometry><box/></geometry></collision>
    <inertial><mass value="heavy"/><inertia ixx="?"/><origin xyz="not numbers"/></inertial>
  </link>
  <link name="b"><sensor name="cam"/></link>
  <link name="c"/>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1"/>
    <dynamics damping="lots"/><safety_controller k_velocity="x"/><calibration rising="?"/></joint>
  <joint name="j2" type="continuous"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/>
    <axis xyz="0 1 0"/></joint>
  <transmission name="pr2_style" type="pr2_mechanism_model/SimpleTransmission">
    <actuator name="motor"/><joint name="j1"/><mechanicalReduction>1</mechanicalReduction></transmission>
  <gazebo reference="a"><material>Gazebo/Grey</material><mu1 value="0.2"/></gazebo>
  <gazebo><plugin name="control" filename="libgazebo_ros_control.so"/></gazebo>
  <xacro:property name="unused" value="1"/>
  <anything_else at="all"><joint name="nested_and_ignored" type="nonsense"/></anything_else>
</robot>
"""


def test_elements_kinematics_does_not_read_are_skipped_unread():
    """iCub's <texture/> without a filename, PR2's <transmission> without a <type>, <gazebo>
    blocks, malformed <inertial>, meshes, unknown elements (at the top and in a joint): none
    is read, and the chain loads as if they were not there."""
    import sympy as sp
    description = parsed(QUIRKS)
    assert [j.name for j in description.joints] == ["j1", "j2"]
    assert description.joints[1].origin == sp.ImmutableMatrix([[1, 0, 0, sp.Rational(1, 5)], [0, 1, 0, 0],
                                                               [0, 0, 1, 0], [0, 0, 0, 1]])
    assert description.joints[1].axis == (0, 1, 0) and description.joints[1].limits is None


@pytest.mark.parametrize("text, exact", [
    ("1.5708", "pi/2"), ("1.571", "pi/2"), ("1.57", "pi/2"), ("3.14159", "pi"), ("3.14159265", "pi"),
    ("1.570796327", "pi/2"), ("0.7854", "pi/4"), ("0.5236", "pi/6"), ("1.0472", "pi/3"), ("-1.5708", "-pi/2"),
    ("4.7124", "3*pi/2"), ("6.2832", "2*pi"), ("0.785", "pi/4"), ("0.524", "pi/6"), ("1.5707963267948968", "pi/2"),
    ("157.08e-2", "pi/2"), ("-1.67685e-15", "0"),
    ("1.6", None), ("1.5", None), ("0.52", None), ("1.58", None), ("1.5709", None), ("0.5", None), ("0.3", None)])
def test_an_angle_snaps_when_it_is_or_is_written_as_a_special_angle(text, exact):
    """Snapped: within 1e-8 of a multiple of pi/4 or pi/6, or that multiple correctly rounded at
    the places written with 3 significant digits or more (1.5708 is pi/2 to 4 places).  Not
    snapped: 1.6, 1.5, 0.52 (too few digits to say), 1.58 and 1.5709 (pi/2 to 2 and 4 places is
    1.57 and 1.5708).  The reason is computed here from Python's round, apart from the reader."""
    import sympy as sp
    value = float(text)
    digits, places = _places(text)
    description = parsed(one_joint(rpy=f"{text} 0 0"))
    rotation = description.joints[0].origin[:3, :3]
    if exact is None:
        special = round(value / (math.pi / 12)) * math.pi / 12
        assert digits < 3 or round(special, places) != value
        assert "snapped" not in description.notes
        assert rotation[1, 1] == sp.Float(math.cos(value)) and isinstance(rotation[1, 1], sp.Float)
        return
    angle = sp.sympify(exact)
    assert abs(value - float(angle)) <= 1e-8 or (digits >= 3 and round(float(angle), places) == value)
    c, s = sp.cos(angle), sp.sin(angle)
    assert rotation == sp.ImmutableMatrix([[1, 0, 0], [0, c, -s], [0, s, c]])
    assert description.notes["snapped"] == f"j1 origin rpy[0] {text} -> {angle}"


def test_with_snapping_off_every_angle_is_a_float_and_no_rational_is_large():
    """--no-snap: every non-zero angle is the double written (its cosine a number at once), and
    no number anywhere in the joints is a rational with a numerator or denominator past 2**53,
    in the five files and in one written with long decimals (those become floats)."""
    import sympy as sp
    from derivations.urdf import read_urdf
    long_decimals = one_joint(rpy="1.5708 0.1234567890123456789 -3", xyz="0.123456789012345678 1e-30 123456.7",
                              axis="0 0.6 0.8")
    descriptions = [read_urdf(URDF_DIR / filename, tip=tip, snap=False) for filename, tip in ROBOTS.values()]
    descriptions.append(parsed(long_decimals, snap=False))
    for description in descriptions:
        assert "snapped" not in description.notes
        for joint in description.joints:
            fields = [joint.origin, sp.Matrix(joint.axis)] + ([joint.after] if joint.after is not None else [])
            fields += [sp.Matrix(joint.limits)] if joint.limits is not None else []
            for field in fields:
                assert not field.has(sp.pi), (joint.name, field)
                assert all(f.args[0].free_symbols for f in field.atoms(sp.cos, sp.sin)), (joint.name, field)
                assert all(max(abs(r.p), r.q) <= 2**53 for r in field.atoms(sp.Rational)), (joint.name, field)
    origin = descriptions[-1].joints[0].origin
    expected = _rotation(1.5708, float("0.1234567890123456789"), -3.0)
    assert all(isinstance(entry, sp.Float) for entry in origin[:3, :3])
    assert np.max(np.abs(np.array(origin[:3, :3], dtype=float) - expected)) < 1e-15
    assert list(origin[:3, 3]) == [sp.Float(0.123456789012345678), sp.Float(1e-30), sp.Rational(1234567, 10)]


def test_lengths_are_small_rationals_or_floats():
    """A length is the rational of its digits while that has at most 15 significant digits and
    terms at most 2**53 (0.089159, 1e-15), else its double (17 digits; 1e-30, whose denominator
    is past 2**53); a number whose double is 0 is exactly 0."""
    import sympy as sp
    x = parsed(one_joint(xyz="0.089159 -0.10000000000000001 1e-30")).joints[0].origin[:3, 3]
    assert list(x) == [sp.Rational(89159, 10**6), sp.Float(-0.1), sp.Float(1e-30)]
    assert parsed(one_joint(xyz="1e-15 0 0")).joints[0].origin[0, 3] == sp.Rational(1, 10**15)
    assert parsed(one_joint(xyz="0 -0.0 1e-400")).joints[0].origin[:3, 3] == sp.zeros(3, 1)


@pytest.mark.parametrize("written, axis, note", [
    ("0.7071 0 0.7071", "(sqrt(2)/2, 0, sqrt(2)/2)", "j1 axis 0.7071 0 0.7071 -> [sqrt(2)/2, 0, sqrt(2)/2]"),
    ("0 0 0.99999999999", "(0, 0, 1)", "j1 axis 0 0 0.99999999999 -> [0, 0, 1]"),
    ("0 -1 5.55112e-17", "(0, -1, 0)", "j1 axis 0 -1 5.55112e-17 -> [0, -1, 0]"),
    ("0.5 0 0.866", "(1/2, 0, sqrt(3)/2)", "j1 axis 0.5 0 0.866 -> [1/2, 0, sqrt(3)/2]"),
    ("1 1 0", "(sqrt(2)/2, sqrt(2)/2, 0)", "j1 axis 1 1 0 -> [sqrt(2)/2, sqrt(2)/2, 0]"),
    ("0.5 0.5 0.70710678118654752", "(1/2, 1/2, sqrt(2)/2)", "j1 axis 0.5 0.5 0.70710678118654752 -> [1/2, 1/2, sqrt(2)/2]"),
    ("0 0 -1", "(0, 0, -1)", None), ("0 1.0 0", "(0, 1, 0)", None)])
def test_an_axis_snaps_to_an_exact_unit_vector(written, axis, note):
    """Each component snaps to 0, +-1/2, +-sqrt(2)/2, +-sqrt(3)/2, +-1 by the angles' rule; the
    snapped vector is kept when of unit length, normalised exactly when a diagonal (1 1 0)."""
    import sympy as sp
    description = parsed(one_joint(axis=written))
    assert description.joints[0].axis == sp.sympify(axis)
    assert description.notes.get("snapped") == note


@pytest.mark.parametrize("written", ["0.123456789012 0.2 0.9", "0.6 0 0.8", "1 2 2", "1e200 0 1e200"])
def test_an_axis_that_does_not_snap_is_normalised_in_floating_point(written):
    """Components not all special (0.123456789012, 0.6 with one digit, 2) or mixed: the written
    vector over its length, as floats; 1e200 (beyond what squares in a double) included."""
    import sympy as sp
    numbers = [float(v) for v in written.split()]
    expected = np.array(numbers) / math.hypot(*numbers)
    for snap in (True, False):
        axis = parsed(one_joint(axis=written), snap=snap).joints[0].axis
        assert all(isinstance(c, sp.Float) or c == 0 for c in axis)
        assert np.max(np.abs(np.array(axis, dtype=float) - expected)) < 1e-16
    assert parsed(one_joint(axis="0.7071 0 0.7071"), snap=False).joints[0].axis == (
        sp.Float(math.sqrt(0.5)), 0, sp.Float(math.sqrt(0.5)))


def test_mimic_numbers_follow_the_rules_of_their_kind():
    """The multiplier is a length-like number (exact 1/2); a revolute joint's offset an angle
    (1.5708 snaps to pi/2), a prismatic joint's a length."""
    import sympy as sp
    text = (URDF_DIR / "pantograph_mimic.urdf").read_text().replace('multiplier="-1" offset="0.25"',
                                                                   'multiplier="0.5" offset="1.5708"')
    description = parsed(text)
    assert "wrist_pitch mimic offset 1.5708 -> pi/2" in description.notes["snapped"]
    # wrist_pitch turns by q3/2 + pi/2 (cos(q3/2 + pi/2) is -sin(q3/2)), folded into wrist_roll's origin.
    wrist_roll = description.joints[-1].origin
    assert wrist_roll.has(sp.sin(sp.Symbol("q3", real=True) / 2)) and not wrist_roll.has(sp.Float)
    prismatic = parsed(text.replace('name="wrist_pitch" type="revolute"', 'name="wrist_pitch" type="prismatic"'))
    assert "mimic offset" not in prismatic.notes["snapped"]
    assert prismatic.joints[-1].origin.has(sp.Rational(7854, 5000))


def test_four_thousand_fixed_joints_in_a_line_parse_quickly():
    """The structure checks are single passes: 4,000 fixed joints took 16 s when the loop check
    walked from every link to the root."""
    n = 4000
    links = "".join(f'<link name="l{i}"/>' for i in range(n + 2))
    fixed = "".join(f'<joint name="f{i}" type="fixed"><parent link="l{i}"/><child link="l{i + 1}"/>'
                    f'<origin xyz="0 0 0.001"/></joint>' for i in range(n))
    moving = f'<joint name="j" type="revolute"><parent link="l{n}"/><child link="l{n + 1}"/></joint>'
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    description = parsed(f'<robot name="long">{links}{fixed}{moving}</robot>')
    assert time.process_time() - start < 5
    assert description.joints[0].origin[2, 3] == 4 and description.joints[0].axis == (1, 0, 0)


def test_show_names_the_chain_it_took_when_no_end_was_given(tmp_path, capsys):
    """A file whose one leaf is a gripper's jaw (the SO-100 of example-robot-data is such a file) gets
    that leaf as its tip: the run says which chain it took, with its joints, so that a user who meant
    the arm without the jaw sees it at once, and says so only where an end was left to the default."""
    path = tmp_path / "two_links.urdf"
    path.write_text("""<robot name="two">
  <link name="base"/><link name="arm"/><link name="jaw"/>
  <joint name="lift" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="grip" type="revolute"><parent link="arm"/><child link="jaw"/>
    <origin xyz="0.2 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>""")
    assert main(["show", str(path), "--what", "ik"]) == 0
    assert "the chain base -> jaw, 2 joints (lift, grip); --base and --tip choose another" in capsys.readouterr().err
    assert main(["show", str(path), "--base", "base", "--tip", "jaw", "--what", "ik"]) == 0
    assert "the chain" not in capsys.readouterr().err

"""The zoo of real URDF files: the arm chain a user would cut out of each, and an independent
forward kinematics of that chain read from the XML alone.

The files in tests/data/urdf/zoo/ are copied byte for byte from the PyPI wheels or the maker's
repository that ship them
(tests/data/urdf/zoo/SOURCES.md gives each one's package, upstream, licence and sha256).  They
are not written for this project: humanoids and mobile manipulators with dozens of joints,
xacro output with 1.5708 for pi/2, sensor frames, grippers with mimic joints, transmissions,
textures.  ``ZOO`` names, per file, the ``--base`` and ``--tip`` of its arm and how many moving
joints lie between them.

``XmlChain`` is the reference the tests hold the generated kernels to.  It shares nothing with
the project: the file is read with the standard library's ElementTree and each joint on the
chain composes ``Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`` of its origin with the motion about or
along its axis (Rodrigues' formula), in float64, with every number exactly as written.  Its
geometric Jacobian takes, per moving joint, that joint's world axis and origin (a mimic joint
adds its column, times its multiplier, to its leader's).  It is the chain of tests/formats/test_urdf.py,
extended to start at any ``base`` link and to take replacement numbers for the angles and axes
that snapping changed (so that the snapped model can be checked to 1e-12 as well).
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ZOO_DIR = Path(__file__).resolve().parent / "data" / "urdf" / "zoo"
ERD = "example-robot-data 6.0.0"
RTB = "rtb-data 2.0.0"
TROSSEN = "TrossenRobotics/trossen_arm_description 1.0.0"


@dataclass(frozen=True)
class ZooArm:
    """One arm of the zoo: ``file`` in ZOO_DIR, the chain ``base`` -> ``tip`` with ``joints``
    moving (non-fixed, non-mimic) joints, and ``source``, the wheel and folder the file came from."""

    file: str
    base: str
    tip: str
    joints: int
    source: str

    @property
    def path(self) -> Path:
        return ZOO_DIR / self.file


# The arm of each robot, from the base a user mounts it by to its flange or tool frame.  On the
# humanoids and mobile bases the base is the link the arm hangs from, so that torso, lift and
# leg joints stay out; grippers and fingers are other leaves and stay out too.
ZOO = {
    "xarm7": ZooArm("xarm7.urdf", "link_base", "link_eef", 7, f"{ERD}: xarm_description/urdf"),
    # The five arm joints (shoulder_pan .. wrist_roll) to the gripper's frame; the jaw is another leaf.
    "so101": ZooArm("so101.urdf", "base_link", "gripper_frame_link", 5, f"{ERD}: so_arm_description/urdf"),
    "z1": ZooArm("z1.urdf", "link00", "gripperStator", 6, f"{ERD}: z1_description/urdf"),
    # Kinova's JACO2 6-DOF with two fingers (j2s6s200), from the mounting block.
    "kinova_j2s6s200": ZooArm("kinova.urdf", "base", "j2s6s200_end_effector", 6,
                              f"{ERD}: kinova_description/robots"),
    # From the chest: shoulder pitch, roll, yaw, elbow, wrist prosup, pitch, yaw (no torso joints).
    "icub_left_arm": ZooArm("icub.urdf", "chest", "l_hand_dh_frame", 7, f"{ERD}: icub_description/robots"),
    "pr2_right_arm": ZooArm("pr2.urdf", "torso_lift_link", "r_wrist_roll_link", 7, f"{ERD}: pr2_description/urdf"),
    "romeo_left_arm": ZooArm("romeo.urdf", "torso", "l_gripper", 7, f"{ERD}: romeo_description/urdf"),
    "baxter_left_arm": ZooArm("baxter.urdf", "torso", "left_gripper", 7, f"{ERD}: baxter_description/urdf"),
    "ur3": ZooArm("ur3_robot.urdf", "base_link", "tool0", 6, f"{ERD}: ur_description/urdf"),
    "kr210": ZooArm("kr210l150.urdf", "base_link", "tool0", 6, f"{RTB}: xacro/kuka_description/kuka_kr210/urdf"),
    "kr16": ZooArm("kr16_2.urdf", "base_link", "tool0", 6, f"{RTB}: xacro/kuka_description/kuka_kr16/urdf"),
    "irb140": ZooArm("irb140.urdf", "base_link", "tool0", 6, f"{RTB}: xacro/abb_irb140_description/urdf"),
    "al5d": ZooArm("al5d_robot.urdf", "base", "link4", 4, f"{RTB}: xacro/lynxmotion_al5d_description/urdf"),
    "panda": ZooArm("panda.urdf", "panda_link0", "panda_hand", 7, f"{ERD}: panda_description/urdf"),
    # Trossen's WidowX AI follower arm (joint_0 .. joint_5) to its gripper's tool frame; the carriages
    # (one a mimic of the other) and the wrist camera's frames are other leaves.
    "wxai": ZooArm("wxai_follower.urdf", "base_link", "ee_gripper_link", 6,
                   f"{TROSSEN}: urdf/generated/wxai"),
}


def relative_error(got, expected) -> float:
    """Max-norm error relative to max(1, max |expected|): rotation entries are unit scale, and
    positions and Jacobian entries at most a few metres."""
    return float(np.max(np.abs(np.asarray(got) - expected)) / max(1.0, float(np.max(np.abs(expected)))))


# --------------------------------------------------------------------------- the independent FK

def _numbers(text: str | None, default) -> list[float]:
    return [float(v) for v in text.split()] if text else list(default)


def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp_ = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp_], [0, 1, 0], [-sp_, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _motion(kind: str, axis: np.ndarray, value: float) -> np.ndarray:
    T = np.eye(4)
    if kind == "prismatic":
        T[:3, 3] = axis * value
        return T
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    T[:3, :3] = np.eye(3) + math.sin(value) * K + (1 - math.cos(value)) * K @ K
    return T


class XmlChain:
    """The chain ``base`` -> ``tip`` of a URDF file, read with ElementTree, numbers as written.

    ``rpy`` ({(joint name, index): angle}) and ``axes`` ({joint name: xyz}) replace the file's
    numbers where given: the tests pass what a snapping model reports it changed.  Revolute and
    continuous joints turn, prismatic ones slide, fixed ones only carry their origin; a mimic
    joint moves with its leader (``multiplier * q + offset``)."""

    def __init__(self, path: Path, base: str, tip: str, rpy: dict | None = None, axes: dict | None = None):
        self.rpy, self.axes = rpy or {}, axes or {}
        joints = ET.parse(path).getroot().findall("joint")
        by_child = {j.find("child").get("link"): j for j in joints}
        chain, link = [], tip
        while link != base:
            if link not in by_child:
                raise ValueError(f"{path.name}: link {tip!r} is not below link {base!r}")
            chain.append(by_child[link])
            link = by_child[link].find("parent").get("link")
        self.joints = list(reversed(chain))
        moving = [j for j in self.joints if j.get("type") != "fixed" and j.find("mimic") is None]
        self.moving = [j.get("name") for j in moving]
        self.limits = [self._limit(j) for j in moving]

    @staticmethod
    def _limit(joint) -> tuple[float, float]:
        """The joint's range from <limit>; a continuous joint, or one without a range, over a turn."""
        element = joint.find("limit")
        if joint.get("type") == "continuous" or element is None:
            return (-math.pi, math.pi)
        low, high = float(element.get("lower", "0")), float(element.get("upper", "0"))
        return (-math.pi, math.pi) if low == high == 0 else (low, high)

    @property
    def n(self) -> int:
        return len(self.moving)

    def configurations(self, count: int, seed: int) -> np.ndarray:
        """``count`` joint vectors drawn uniformly within the limits."""
        low, high = np.array(self.limits).T
        return np.random.default_rng(seed).uniform(low, high, (count, self.n))

    def _origin(self, joint) -> np.ndarray:
        """The joint's <origin> as a transform (read from the XML once per joint: a walk reads every
        joint's, and the tests walk thousands of configurations)."""
        cache = self.__dict__.setdefault("_origins", {})
        if joint not in cache:
            cache[joint] = self._read_origin(joint)
        return cache[joint]

    def _read_origin(self, joint) -> np.ndarray:
        element = joint.find("origin")
        xyz = _numbers(element.get("xyz") if element is not None else None, (0, 0, 0))
        rpy = _numbers(element.get("rpy") if element is not None else None, (0, 0, 0))
        rpy = [self.rpy.get((joint.get("name"), k), angle) for k, angle in enumerate(rpy)]
        T = np.eye(4)
        T[:3, :3] = _rotation(*rpy)
        T[:3, 3] = xyz
        return T

    def _axis(self, joint) -> np.ndarray:
        cache = self.__dict__.setdefault("_axes", {})
        if joint not in cache:
            cache[joint] = self._read_axis(joint)
        return cache[joint]

    def _read_axis(self, joint) -> np.ndarray:
        element = joint.find("axis")
        written = _numbers(element.get("xyz") if element is not None else None, (1, 0, 0))
        axis = np.array(self.axes.get(joint.get("name"), written), dtype=float)
        return axis / np.linalg.norm(axis)

    def walk(self, q):
        """(the tip transform, per moving and mimic joint: (leader, multiplier, kind, world axis, world origin))."""
        value = dict(zip(self.moving, q))
        T = np.eye(4)
        axes = []
        for joint in self.joints:
            T = T @ self._origin(joint)
            kind = joint.get("type")
            if kind == "fixed":
                continue
            axis = self._axis(joint)
            mimic = joint.find("mimic")
            if mimic is not None:
                leader, multiplier = mimic.get("joint"), float(mimic.get("multiplier", "1"))
                angle = multiplier * value[leader] + float(mimic.get("offset", "0"))
            else:
                leader, multiplier, angle = joint.get("name"), 1.0, value[joint.get("name")]
            axes.append((leader, multiplier, kind, T[:3, :3] @ axis, T[:3, 3].copy()))
            T = T @ _motion(kind, axis, angle)
        return T, axes

    def fk(self, q) -> np.ndarray:
        return self.walk(q)[0]

    def jacobian(self, q) -> np.ndarray:
        T, axes = self.walk(q)
        J = np.zeros((6, self.n))
        for leader, multiplier, kind, z, o in axes:
            column = (np.concatenate([z, np.zeros(3)]) if kind == "prismatic"
                      else np.concatenate([np.cross(z, T[:3, 3] - o), z]))
            J[:, self.moving.index(leader)] += multiplier * column
        return J

"""URDF files -> serial-chain descriptions (the same :class:`Description` a TOML file gives).

The file is read by our own reader of URDF's kinematic subset, over the standard library's
ElementTree (expat), after two checks: at most :data:`MAX_BYTES`, and no document type
declaration (no entities: nothing in the file is expanded or fetched).  It reads ``<robot name>``,
``<link name>`` and ``<joint name type>`` with its ``<parent>``, ``<child>``, ``<origin xyz rpy>``,
``<axis xyz>``, ``<limit lower upper>`` and ``<mimic joint multiplier offset>``, and checks those
strictly; the ``<inertial>`` of the links the chain moves (for the equations of motion: read, folded
and checked in :meth:`_Chain._bodies`) and the ``<dynamics damping friction>`` of its moving joints
(viscous and Coulomb friction, :func:`_frictions`); every other element (visual, collision, material,
transmission, gazebo, the inertials of other links, ...) is skipped unread.  Real files carry quirks there that a full URDF parser refuses (iCub's
``<texture>`` without a filename, PR2's ``<transmission>`` without a ``<type>``), and kinematics
needs none of it.  Meshes are never opened.  From the tree we take the serial chain from ``base``
(default: the root link) to ``tip`` (default: the single leaf below it):

* revolute and continuous joints become R joints, prismatic ones P joints, each a
  general joint: the fixed transform of its ``<origin>`` then the motion about or
  along its ``<axis>`` (``derivations.chain.axis_motion``);
* fixed joints fold into the next moving joint's fixed transform (those after the
  last moving joint into its ``after`` transform, so the last frame is the tip link);
* a ``<mimic>`` joint folds in the same way, moving with its leader
  (``multiplier * q_leader + offset``), whose Jacobian column then includes it;
* floating and planar joints on the chain are refused, naming them.

Numbers are read strictly as XML Schema decimals or doubles (``1.5``, ``-.25``, ``1e-3``; no
``nan``, ``inf``, ``1_000`` or non-ASCII digits), at most :data:`LARGEST` in size, and kept as
what derives well:

* lengths (origin xyz, limits, a mimic multiplier and a prismatic mimic offset) become the exact
  rational of their digits (``0.089159`` is 89159/10^6), so that zeros stay zeros and sums
  cancel, when that rational is small (:func:`_length`); otherwise the double they denote;
* angles (origin rpy, a revolute mimic offset) become the double they denote, a SymPy ``Float``,
  whose cosine and sine are numbers at once; an exact rational such as 3927/2500 (``1.5708``) would
  stay ``cos(3927/2500)`` through every product and make the derivation explode;
* with ``snap`` (the default), an angle that is, or is written as, a multiple of pi/4 or of pi/6
  becomes that multiple exactly, and so does an axis component that is one of 0, 1/2,
  sqrt(2)/2, sqrt(3)/2, 1 (with either sign); see :func:`_written_as` for "written as" (within
  :data:`SNAP_TOLERANCE`, or correctly rounded at the precision written: ``1.5708``, ``0.7071``).
  What was snapped is listed in the description's ``notes["snapped"]``;
* the fixed transforms folded together stay small however many there are (:func:`_compose`).

Every error is a :class:`derivations.formats.shared.DescriptionError` naming the file and the joint
(or link) and, for a number, its field.
"""
from __future__ import annotations

import functools
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from pathlib import Path
from typing import Sequence

import numpy as np
import sympy as sp

from ..chain import PRISMATIC, REVOLUTE, Joint, axis_motion, rpy_matrix
from ..expressions import is_package_name
from ..mechanics.inertia import INERTIA_ORDER, Actuator, Inertial, check_physical, combine, transformed
from .shared import MAX_JOINTS, Description, DescriptionError, read_input

__all__ = ["read_urdf", "parse_urdf", "MAX_BYTES", "SNAP_TOLERANCE"]

# A URDF of a whole humanoid with its inertias is well under 1 MB; anything past this is refused unread.
MAX_BYTES = 10 * 2**20
# 1e-8, not tighter: ROS's own UR descriptions write pi as 3.14159265, so their pi/2 is 1.8e-9 off.
SNAP_TOLERANCE = 1e-8
# A number written to fewer significant digits than this is never taken for a rounded special
# value: 1.6 or 0.52 may mean just that, while 1.57 and 0.524 are pi/2 and pi/6 written short.
SNAP_DIGITS = 3
# Angles snap within this many turns either way (100 rad): no arm writes larger ones, and far
# enough out (1e8 rad) the spacing of doubles is itself SNAP_TOLERANCE.
SNAP_TURNS = 16
# No length in metres or angle in radians comes near; a file that writes one is hostile.
LARGEST = 1e300
# A rational length keeps its numerator and denominator at most this (a double's 53 bits), so
# that exact arithmetic on it stays as cheap as the sums it keeps exact.
RATIONAL_TERMS = 2**53
# A 4x4 transform as rows of SymPy numbers (see _compose).
Rows = Sequence[Sequence[sp.Expr]]
IDENTITY: Rows = tuple(map(tuple, sp.eye(4).tolist()))
# Standard gravity (m/s^2), the default of an arm's parameter `gravity` (along -z of its base).
STANDARD_GRAVITY = 9.81
MOVING = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC}
JOINT_TYPES = (*MOVING, "fixed", "floating", "planar")
# XML Schema's decimal and double lexical forms without its INF and NaN (re.ASCII: no other digits).
NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?", re.ASCII)
# XML's whitespace: what separates the numbers of a list such as xyz="0 0 0.1".
SPACES = re.compile(r"[ \t\r\n]+")
# The values an axis component snaps to (0, +-1, +-1/2, +-sqrt(2)/2, +-sqrt(3)/2), each with its double.
AXIS_VALUES = [(v, float(v)) for v in (sp.S.Zero, *(s * u for u in (sp.S.One, sp.S.Half, sp.sqrt(2) / 2,
                                                                      sp.sqrt(3) / 2) for s in (1, -1)))]


def read_urdf(path: str | Path, base: str | None = None, tip: str | None = None, snap: bool = True) -> Description:
    """The serial chain ``base`` -> ``tip`` of a URDF file, as a description."""
    path = Path(path)
    raw = read_input(path, MAX_BYTES, "URDF")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DescriptionError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    description = parse_urdf(text, str(path), base=base, tip=tip, snap=snap, stem=path.stem)
    description.inputs = raw
    return description


def parse_urdf(text: str, origin: str = "<string>", base: str | None = None, tip: str | None = None,
               snap: bool = True, stem: str = "robot") -> Description:
    """The serial chain ``base`` -> ``tip`` of the URDF ``text`` (``origin`` names it in messages;
    ``stem`` names the robot when the file's own name cannot name a package)."""
    if re.search(r"<!(DOCTYPE|ENTITY)", text):
        raise DescriptionError(f"{origin}: a document type or entity declaration; a URDF needs neither "
                               "(refused: entities could expand without bound)")
    try:
        root = ET.fromstring(text)  # a str: expat reads it as UTF-8 whatever its declaration says
    except ET.ParseError as exc:
        message = " ".join(str(exc).split())
        raise DescriptionError(f"{origin}: not a valid URDF: {message}") from None
    chain = _Chain(origin, snap)
    chain.read(root)
    return chain.description(base, tip, stem)


@dataclass(frozen=True)
class _Number:
    """A number as written: its text (for messages and notes), its exact value and its double."""

    text: str
    value: Decimal
    double: float


ZERO, ONE = _Number("0", Decimal(0), 0.0), _Number("1", Decimal(1), 1.0)


@dataclass
class _UrdfJoint:
    """A ``<joint>`` as read: names, and its numbers as written (URDF's defaults where absent)."""

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[_Number, ...] = (ZERO, ZERO, ZERO)
    rpy: tuple[_Number, ...] = (ZERO, ZERO, ZERO)
    axis: tuple[_Number, ...] = (ONE, ZERO, ZERO)
    limit: tuple[_Number, _Number] | None = None  # (lower, upper)
    mimic: tuple[str, _Number, _Number] | None = None  # (leader, multiplier, offset)
    dynamics: ET.Element | None = None  # <dynamics damping friction>: read for the chain's joints (_frictions)
    dynamics_count: int = 0


@dataclass
class _UrdfInertial:
    """A link's ``<inertial>`` as read: the centre of mass's origin, the mass and the tensor."""

    xyz: tuple[_Number, ...] = (ZERO, ZERO, ZERO)
    rpy: tuple[_Number, ...] = (ZERO, ZERO, ZERO)
    mass: _Number = ZERO
    inertia: tuple[_Number, ...] = (ZERO,) * 6


class _Chain:
    """One file's links and joints as read (:meth:`read`), then its chain as a description
    (:meth:`description`); every refusal names the file (``origin``)."""

    def __init__(self, origin: str, snap: bool):
        self.origin, self.snap = origin, snap
        self.name: str | None = None
        self.links: list[str] = []
        self.joints: list[_UrdfJoint] = []
        self.snapped: list[str] = []
        self.inertial_elements: dict[str, ET.Element] = {}  # link name -> its <link> element

    def fail(self, message: str):
        raise DescriptionError(f"{self.origin}: {message}")

    # -- reading the kinematic elements --------------------------------------------------------------

    def read(self, root: ET.Element) -> None:
        """The robot's name, links and joints; every other element is skipped unread."""
        if root.tag != "robot":
            self.fail(f"not a valid URDF: the root element is <{root.tag}>, not <robot>")
        self.name = root.get("name")
        links: set[str] = set()
        joints: set[str] = set()
        for element in root:
            if element.tag == "link":
                name = element.get("name")
                if not name:
                    self.fail(f"<link> number {len(self.links) + 1} has no name")
                if name in links:  # ROS refuses it too: which of the two would a joint mean?
                    self.fail(f"link {name!r} is defined twice")
                links.add(name)
                self.links.append(name)
                self.inertial_elements[name] = element  # its <inertial> is read if the chain moves it
            elif element.tag == "joint":
                joint = self._joint(element, len(self.joints) + 1)
                if joint.name in joints:
                    self.fail(f"joint {joint.name!r} is defined twice")
                joints.add(joint.name)
                self.joints.append(joint)

    def _joint(self, element: ET.Element, number: int) -> _UrdfJoint:
        name = element.get("name")
        if not name:
            self.fail(f"<joint> number {number} has no name")
        kind = element.get("type")
        if kind not in JOINT_TYPES:
            what = "no type" if kind is None else f"type {kind!r}"
            self.fail(f"joint {name!r}: {what} (a URDF joint is {', '.join(JOINT_TYPES)})")
        ends = {}
        for role in ("parent", "child"):
            end = self._only(element, role, name)
            if end is None or not end.get("link"):
                self.fail(f"joint {name!r}: no <{role} link=\"...\"/>")
            ends[role] = end.get("link")
        joint = _UrdfJoint(name, kind, ends["parent"], ends["child"])
        origin = self._only(element, "origin", name)
        if origin is not None:
            if origin.get("xyz") is not None:
                joint.xyz = self._numbers(origin.get("xyz"), name, "origin xyz")
            if origin.get("rpy") is not None:
                joint.rpy = self._numbers(origin.get("rpy"), name, "origin rpy")
        if kind not in MOVING:  # a fixed joint's axis, limits and mimic move nothing
            return joint
        axis = self._only(element, "axis", name)
        if axis is not None and axis.get("xyz") is not None:
            joint.axis = self._numbers(axis.get("xyz"), name, "axis")
        limit = self._only(element, "limit", name)
        if limit is not None:
            joint.limit = (self._attribute(limit, "lower", name, "limit", ZERO),
                           self._attribute(limit, "upper", name, "limit", ZERO))
        found = element.findall("dynamics")
        joint.dynamics = found[0] if len(found) == 1 else None  # two: refused if the chain's (_frictions)
        joint.dynamics_count = len(found)
        mimic = self._only(element, "mimic", name)
        if mimic is not None:
            if not mimic.get("joint"):
                self.fail(f"joint {name!r}: <mimic> names no joint to follow")
            joint.mimic = (mimic.get("joint"), self._attribute(mimic, "multiplier", name, "mimic", ONE),
                           self._attribute(mimic, "offset", name, "mimic", ZERO))
        return joint

    def _inertial(self, link: ET.Element, name: str) -> "_UrdfInertial | None":
        """A link's ``<inertial>``: ``<origin xyz rpy>`` of the centre of mass, ``<mass value>`` and
        ``<inertia ixx ixy ixz iyy iyz izz>`` (URDF's defaults: origin 0, the rest required).
        Read only for the links of the chain's bodies (:meth:`_bodies`), and checked there: a file's other
        links may carry what no rigid body has (a base link's placeholder), which moves nothing."""
        found = link.findall("inertial")
        if len(found) > 1:
            self.fail(f"link {name!r}: {len(found)} <inertial> elements (a link has at most one)")
        if not found:
            return None
        element = found[0]
        inertial = _UrdfInertial()
        origin = element.findall("origin")
        if origin and origin[0].get("xyz") is not None:
            inertial.xyz = self._numbers(origin[0].get("xyz"), name, "inertial origin xyz", "link")
        if origin and origin[0].get("rpy") is not None:
            inertial.rpy = self._numbers(origin[0].get("rpy"), name, "inertial origin rpy", "link")
        mass = element.findall("mass")
        if not mass or mass[0].get("value") is None:
            self.fail(f"link {name!r}: <inertial> without <mass value=\"...\"/>")
        inertial.mass = self._number(mass[0].get("value"), name, "mass", "link")
        tensor = element.findall("inertia")
        if not tensor:
            self.fail(f"link {name!r}: <inertial> without <inertia ixx=... iyz=.../>")
        inertial.inertia = tuple(self._attribute(tensor[0], key, name, "inertia", ZERO, "link")
                                 for key in INERTIA_ORDER)
        return inertial

    def _attribute(self, element: ET.Element, attribute: str, joint: str, field: str, default: _Number,
                   kind: str = "joint") -> _Number:
        """The number ``attribute`` of ``element`` (field ``"<field> <attribute>"``), or URDF's default."""
        text = element.get(attribute)
        return default if text is None else self._number(text, joint, f"{field} {attribute}", kind)

    def _only(self, element: ET.Element, tag: str, joint: str) -> ET.Element | None:
        """The joint's one ``<tag>`` element, or None; two would leave the kinematics ambiguous."""
        found = element.findall(tag)
        if len(found) > 1:
            self.fail(f"joint {joint!r}: {len(found)} <{tag}> elements (a joint has at most one)")
        return found[0] if found else None

    def _numbers(self, text: str, joint: str, field: str, kind: str = "joint") -> tuple[_Number, ...]:
        tokens = SPACES.split(text.strip(" \t\r\n"))
        if len(tokens) != 3:
            self.fail(f"{kind} {joint!r}: {field} needs 3 numbers, got {_shown(text)}")
        return tuple(self._number(token, joint, f"{field}[{k}]", kind) for k, token in enumerate(tokens))

    def _number(self, text: str, joint: str, field: str, kind: str = "joint") -> _Number:
        """``kind`` names what the number belongs to in messages: a joint, or a link (its inertial)."""
        text = text.strip(" \t\r\n")
        if not NUMBER.fullmatch(text):
            if text.lstrip("+-").lower() in ("nan", "inf", "infinity"):
                self.fail(f"{kind} {joint!r}: {field} is {text} (expected a finite number)")
            self.fail(f"{kind} {joint!r}: {field} {_shown(text)} is not a number (expected a decimal such as "
                      "-0.25 or 1.5e-3)")
        double = float(text)
        if not abs(double) <= LARGEST:
            self.fail(f"{kind} {joint!r}: {field} {_shown(text)} is more than {LARGEST:g} in size")
        return _Number(text, Decimal(text), double)

    # -- the chain -----------------------------------------------------------------------------------

    def description(self, base: str | None, tip: str | None, stem: str) -> Description:
        """Every check below is a single pass (dictionaries and sets, each link walked once), so
        that a file of thousands of links is refused or read in time linear in its size."""
        if not self.joints:
            self.fail("no joints: a robot needs at least one moving joint")
        links = set(self.links)
        parent_of: dict[str, _UrdfJoint] = {}
        for joint in self.joints:
            for role in ("parent", "child"):
                if getattr(joint, role) not in links:
                    self.fail(f"joint {joint.name!r}: its {role} link {getattr(joint, role)!r} is not defined")
            if joint.child in parent_of:
                self.fail(f"joint {joint.name!r}: link {joint.child!r} already has the parent joint "
                          f"{parent_of[joint.child].name!r} (a URDF is a tree)")
            parent_of[joint.child] = joint
        rooted: set[str] = set()  # links whose parents are known to end at a root
        for link in self.links:  # a loop: following parents comes back before reaching a root
            walk, current = set(), link
            while current in parent_of and current not in rooted:
                if current in walk:
                    self.fail(f"joint {parent_of[current].name!r}: the links form a loop (a URDF is a tree)")
                walk.add(current)
                current = parent_of[current].parent
            rooted |= walk
        roots = [link for link in self.links if link not in parent_of]
        if base is None:
            if len(roots) != 1:
                self.fail(f"{len(roots)} root links ({', '.join(roots)}): give --base")
            base = roots[0]
        if base not in links:
            self.fail(f"no link {base!r} (links: {', '.join(self.links)})")
        children: dict[str, list[str]] = {}
        for joint in self.joints:
            children.setdefault(joint.parent, []).append(joint.child)
        if tip is None:
            leaves, stack = [], [base]
            while stack:
                link = stack.pop()
                below = children.get(link, [])
                stack.extend(reversed(below))
                if not below and link != base:
                    leaves.append(link)
            if len(leaves) != 1:
                self.fail(f"{len(leaves)} leaf links below {base!r} ({', '.join(sorted(leaves)) or 'none'}): "
                          "give --tip")
            tip = leaves[0]
        if tip not in links:
            self.fail(f"no link {tip!r} (links: {', '.join(self.links)})")
        path, current = [], tip
        while current != base:
            if current not in parent_of:
                self.fail(f"link {tip!r} is not below link {base!r}")
            path.append(parent_of[current])
            current = parent_of[current].parent
        path.reverse()
        return self._build(path, base, tip, stem)

    def _build(self, path: list[_UrdfJoint], base: str, tip: str, stem: str) -> Description:
        for joint in path:
            if joint.type not in MOVING and joint.type != "fixed":
                self.fail(f"joint {joint.name!r}: type {joint.type!r} on the chain {base} -> {tip} "
                          "(revolute, continuous, prismatic and fixed joints are supported)")
        moving = [j for j in path if j.type in MOVING and j.mimic is None]
        if not moving:
            self.fail(f"no moving joint between {base!r} and {tip!r}")
        if len(moving) > MAX_JOINTS:  # the limit of a TOML description too, checked before any work
            self.fail(f"{len(moving)} moving joints between {base!r} and {tip!r}; a chain has 1 to {MAX_JOINTS} "
                      "(give --base and --tip to cut out the arm)")
        q = tuple(sp.Symbol(f"q{i + 1}", real=True) for i in range(len(moving)))
        symbol = {j.name: qi for j, qi in zip(moving, q)}
        joints: list[Joint] = []
        pending = IDENTITY  # fixed and mimic transforms since the last moving joint
        for joint in path:
            transform = self._origin(joint)
            if joint.type == "fixed":
                pending = _compose(pending, transform)
                continue
            axis = self._axis(joint)
            kind = MOVING[joint.type]
            if joint.mimic is not None:
                leader, multiplier, offset = joint.mimic
                if leader not in symbol:
                    self.fail(f"joint {joint.name!r}: mimics {leader!r}, which is not a moving joint of the chain")
                offset = (self._angle(offset, joint, "mimic offset") if kind == REVOLUTE
                          else _length(offset))
                value = _length(multiplier) * symbol[leader] + offset
                pending = _compose(pending, transform, axis_motion(kind, axis, value).tolist())
                continue
            joints.append(Joint(kind, origin=sp.ImmutableMatrix(_compose(pending, transform)), axis=axis,
                                limits=self._limits(joint), name=joint.name, link=joint.child))
            pending = IDENTITY
        if pending != IDENTITY:
            last = joints[-1]
            joints[-1] = Joint(last.type, origin=last.origin, axis=last.axis, limits=last.limits, name=last.name,
                               after=sp.ImmutableMatrix(pending), link=tip)
        inertials, dynamics_note = self._bodies(path, moving, joints)
        name = self.name if self.name is not None and is_package_name(self.name) else None
        name = name or (stem if is_package_name(stem) else "urdf_robot")
        notes = {"snapped": "; ".join(self.snapped)} if self.snapped else {}
        if dynamics_note:
            notes["dynamics"] = dynamics_note
        params, gravity = {}, ()
        if inertials:  # gravity along -z of the base link, of the size of the parameter `gravity`
            symbol = sp.Symbol("gravity", real=True)
            params, gravity = {symbol: STANDARD_GRAVITY}, (sp.S.Zero, sp.S.Zero, -symbol)
        return Description(
            name=name, title=f"{self.name or name} (URDF, {base} to {tip})",
            source=f"URDF {Path(self.origin).name}: {' '.join(j.name for j in path)}",
            convention="urdf", task=["pose"], params=params, joints=joints, tool=sp.eye(4), notes=notes, q=q,
            base_link=base, inertials=inertials, gravity=gravity,
            gravity_parameter=next(iter(params), None), actuators=self._frictions(moving) if inertials else ())

    def _frictions(self, moving: list[_UrdfJoint]) -> tuple:
        """Each moving joint's ``<dynamics damping friction>`` as an actuator with viscous friction
        ``damping`` and Coulomb friction ``friction`` (URDF has no element for a rotor's inertia or
        gear); empty where no joint of the chain has a non-zero one.  Read only for the chain's
        joints: another joint's may be what a simulator alone reads."""
        actuators = []
        for joint in moving:
            if joint.dynamics_count > 1:
                self.fail(f"joint {joint.name!r}: {joint.dynamics_count} <dynamics> elements (a joint has at most one)")
            if joint.dynamics is None:
                actuators.append(None)
                continue
            numbers = [self._attribute(joint.dynamics, key, joint.name, "dynamics", ZERO) for key in ("damping", "friction")]
            for number, key in zip(numbers, ("damping", "friction")):
                if number.double < 0:
                    self.fail(f"joint {joint.name!r}: dynamics {key} {number.text} is negative "
                              "(friction takes energy out)")
            actuators.append(Actuator(viscous=_length(numbers[0]), coulomb=_length(numbers[1]))
                             if any(n.double for n in numbers) else None)
        return tuple(actuators) if any(actuators) else ()

    # -- inertial parameters -------------------------------------------------------------------------

    def _bodies(self, path: list[_UrdfJoint], moving: list[_UrdfJoint], joints: list[Joint]):
        """Each moving joint's body as one :class:`Inertial` in its link frame (the model's frame k),
        and a note on what was folded; ``()`` where no link of the chain's bodies has an inertial.

        Body k is the child link of moving joint k with every link that hangs from it rigidly:
        through fixed joints, and through moving joints off the chain (a gripper's fingers, held at
        their zero position, as a reduced model locks them); it ends at the next moving joint of
        the chain.  Each link is checked physical (:func:`derivations.mechanics.inertia.check_physical`,
        naming it) and the links are combined by the parallel-axis theorem, in float64."""
        mimics = [j.name for j in path if j.mimic is not None]
        below: dict[str, list[_UrdfJoint]] = {}
        for joint in self.joints:
            below.setdefault(joint.parent, []).append(joint)
        chain_children = {j.child for j in moving}
        mark = len(self.snapped)  # angles snapped here were noted already (chain) or are not the chain's
        bodies, held, found = [], [], False
        for k, joint in enumerate(moving):
            parts = []
            stack = [(joint.child, np.eye(4))]
            while stack:
                link, placement = stack.pop()
                inertial = self._inertial(self.inertial_elements[link], link)
                if inertial is not None:
                    found = True
                    with np.errstate(over="ignore", invalid="ignore"):  # a sum past a double: refused below
                        parts.append(self._link_inertial(link, inertial, placement))
                for child in below.get(link, []):
                    if child.child in chain_children:
                        continue
                    if child.type in MOVING:
                        held.append(child.name)
                    stack.append((child.child, placement @ self._float_origin(child)))
            with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below
                bodies.append(combine(parts) if parts else (0.0, np.zeros(3), np.zeros((3, 3))))
        del self.snapped[mark:]
        if not found:
            return (), ""
        if mimics:
            return (), (f"no dynamics: the chain has mimic joints ({', '.join(mimics)}), whose links move "
                        "relative to their leader's")
        after = joints[-1].after
        if after is not None:  # the last body in the tip link's frame: x_body = R x_tip + p
            A = np.array(sp.Matrix(after).evalf(30).tolist(), dtype=float)
            with np.errstate(over="ignore", invalid="ignore"):
                bodies[-1] = transformed(*bodies[-1], A[:3, :3].T, -A[:3, :3].T @ A[:3, 3])
        for joint, body in zip(moving, bodies):  # each part finite, their sum past a double
            if not all(np.all(np.isfinite(x)) for x in body):
                self.fail(f"link {joint.child!r}: inertial: the links it carries sum to more than a double holds")
        note = (f"dynamics: joints off the chain held at zero and their links folded into the chain's "
                f"bodies: {', '.join(held)}" if held else "")
        return tuple(Inertial.from_numbers(*body) for body in bodies), note

    def _link_inertial(self, link: str, inertial: "_UrdfInertial", placement: np.ndarray):
        """The link's (mass, com, tensor) in its body's frame (``placement``: body -> link), checked."""
        mass = inertial.mass.double
        xx, xy, xz, yy, yz, zz = (n.double for n in inertial.inertia)
        tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])

        def fail(message):
            self.fail(f"link {link!r}: inertial: {message}")
        check_physical(mass, np.zeros(3), tensor, fail)
        rotation = _float_rotation([float(self._angle(n, _UrdfJoint(link, "fixed", "", ""), "")) for n in inertial.rpy])
        offset = np.array([n.double for n in inertial.xyz])
        mass, com, tensor = transformed(mass, np.zeros(3), tensor, rotation, offset)  # inertial frame -> link
        return transformed(mass, com, tensor, placement[:3, :3], placement[:3, 3])

    def _float_origin(self, joint: _UrdfJoint) -> np.ndarray:
        """A joint's origin as a float64 transform, its angles snapped as the chain's are."""
        transform = np.eye(4)
        transform[:3, :3] = _float_rotation([float(self._angle(n, joint, "")) for n in joint.rpy])
        transform[:3, 3] = [n.double for n in joint.xyz]
        return transform

    # -- numbers -------------------------------------------------------------------------------------

    def _origin(self, joint: _UrdfJoint) -> Rows:
        angles = [self._angle(n, joint, f"origin rpy[{k}]") for k, n in enumerate(joint.rpy)]
        rotation = _rotation(*angles)
        return (*((*rotation[k], _length(n)) for k, n in enumerate(joint.xyz)), IDENTITY[3])

    def _angle(self, number: _Number, joint: _UrdfJoint, field: str) -> sp.Expr:
        """An angle: the special angle it is or is written as (with snapping, within
        :data:`SNAP_TURNS`), else its double; 0 stays exact."""
        if number.double == 0:
            return sp.S.Zero
        if self.snap and abs(number.double) <= SNAP_TURNS * 2 * math.pi:
            # The special angles are the multiples k pi/12 with k even (pi/6) or a multiple of 3
            # (pi/4). They lie pi/12 apart or more, and a number is only ever taken for one within
            # 0.005 of it, so only the nearest multiple of pi/12 can be the one.
            k = round(number.double / (math.pi / 12))
            special = k * sp.pi / 12
            if (k % 2 == 0 or k % 3 == 0) and _written_as(number, special, k * math.pi / 12):
                self.snapped.append(f"{joint.name} {field} {number.text} -> {special}")
                return special
        return sp.Float(number.double)

    def _axis(self, joint: _UrdfJoint) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
        """The unit axis: exact where the written one is a coordinate axis, or (with snapping) its
        components are special values, else the written vector normalised in floating point."""
        written = joint.axis
        length = math.hypot(*(n.double for n in written))  # hypot: no overflow for 1e200
        if length < 1e-12:
            self.fail(f"joint {joint.name!r}: axis {[n.double for n in written]} has zero length")
        if sorted(abs(n.value) for n in written) == [0, 0, 1]:
            return tuple(sp.Integer(int(n.value)) for n in written)
        if self.snap:
            snapped = [next((v for v, double in AXIS_VALUES if _written_as(n, v, double)), None) for n in written]
            if None not in snapped:
                unit = _unit(snapped)
                if unit is not None:
                    if not all(_is_exactly(n, v) for n, v in zip(written, unit)):
                        self.snapped.append(f"{joint.name} axis {' '.join(n.text for n in written)} -> {list(unit)}")
                    return unit
        return tuple(sp.S.Zero if n.double == 0 else sp.Float(n.double / length) for n in written)

    def _limits(self, joint: _UrdfJoint):
        if joint.type == "continuous" or joint.limit is None:
            return None
        low, high = (_length(n) for n in joint.limit)
        if low > high:
            self.fail(f"joint {joint.name!r}: limit lower {float(low)} above upper {float(high)}")
        if low == high == 0:  # URDF's default when a prismatic or revolute joint gives no range
            return None
        return (low, high)


def _float_rotation(rpy) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` in float64."""
    (cr, sr), (cp, sp_), (cy, sy) = ((math.cos(a), math.sin(a)) for a in rpy)
    return np.array([[cy * cp, cy * sp_ * sr - sy * cr, cy * sp_ * cr + sy * sr],
                     [sy * cp, sy * sp_ * sr + cy * cr, sy * sp_ * cr - cy * sr],
                     [-sp_, cp * sr, cp * cr]])


def _length(number: _Number) -> sp.Expr:
    """The exact rational of the digits when it is small: at most 15 significant digits (a double
    holds 15 decimal digits exactly) and numerator and denominator at most
    :data:`RATIONAL_TERMS`; else the double, so that no number drags huge integers through the
    derivation.  A number whose double is zero (``0``, ``-0.0``, ``1e-400``) is exactly zero."""
    if number.double == 0:
        return sp.S.Zero
    sign, digits, exponent = number.value.as_tuple()
    written = "".join(map(str, digits))
    significant = written.rstrip("0")
    if len(significant) <= 15:  # the exponent is then bounded by the double's range
        return _rational(Fraction(int(significant) * (-1) ** sign)
                         * Fraction(10) ** (exponent + len(written) - len(significant)))
    return sp.Float(number.double)


def _compose(*transforms: Rows) -> Rows:
    """The product of fixed (and mimic) transforms, entry by entry: a float in a term makes the
    entry a float, summed in floating point (it is inexact anyway); otherwise it stays exact,
    tidied (:func:`_tidy`).  Plain lists, not SymPy matrices: their product takes a float times
    sqrt(2)/2 through SymPy's assumptions system (30 ms a fixed joint), and building one costs
    more than the product of two rigid transforms."""
    product = transforms[0]
    for transform in transforms[1:]:
        columns = list(zip(*transform))
        product = tuple(tuple(_dot(row, column) for column in columns) for row in product)
    return product


def _dot(row: Sequence[sp.Expr], column: Sequence[sp.Expr]) -> sp.Expr:
    """One entry of a product of transforms (:func:`_compose`)."""
    terms = [(a, b) for a, b in zip(row, column) if a is not sp.S.Zero and b is not sp.S.Zero]
    if all(a.is_Rational and b.is_Rational for a, b in terms):  # 0, 1 and lengths: most entries
        return _rational(sum((Fraction(a.p, a.q) * Fraction(b.p, b.q) for a, b in terms), Fraction(0)))
    if any(a.is_Float or b.is_Float for a, b in terms) and all(a.is_number and b.is_number for a, b in terms):
        total = math.fsum(_double(a) * _double(b) for a, b in terms)
        return sp.Float(total) if total else sp.S.Zero
    return _tidy(sp.Add(*(a * b for a, b in terms)))


def _rational(value: Fraction) -> sp.Expr:
    """``value`` exactly while its terms are at most :data:`RATIONAL_TERMS`, else its double."""
    if max(abs(value.numerator), value.denominator) <= RATIONAL_TERMS:
        return sp.Rational(value.numerator, value.denominator)
    return sp.Float(float(value))


@functools.lru_cache(maxsize=256)
def _rotation(roll: sp.Expr, pitch: sp.Expr, yaw: sp.Expr) -> Rows:
    """The rows of ``Rz(yaw) Ry(pitch) Rx(roll)``, tidied (cached: a file repeats its few
    rotations, pi/2 about an axis above all)."""
    return tuple(map(tuple, rpy_matrix(roll, pitch, yaw).applyfunc(_tidy).tolist()))


@functools.lru_cache(maxsize=256)
def _double(number: sp.Expr) -> float:
    """The double of a numeric entry (cached: sqrt(2)/2 and its kin recur at every joint)."""
    return float(number)


def _tidy(entry: sp.Expr) -> sp.Expr:
    """A numeric entry of a fixed transform in a form that stays small however many fixed joints
    are composed: a single Float when it holds a float (it is inexact anyway); else expanded,
    so that products of the sines and cosines of pi/4 and pi/6 stay sums of at most four terms
    (in 1, sqrt(2), sqrt(3), sqrt(6)) instead of nesting deeper with every joint; and a Float
    once a rational in it passes :data:`RATIONAL_TERMS` (those rationals double in size with
    every such rotation).  Unexpanded, ten fixed joints turned by rpy="0.7854 0.5236 0" took
    minutes.  Entries with symbols (a mimic joint's motion) are left as they are."""
    if entry.is_Float or entry.is_Integer or entry.free_symbols:
        return entry
    if not entry.is_Rational:
        if entry.has(sp.Float):
            return entry.evalf()
        entry = sp.expand(entry)
    if all(max(abs(r.p), r.q) <= RATIONAL_TERMS for r in entry.atoms(sp.Rational)):
        return entry
    return entry.evalf()


def _written_as(number: _Number, value: sp.Expr, double: float) -> bool:
    """Whether ``number`` is ``value`` (whose double is ``double``) as a file would write it:
    within :data:`SNAP_TOLERANCE` of it (float noise, as 1.5707963267948968 for pi/2), or its
    correctly rounded form at the precision written.  That precision is the place of the last
    digit written (``1.5708`` and ``15708e-4``: 4 places after the point), and the rounded form
    is within half a unit of it, compared exactly against 40 digits of ``value``.  The number
    needs :data:`SNAP_DIGITS` significant digits and 2 places after the point (so that ``12.6``
    or ``100``, 3 digits of a large number, is not taken for a multiple of pi/12 nearby); past 8
    places the first rule holds whenever this one does, which also bounds the work on a long
    number."""
    if abs(number.double - double) <= SNAP_TOLERANCE:
        return True
    _, digits, exponent = number.value.as_tuple()
    places = -exponent
    if len(digits) < SNAP_DIGITS or not 2 <= places <= 8:
        return False
    return abs(Fraction(number.value) - _reference(value)) <= Fraction(1, 2 * 10**places)


@functools.lru_cache(maxsize=256)
def _reference(value: sp.Expr) -> Fraction:
    """40 significant digits of a special value (cached: files write the same few again and again)."""
    return Fraction(str(sp.N(value, 40)))


def _unit(snapped: list[sp.Expr]) -> tuple[sp.Expr, ...] | None:
    """The snapped axis when it is exactly of unit length; normalised exactly when its non-zero
    components are equal in size (a diagonal written by its direction: ``1 1 0`` is
    (sqrt(2)/2, sqrt(2)/2, 0), ``1 1 1`` has sqrt(3)/3), which keeps every root small; None
    otherwise (mixed sizes would bring roots such as sqrt(5) that buy nothing over floats)."""
    if sum(v**2 for v in snapped) == 1:
        return tuple(snapped)
    sizes = {abs(v) for v in snapped if v != 0}
    if len(sizes) != 1:
        return None
    count = sum(1 for v in snapped if v != 0)
    return tuple(sp.sign(v) * sp.sqrt(count) / count for v in snapped)


def _is_exactly(number: _Number, value: sp.Expr) -> bool:
    """Whether the decimal written is ``value`` itself (compared exactly; an irrational never is)."""
    return value.is_Rational and number.value == Decimal(int(value.p)) / Decimal(int(value.q))


def _shown(text: str) -> str:
    """``text`` quoted for a message, cut short: a number may be megabytes long."""
    return repr(text if len(text) <= 40 else text[:40] + "...")

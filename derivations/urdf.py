"""URDF files -> serial-chain descriptions (the same :class:`Description` a TOML file gives).

The file is parsed by ``urdf_parser_py`` (ROS's URDF parser; pure Python over lxml),
after two checks of our own: at most :data:`MAX_BYTES`, and no document type
declaration (no entities: nothing in the file is expanded or fetched).  Meshes are
never opened.  From the tree we take the serial chain from ``base`` (default: the
root link) to ``tip`` (default: the single leaf below it):

* revolute and continuous joints become R joints, prismatic ones P joints, each a
  general joint: the fixed transform of its ``<origin>`` then the motion about or
  along its ``<axis>`` (``derivations.chain.axis_motion``);
* fixed joints fold into the next moving joint's fixed transform (those after the
  last moving joint into its ``after`` transform, so the last frame is the tip link);
* a ``<mimic>`` joint folds in the same way, moving with its leader
  (``multiplier * q_leader + offset``), whose Jacobian column then includes it;
* floating and planar joints on the chain are refused, naming them.

Numbers become exact: each decimal the rational of its digits (``0.089159`` is
89159/10^6), so that zeros stay zeros.  With ``snap`` (the default), an rpy angle
within :data:`SNAP_TOLERANCE` of a multiple of pi/2 becomes that multiple exactly and
an axis within it of a coordinate axis becomes that axis; what was snapped is listed
in the description's ``notes["snapped"]``.  Every error is a
:class:`derivations.description.DescriptionError` naming the file and the joint.
"""
from __future__ import annotations

import contextlib
import io
import math
import re
from pathlib import Path

import sympy as sp

from .chain import PRISMATIC, REVOLUTE, Joint, axis_motion, rpy_matrix
from .description import Description, DescriptionError
from .expressions import is_package_name

__all__ = ["read_urdf", "MAX_BYTES", "SNAP_TOLERANCE"]

# A URDF of a whole humanoid with its inertias is well under 1 MB; anything past this is refused unread.
MAX_BYTES = 10 * 2**20
# 1e-8, not tighter: ROS's own UR descriptions write pi as 3.14159265, so their pi/2 is 1.8e-9 off.
SNAP_TOLERANCE = 1e-8
MOVING = {"revolute": REVOLUTE, "continuous": REVOLUTE, "prismatic": PRISMATIC}


def read_urdf(path: str | Path, base: str | None = None, tip: str | None = None, snap: bool = True) -> Description:
    """The serial chain ``base`` -> ``tip`` of a URDF file, as a description."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise DescriptionError(f"{path}: cannot read: {exc.strerror}") from None
    if size > MAX_BYTES:
        raise DescriptionError(f"{path}: {size} bytes, more than the {MAX_BYTES} a URDF may have here")
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DescriptionError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    return parse_urdf(text, str(path), base=base, tip=tip, snap=snap, stem=path.stem)


def parse_urdf(text: str, origin: str = "<string>", base: str | None = None, tip: str | None = None,
               snap: bool = True, stem: str = "robot") -> Description:
    if re.search(r"<!(DOCTYPE|ENTITY)", text):
        raise DescriptionError(f"{origin}: a document type or entity declaration; a URDF needs neither "
                               "(refused: entities could expand without bound)")
    from urdf_parser_py.urdf import URDF  # imported here: only URDF input needs it

    try:
        with contextlib.redirect_stderr(io.StringIO()):  # its warnings on unknown tags
            robot = URDF.from_xml_string(text.encode("utf-8"))
    except Exception as exc:  # lxml's XMLSyntaxError, the parser's ParseError, ...
        message = " ".join(str(exc).split()) or type(exc).__name__
        raise DescriptionError(f"{origin}: not a valid URDF: {message}") from None
    return _Chain(origin, robot, snap).description(base, tip, stem)


class _Chain:
    def __init__(self, origin: str, robot, snap: bool):
        self.origin, self.robot, self.snap = origin, robot, snap
        self.snapped: list[str] = []

    def fail(self, message: str):
        raise DescriptionError(f"{self.origin}: {message}")

    def description(self, base: str | None, tip: str | None, stem: str) -> Description:
        robot = self.robot
        links = [link.name for link in robot.links]
        if not robot.joints:
            self.fail("no joints: a robot needs at least one moving joint")
        parent_of: dict[str, object] = {}
        for joint in robot.joints:
            for role in ("parent", "child"):
                if getattr(joint, role) not in links:
                    self.fail(f"joint {joint.name!r}: its {role} link {getattr(joint, role)!r} is not defined")
            if joint.child in parent_of:
                self.fail(f"joint {joint.name!r}: link {joint.child!r} already has the parent joint "
                          f"{parent_of[joint.child].name!r} (a URDF is a tree)")
            parent_of[joint.child] = joint
        for link in links:  # a loop: following parents comes back
            seen, current = set(), link
            while current in parent_of:
                if current in seen:
                    self.fail(f"joint {parent_of[current].name!r}: the links form a loop (a URDF is a tree)")
                seen.add(current)
                current = parent_of[current].parent
        roots = [link for link in links if link not in parent_of]
        if base is None:
            if len(roots) != 1:
                self.fail(f"{len(roots)} root links ({', '.join(roots)}): give --base")
            base = roots[0]
        if base not in links:
            self.fail(f"no link {base!r} (links: {', '.join(links)})")
        children: dict[str, list[str]] = {}
        for joint in robot.joints:
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
            self.fail(f"no link {tip!r} (links: {', '.join(links)})")
        path, current = [], tip
        while current != base:
            if current not in parent_of:
                self.fail(f"link {tip!r} is not below link {base!r}")
            path.append(parent_of[current])
            current = parent_of[current].parent
        path.reverse()
        return self._build(path, base, tip, stem)

    def _build(self, path, base: str, tip: str, stem: str) -> Description:
        for joint in path:
            if joint.type not in MOVING and joint.type not in ("fixed",):
                self.fail(f"joint {joint.name!r}: type {joint.type!r} on the chain {base} -> {tip} "
                          "(revolute, continuous, prismatic and fixed joints are supported)")
        moving = [j for j in path if j.type in MOVING and j.mimic is None]
        if not moving:
            self.fail(f"no moving joint between {base!r} and {tip!r}")
        q = tuple(sp.Symbol(f"q{i + 1}", real=True) for i in range(len(moving)))
        symbol = {j.name: qi for j, qi in zip(moving, q)}
        joints: list[Joint] = []
        pending = sp.eye(4)  # fixed and mimic transforms since the last moving joint
        for joint in path:
            transform = self._origin(joint)
            if joint.type == "fixed":
                pending = pending * transform
                continue
            axis = self._axis(joint)
            kind = MOVING[joint.type]
            if joint.mimic is not None:
                leader = joint.mimic.joint
                if leader not in symbol:
                    self.fail(f"joint {joint.name!r}: mimics {leader!r}, which is not a moving joint of the chain")
                value = (self._exact(joint.mimic.multiplier if joint.mimic.multiplier is not None else 1.0,
                                     joint, "mimic multiplier") * symbol[leader]
                         + self._exact(joint.mimic.offset or 0.0, joint, "mimic offset"))
                pending = pending * transform * axis_motion(kind, axis, value)
                continue
            joints.append(Joint(kind, origin=sp.ImmutableMatrix(pending * transform), axis=axis,
                                limits=self._limits(joint, kind), name=joint.name))
            pending = sp.eye(4)
        if pending != sp.eye(4):
            last = joints[-1]
            joints[-1] = Joint(last.type, origin=last.origin, axis=last.axis, limits=last.limits, name=last.name,
                               after=sp.ImmutableMatrix(pending))
        name = self.robot.name if isinstance(self.robot.name, str) and is_package_name(self.robot.name) else None
        name = name or (stem if is_package_name(stem) else "urdf_robot")
        notes = {"snapped": "; ".join(self.snapped)} if self.snapped else {}
        return Description(
            name=name, title=f"{self.robot.name or name} (URDF, {base} to {tip})",
            source=f"URDF {Path(self.origin).name}: {' '.join(j.name for j in path)}",
            convention="urdf", task=["pose"], params={}, joints=joints, tool=sp.eye(4), notes=notes, q=q)

    # -- exact numbers -------------------------------------------------------------------------------

    def _exact(self, value, joint, field: str) -> sp.Expr:
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"joint {joint.name!r}: {field} {value!r} is not a number")
        if not math.isfinite(number):
            self.fail(f"joint {joint.name!r}: {field} is {number} (expected a finite number)")
        return sp.Rational(repr(number))

    def _origin(self, joint) -> sp.Matrix:
        origin = joint.origin
        xyz = list(origin.xyz) if origin is not None and origin.xyz is not None else [0.0] * 3
        rpy = list(origin.rpy) if origin is not None and origin.rpy is not None else [0.0] * 3
        if len(xyz) != 3 or len(rpy) != 3:
            self.fail(f"joint {joint.name!r}: origin needs 3 numbers in xyz and in rpy")
        exact_xyz = [self._exact(v, joint, f"origin xyz[{k}]") for k, v in enumerate(xyz)]
        angles = [self._angle(v, joint, f"origin rpy[{k}]") for k, v in enumerate(rpy)]
        transform = sp.eye(4)
        transform[:3, :3] = rpy_matrix(*angles)
        transform[:3, 3] = sp.Matrix(exact_xyz)
        return transform

    def _angle(self, value, joint, field: str) -> sp.Expr:
        exact = self._exact(value, joint, field)
        if not self.snap or exact == 0:
            return exact
        turns = round(float(value) / (math.pi / 2))
        if abs(float(value) - turns * math.pi / 2) <= SNAP_TOLERANCE:
            snapped = turns * sp.pi / 2
            self.snapped.append(f"{joint.name} {field} {float(value)!r} -> {snapped}")
            return snapped
        return exact

    def _axis(self, joint) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
        values = list(joint.axis) if joint.axis is not None else [1.0, 0.0, 0.0]  # URDF's default axis
        if len(values) != 3:
            self.fail(f"joint {joint.name!r}: axis needs 3 numbers")
        exact = [self._exact(v, joint, f"axis[{k}]") for k, v in enumerate(values)]
        length = math.sqrt(sum(float(v)**2 for v in values))
        if length < 1e-12:
            self.fail(f"joint {joint.name!r}: axis {values} has zero length")
        if self.snap:
            unit = [float(v) / length for v in values]
            for k in range(3):
                for sign in (1, -1):
                    target = [0.0, 0.0, 0.0]
                    target[k] = float(sign)
                    if max(abs(u - t) for u, t in zip(unit, target)) <= SNAP_TOLERANCE:
                        snapped = tuple(sp.Integer(int(t)) for t in target)
                        if list(snapped) != exact:
                            self.snapped.append(f"{joint.name} axis {values} -> {list(snapped)}")
                        return snapped
        norm = sp.sqrt(sum(v**2 for v in exact))
        return tuple(sp.nsimplify(v / norm) if norm != 1 else v for v in exact)

    def _limits(self, joint, kind: str):
        if joint.type == "continuous" or joint.limit is None:
            return None
        low, high = joint.limit.lower, joint.limit.upper
        if low is None or high is None:
            return None
        low = self._exact(low, joint, "limit lower")
        high = self._exact(high, joint, "limit upper")
        if low > high:
            self.fail(f"joint {joint.name!r}: limit lower {float(low)} above upper {float(high)}")
        if low == high == 0:  # URDF's default when a prismatic or revolute joint gives no range
            return None
        return (low, high)

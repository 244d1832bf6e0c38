"""Mobility of a mechanism by the Grübler-Kutzbach count (Kumar, section 5.1).

``n`` moving links, ``g`` joints, joint ``i`` of connectivity ``f_i`` (the degrees
of freedom it leaves between the two links it joins):

* spatial, Kumar's Eq. (2): ``M = 6 n - sum(6 - f_i) = 6 (n - g) + sum f_i``
* planar,  Kumar's Eq. (3): ``M = 3 (n - g) + sum f_i``

For a serial chain (``n = g``) both reduce to ``M = sum f_i``.  Connectivity by
joint type (Kumar: R, P and H have 1, S has 3); C (cylindrical) and U
(universal) have 2, E (planar pair) 3; any other joint is given by its
connectivity, an integer.  A planar chain has only R and P joints (Kumar:
"A planar chain can only allow prismatic and revolute joints"), or a planar
higher pair of connectivity 2 given as an integer.

The count is a count: it ignores special geometry (parallel axes that make an
overconstrained linkage move, idle rotations of a leg between two spherical
joints), as Kumar's formula does.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Sequence

import sympy as sp

__all__ = ["CONNECTIVITY", "MechanismError", "Mechanism", "describe", "mobility", "serial_chain",
           "robot_mechanism", "is_planar_chain", "EXAMPLES"]

CONNECTIVITY = {"R": 1, "P": 1, "H": 1, "C": 2, "U": 2, "S": 3, "E": 3}
PLANAR_TYPES = ("R", "P")
GROUND = "ground"


class MechanismError(ValueError):
    """A mechanism description that cannot be counted; the message names the joint or link."""


@dataclass(frozen=True)
class Mechanism:
    """A validated mechanism: moving links, and per joint its type, connectivity and links.

    ``links`` names the moving links (``"1"``, ``"2"``, ... when given as a count);
    ``joints`` holds ``(type, connectivity, link_a, link_b)``, the type ``None``
    for a joint given by connectivity alone, and the links ``None`` when the
    description did not name them.
    """

    links: tuple[str, ...]
    joints: tuple[tuple[str | None, int, str | None, str | None], ...]
    planar: bool

    @property
    def n(self) -> int:
        return len(self.links)

    @property
    def g(self) -> int:
        return len(self.joints)

    @property
    def connectivity(self) -> int:
        """``sum f_i``."""
        return sum(j[1] for j in self.joints)

    @property
    def mobility(self) -> int:
        """Kumar Eq. (3) when planar, Eq. (2) otherwise."""
        freedom = 3 if self.planar else 6
        return freedom * (self.n - self.g) + self.connectivity


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _connectivity(kind, index: int, planar: bool) -> tuple[str | None, int]:
    where = f"joint {index}"
    top = 2 if planar else 5
    if _is_int(kind):
        if not 1 <= kind <= top:
            raise MechanismError(f"{where}: connectivity must be an integer from 1 to {top} "
                                 f"({'planar' if planar else 'spatial'} mechanism), got {kind}")
        return None, int(kind)
    if isinstance(kind, str) and kind.upper() in CONNECTIVITY:
        letter = kind.upper()
        if planar and letter not in PLANAR_TYPES:
            raise MechanismError(f"{where}: a planar mechanism has only R and P joints "
                                 f"(or a connectivity 1 or 2 as an integer), got {kind!r}")
        return letter, CONNECTIVITY[letter]
    raise MechanismError(f"{where}: expected a joint type ({', '.join(CONNECTIVITY)}) or a connectivity "
                         f"(integer), got {kind!r}")


def _link_table(links) -> tuple[tuple[str, ...], dict]:
    """Moving link names and a lookup {reference: name} (ground = 0 or "ground")."""
    if _is_int(links):
        if links < 0:
            raise MechanismError(f"links: the number of moving links must be >= 0, got {links}")
        names = tuple(str(i) for i in range(1, links + 1))
        lookup = {i: str(i) for i in range(1, links + 1)}
    elif isinstance(links, Sequence) and not isinstance(links, (str, bytes)):
        names = tuple(links)
        for name in names:
            if not isinstance(name, str) or not name or name == GROUND:
                raise MechanismError(f"links: each moving link needs a name (a non-empty string other than "
                                     f"{GROUND!r}), got {name!r}")
        if len(set(names)) != len(names):
            raise MechanismError(f"links: a link name repeats: {list(names)}")
        lookup = {name: name for name in names}
        lookup.update({i: name for i, name in enumerate(names, 1)})
    else:
        raise MechanismError(f"links: expected the number of moving links or a list of their names, got {links!r}")
    lookup[0] = GROUND
    lookup[GROUND] = GROUND
    return names, lookup


def describe(links, joints, planar: bool = False) -> Mechanism:
    """Validate a mechanism description (see :func:`mobility`) into a :class:`Mechanism`."""
    names, lookup = _link_table(links)
    if isinstance(joints, str):
        joints = list(joints)  # "RRPS": one letter per joint
    if not isinstance(joints, Sequence):
        raise MechanismError(f"joints: expected a list of joints, got {joints!r}")
    rich = [isinstance(j, (tuple, list)) for j in joints]
    if any(rich) and not all(rich):
        raise MechanismError("joints: either every joint names its two links, as (type, link_a, link_b), or none does")
    parsed = []
    for i, joint in enumerate(joints, 1):
        if not rich[i - 1]:
            kind, f = _connectivity(joint, i, planar)
            parsed.append((kind, f, None, None))
            continue
        if len(joint) != 3:
            raise MechanismError(f"joint {i}: expected (type, link_a, link_b), got {tuple(joint)!r}")
        kind, f = _connectivity(joint[0], i, planar)
        ends = []
        for ref in joint[1:]:
            usable = isinstance(ref, (str, numbers.Integral)) and not isinstance(ref, bool)
            if not usable or ref not in lookup:
                known = ", ".join([f"{GROUND!r} (or 0)"] + [f"{name!r} (or {k})" for k, name in enumerate(names, 1)])
                if _is_int(links):
                    known = f"0 (ground) and 1..{len(names)}" if names else "0 (ground) only"
                raise MechanismError(f"joint {i} ({joint[0]}): unknown link {ref!r}; known links: {known}")
            ends.append(lookup[ref])
        if ends[0] == ends[1]:
            raise MechanismError(f"joint {i} ({joint[0]}): joins link {ends[0]!r} to itself")
        parsed.append((kind, f, ends[0], ends[1]))
    if parsed and all(rich):
        attached = {end for j in parsed for end in j[2:]}
        loose = [name for name in names if name not in attached]
        if loose:
            raise MechanismError(f"links {loose} are attached to no joint")
    return Mechanism(names, tuple(parsed), bool(planar))


def mobility(links, joints, planar: bool = False) -> int:
    """The Grübler-Kutzbach mobility ``M`` (Kumar Eqs. 2 and 3).

    ``links``: the number of moving links (ground not counted), or a list of
    their names.  ``joints``: one entry per joint, each a type letter (R, P, H,
    S, C, U, E; a string "RRPS" lists one per letter), a connectivity
    (integer), or ``(type, link_a, link_b)`` naming the two links it joins, by
    name or by index (1..n in the order of ``links``, ground = 0 or "ground").
    ``planar`` selects Eq. (3).  Raises :class:`MechanismError` naming the joint
    or link at fault.
    """
    return describe(links, joints, planar).mobility


def serial_chain(joint_types: Sequence[str], planar: bool = False) -> Mechanism:
    """A serial chain ground - 1 - 2 - ... - n, one joint of each type between neighbours."""
    n = len(joint_types)
    return describe(n, [(kind, i, i + 1) for i, kind in enumerate(joint_types)], planar)


def is_planar_chain(model) -> bool:
    """Whether a DH model's chain is planar in Kumar's sense, for every joint value.

    Every revolute axis along the base z axis and every prismatic axis in the
    base xy plane (checked symbolically: the axes do not depend on ``q`` then).
    """
    chain = getattr(model, "chain", None)
    if chain is None:
        raise MechanismError(f"{model.name} is not a serial DH chain: describe its links and joints")
    if chain.convention == "standard":
        frames = model.frames[:chain.n]  # z_{i-1} of joint i; the tool transform touches only the last frame
    else:
        frames = chain.link_frames(model.q)[1:]  # Craig: joint i moves about z_i
    for joint, frame in zip(chain.joints, frames):
        z = [sp.simplify(e) for e in frame[:3, 2]]
        if joint.type == "R" and not (z[0] == 0 and z[1] == 0 and z[2] in (1, -1)):
            return False
        if joint.type == "P" and z[2] != 0:
            return False
    return True


def robot_mechanism(model) -> Mechanism:
    """The serial chain of a registered robot, planar when its axes allow (:func:`is_planar_chain`).

    A robot that is not one DH chain (the AVR 3000) is counted as the serial arm
    its model uses, spatially: Sotirov models the frog leg by the two-link arm
    q1, q2 with the lift q3, the closed loop of the legs keeping the tool radial.
    """
    if getattr(model, "chain", None) is None:
        return serial_chain(model.joint_types, planar=False)
    return serial_chain(model.joint_types, planar=is_planar_chain(model))


def _legs(count: int, leg: str, platform: str) -> tuple[list[str], list[tuple[str, str, str]]]:
    """``count`` identical legs from ground to ``platform``, one link between consecutive joints."""
    links, joints = [], []
    for k in range(1, count + 1):
        previous = GROUND
        for j, kind in enumerate(leg):
            if j == len(leg) - 1:
                joints.append((kind, previous, platform))
            else:
                link = f"leg{k}.{j + 1}"
                links.append(link)
                joints.append((kind, previous, link))
                previous = link
    return links + [platform], joints


def _examples() -> dict[str, dict]:
    parallel_links, parallel_joints = _legs(3, "RRR", "platform")
    stewart_links, stewart_joints = _legs(6, "RRPS", "platform")
    return {
        # Kumar Example 1, Figs. 4 and 5: serial planar arms.
        "planar_3r": dict(links=3, joints="RRR", planar=True),
        "planar_rpr": dict(links=3, joints="RPR", planar=True),
        # Kumar Example 2, Fig. 3: crank, connecting rod and piston; three pins and the piston's slide.
        "slider_crank": dict(links=["crank", "rod", "piston"],
                             joints=[("R", GROUND, "crank"), ("R", "crank", "rod"), ("R", "rod", "piston"),
                                     ("P", "piston", GROUND)], planar=True),
        # Kumar Example 3, Fig. 6: three RRR legs from the ground to a moving platform (n = 7, g = 9).
        "planar_parallel": dict(links=parallel_links, joints=parallel_joints, planar=True),
        # Kumar Fig. 7: six RRPS legs (two revolute joints, a prismatic and a spherical one).
        "stewart_platform": dict(links=stewart_links, joints=stewart_joints, planar=False),
    }


EXAMPLES = _examples()
"""Kumar's worked examples as descriptions: {name: dict(links=..., joints=..., planar=...)}."""

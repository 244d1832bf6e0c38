"""What both description formats produce: the :class:`Description`, its errors and its checks.

A TOML description (:mod:`derivations.formats.description`) and a URDF file
(:mod:`derivations.formats.urdf`) both become a :class:`Description`: a validated chain
with its parameters, task and limits, not yet derived.  The reading of a file within a size
cap (:func:`read_input`) and the checks of a task and of a held joint live here too, shared
by both readers and by ``derivations.load``.
"""
from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp

from ..chain import Chain, Joint
from ..model import TASK_ITEMS, TASK_ITEMS_TEXT

__all__ = ["MAX_JOINTS", "MAX_DESCRIPTION_BYTES", "DescriptionError", "Description", "read_input", "check_task",
           "task_option", "free_joint_index"]


# The most joints a description may have: every arm in the zoo has at most 8 (a Panda with its
# finger, or a 7-joint arm on a rail).  A general chain (every twist pi/2, every offset non-zero)
# derives and renders in 32 s with 7 joints, 59 s with 8 and past 100 s with 9, so a longer
# chain, up to a file of 3000 joints, is refused at once rather than left to its time budget.
MAX_JOINTS = 8


class DescriptionError(ValueError):
    """A robot description is malformed; the message names file, joint and field."""


@dataclass
class Description:
    """A parsed, validated description (exact SymPy values, not yet derived)."""

    name: str
    title: str
    source: str
    convention: str
    task: list[str]
    params: dict[sp.Symbol, float]
    joints: list[Joint]
    tool: sp.Matrix
    notes: dict[str, str]
    q: tuple[sp.Symbol, ...]
    base: sp.Matrix = field(default_factory=lambda: sp.eye(4))
    # The bytes the description was read from (a TOML, and the URDF it names): what the cache keys
    # the derivation by, read once, so that a file changing while it is read cannot key one robot's
    # model by another's bytes.
    inputs: bytes = b""
    # The link the chain starts at (a URDF's base link): the name of frame 0.
    base_link: str = ""
    # The joint (0-based) a seven-joint arm's ik holds at its argument `free`; None: chosen.
    free_joint: int | None = None
    # Each moving link's inertial parameters (derivations.mechanics.inertia.Inertial, in the link's frame k),
    # and gravity in the base frame (3 expressions): empty for an arm without them (no dynamics).
    inertials: tuple = ()
    gravity: tuple = ()
    # The parameter the reader added for gravity's size (None: gravity uses the file's own).
    gravity_parameter: sp.Symbol | None = None
    # Each joint's drive (derivations.mechanics.inertia.Actuator) or None; empty where no joint has one.
    actuators: tuple = ()

    def drop_dynamics(self) -> None:
        """Kinematics only: no inertials, no gravity, no actuators, and no parameter added for gravity."""
        if self.gravity_parameter is not None:
            self.params.pop(self.gravity_parameter, None)
        self.inertials, self.gravity, self.gravity_parameter, self.actuators = (), (), None, ()

    def chain(self) -> Chain:
        return Chain(self.joints, self.convention, self.tool, self.base)


# A description of a few joints is a few kilobytes; a URDF of a whole humanoid with its inertias is
# well under a megabyte (derivations.formats.urdf.MAX_BYTES).
MAX_DESCRIPTION_BYTES = 2**20


def read_input(path: Path, limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them, read once.

    Anything else is refused without blocking or reading on: a folder, a FIFO (opened without
    waiting for a writer), a device such as /dev/zero, a path with a NUL byte, a file past the limit.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise DescriptionError(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise DescriptionError(f"{path}: not a regular file (a {what} is read from a file)")
        if info.st_size > limit:  # refused unread
            raise DescriptionError(f"{path}: {info.st_size} bytes, more than the {limit} a {what} may have here")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(2**20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise DescriptionError(f"{path}: cannot read: {exc.strerror}") from None
    finally:
        os.close(fd)
    if size > limit:  # it grew while it was read
        raise DescriptionError(f"{path}: more than the {limit} bytes a {what} may have here")
    return b"".join(chunks)


def check_task(task, fail) -> list[str]:
    """A task as a list of items (TASK_ITEMS), each once: ``pose`` holds x, y, z and the rotation,
    ``approach`` a column of that rotation.  ``fail(message)`` raises."""
    expected = f"a non-empty list of names among {TASK_ITEMS_TEXT.replace(' or ', ', ')}"
    if not isinstance(task, list) or not task or not all(isinstance(t, str) for t in task):
        fail(f"expected {expected}")
    bad = [t for t in task if t not in TASK_ITEMS]
    if bad:
        fail(f"unknown task coordinate {bad[0]!r} (expected {TASK_ITEMS_TEXT})")
    holds = {"pose": ("x", "y", "z", "rotation"), "approach": ("rotation",)}
    names = [n for t in task for n in holds.get(t, (t,))]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        what = "the rotation" if repeated[0] == "rotation" else repeated[0]
        fail(f"{what!r} is asked for twice (pose already holds x, y, z and the whole rotation, "
             "of which approach is a column)")
    return task


def task_option(text: str, fail) -> list[str]:
    """The task of a ``--task`` option: names separated by commas (``x,y,z,pitch``)."""
    items = [t.strip() for t in str(text).split(",")]
    if not all(items):
        fail(f"expected names separated by commas, such as x,y,z,pitch (got {str(text)!r})")
    return check_task(items, fail)


def free_joint_index(value, joints, fail) -> int:
    """The 0-based index of the joint ``value`` names: its number (1-based) or its name."""
    if len(joints) != 7:
        fail(f"the held joint is for a seven-joint arm's ik; this chain has {len(joints)} joints")
    names = [j.name for j in joints]
    if isinstance(value, str) and value in names:
        return names.index(value)
    if isinstance(value, str) and value.isdigit():
        value = int(value)
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= len(joints):
        return value - 1
    named = f" or a joint's name ({', '.join(n for n in names if n)})" if any(names) else ""
    fail(f"{value!r} is not a joint of the chain: expected a number from 1 to {len(joints)}{named}")

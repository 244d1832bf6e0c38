"""A chain's kinematics, derived: the frames, the Jacobian and the task coordinates of a model.

:func:`build_chain_model` is the slow symbolic step that turns a :class:`~derivations.chain.Chain`
(what a description or a URDF becomes) into a :class:`~derivations.model.RobotModel`: frames
expanded and simplified where they stay short, a straight-line program
(:mod:`derivations.chain_program`) otherwise; :func:`task_coordinates` names the task items
(``x, y, z, phi, pitch, roll, approach, pose``) as expressions in the joint variables.  The
model itself is data and imports none of this (issue #29).
"""
from __future__ import annotations

from typing import Sequence

import sympy as sp

from .chain import REVOLUTE, Chain, derivative, simplify_derivative, simplify_entry, simplify_product
from .chain_program import explicit_pays, program_kinematics
from .chain_program import task_jacobian as program_task_jacobian
from .model import APPROACH_NAMES, POSE_NAMES, TASK_ITEMS_TEXT, RobotModel, TaskError

__all__ = ["build_chain_model", "task_coordinates", "pitch_joints", "joint_angle_task"]


def pitch_joints(chain: Chain) -> list[tuple[int, sp.Expr]]:
    """The joints whose turns make the task coordinate ``pitch``: the first run of two or more
    consecutive revolute joints with parallel axes (a 4- or 5-joint arm's shoulder, elbow and wrist
    pitch), each with its sign ``h_i . h_first`` (+-1).  Empty if the chain has no such run.
    Parallel axes stay parallel at every q (the run's own joints turn them about their common
    direction; earlier joints turn them together), so the run is read at q = 0."""
    from .ik.structure import cross, dot, is_zero, tidy  # the axis geometry ik/ reads too
    zero = [sp.S.Zero] * chain.n
    axes = [sp.Matrix(h).applyfunc(tidy) for h, _ in chain.joint_axes(chain.link_frames(zero))]
    kinds = [j.type for j in chain.joints]

    def parallel(i, j):
        return all(is_zero(e) for e in cross(axes[i], axes[j]))
    for first in range(chain.n - 1):
        if kinds[first] != REVOLUTE:
            continue
        run = [first]
        while run[-1] + 1 < chain.n and kinds[run[-1] + 1] == REVOLUTE and parallel(first, run[-1] + 1):
            run.append(run[-1] + 1)
        if len(run) >= 2:
            norm2 = tidy(dot(axes[first], axes[first]))
            return [(i, sp.sign(tidy(dot(axes[i], axes[first]) / norm2))) for i in run]
    return []


def joint_angle_task(item: str, chain: Chain, q) -> sp.Expr:
    """The task coordinates ``pitch`` and ``roll``, exact linear forms in the joint angles.

    ``pitch``: the tool's turn about the common direction of the first run of parallel revolute
    axes (:func:`pitch_joints`), relative to q = 0: ``sum s_i q_i`` over the run.  For an arm of a
    base turn and parallel pitch joints (``R(q) = Rot(h1, q1) Rot(h2, pitch) R(0)``, the AL5D, the
    SO-101) it is the angle the gripper is tipped by in the arm's plane.  ``roll``: the turn of
    the last joint, a revolute one about the tool's own axis (the wrist roll of a 5-joint arm)."""
    if item == "roll":
        if chain.joints[-1].type != REVOLUTE:
            raise TaskError("task coordinate 'roll' needs the last joint revolute (a wrist roll)")
        return q[-1]
    run = pitch_joints(chain)
    if not run:
        raise TaskError("task coordinate 'pitch' needs two or more consecutive revolute joints with parallel "
                         "axes (an arm's shoulder, elbow and wrist pitch)")
    return sum((s * q[i] for i, s in run), sp.S.Zero)


def task_coordinates(spec: Sequence[str], chain: Chain, q, fk: sp.Matrix, link_frames) -> tuple[list[str], sp.Matrix]:
    """Task coordinates named in ``spec`` as exact expressions in ``q``.

    ``x, y, z``: the tool point; ``pose``: the tool point followed by the nine
    entries of the tool rotation, row by row; ``phi``: the planar orientation of
    the tool (rotation about the base z axis), for chains whose revolute axes
    are all parallel to base z.  ``phi`` is derived as the exact linear form
    ``phi0 + sum(s_i q_i)`` with ``s_i = z_i . e_z = +-1``, and checked against
    the rotation block: ``R(q) = Rz(phi - phi0) R(0)``.
    """
    names: list[str] = []
    values: list[sp.Expr] = []
    for item in spec:
        if item in ("x", "y", "z"):
            names.append(item)
            values.append(fk["xyz".index(item), 3])
        elif item == "pose":
            names.extend(POSE_NAMES)
            values.extend([fk[0, 3], fk[1, 3], fk[2, 3]] + [fk[r, c] for r in range(3) for c in range(3)])
        elif item == "phi":
            names.append(item)
            values.append(_planar_orientation(chain, q, fk, link_frames))
        elif item == "approach":
            names.extend(APPROACH_NAMES)
            values.extend([fk[0, 2], fk[1, 2], fk[2, 2]])
        elif item in ("pitch", "roll"):
            names.append(item)
            values.append(joint_angle_task(item, chain, q))
        else:
            raise ValueError(f"unknown task coordinate {item!r} (expected {TASK_ITEMS_TEXT})")
    if len(set(names)) != len(names):
        raise ValueError(f"task coordinates repeat a name: {names}")
    return names, sp.Matrix(values)


def _planar_orientation(chain: Chain, q, fk: sp.Matrix, link_frames) -> sp.Expr:
    phi = sp.S.Zero
    for joint, qi, (axis, _) in zip(chain.joints, q, chain.joint_axes(link_frames)):
        if joint.type != REVOLUTE:
            continue
        if axis[0] != 0 or axis[1] != 0 or axis[2] not in (1, -1):
            raise TaskError("task coordinate 'phi' needs every revolute axis parallel to the base z axis")
        phi += axis[2] * qi
    rot0 = fk[:3, :3].subs({qi: 0 for qi in q})
    phi0 = sp.atan2(sp.nsimplify(rot0[1, 0]), sp.nsimplify(rot0[0, 0]))
    if rot0[0, 0] == 0 and rot0[1, 0] == 0:
        phi0 = sp.atan2(-rot0[0, 1], rot0[1, 1])
    angle = phi
    rz = sp.Matrix([[sp.cos(angle), -sp.sin(angle), 0], [sp.sin(angle), sp.cos(angle), 0], [0, 0, 1]])
    residual = (rz * rot0 - fk[:3, :3]).applyfunc(simplify_entry)
    if residual != sp.zeros(3, 3):
        raise TaskError("task coordinate 'phi': the tool rotation is not a rotation about the base z axis")
    return phi + phi0


def build_chain_model(name: str, title: str, source: str, chain: Chain, q, params: dict,
                      task_spec: Sequence[str], limits) -> RobotModel:
    """Derive every kinematic quantity of a chain (the slow symbolic step).

    An exact chain whose frames stay short gets them expanded and simplified (every paper's
    robot, the UR and KUKA arms); any other (a number as a file wrote it, seven joints, frames
    that do not cancel) gets its kinematics as a straight-line program
    (:mod:`derivations.chain_program`), whose size grows with the chain, not with its expansion.
    """
    link_frames = explicit_pays(chain, q)
    if link_frames is None:
        return _program_model(name, title, source, chain, q, params, task_spec, limits)
    tool = chain.tool
    frames = list(link_frames)
    if tool != sp.eye(4):  # the flange frame stays; the tool frame follows it
        frames.append((frames[-1] * tool).applyfunc(simplify_product))
    fk = frames[-1]
    jacobian = chain.geometric_jacobian(link_frames, fk[:3, 3], q)
    task_names, task = task_coordinates(task_spec, chain, q, fk, link_frames)
    task_jacobian = sp.Matrix(len(task), len(q),
                              lambda i, j: simplify_derivative(derivative(task[i], q[j])))
    return RobotModel(
        name=name, title=title, source=source,
        joint_types=tuple(j.type for j in chain.joints), q=tuple(q), params=dict(params),
        frames=frames, jacobian=jacobian, task_names=tuple(task_names), task=task,
        task_jacobian=task_jacobian, limits=tuple(limits), chain=chain,
    )


def _program_model(name, title, source, chain: Chain, q, params, task_spec, limits) -> RobotModel:
    derived = program_kinematics(chain, q, {str(s) for s in params})
    program, frames, jacobian = derived["program"], derived["frames"], derived["jacobian"]
    fk = frames[-1]
    task_names, values = [], []
    for item in task_spec:
        if item == "phi":  # a planar arm's angle, read off its explicit frames (a few joints)
            link_frames = chain.link_frames(q)
            explicit_fk = (link_frames[-1] * chain.tool).applyfunc(simplify_product)
            task_names.append(item)
            values.append(_planar_orientation(chain, q, explicit_fk, link_frames))
        else:
            names, entries = task_coordinates([item], chain, q, fk, None)
            task_names.extend(names)
            values.extend(entries)
    if len(set(task_names)) != len(task_names):
        raise ValueError(f"task coordinates repeat a name: {task_names}")
    task = sp.Matrix(values)
    joint_types = tuple(j.type for j in chain.joints)
    task_jacobian = program_task_jacobian(program, task_names, task, jacobian, fk, derived["axes"], joint_types,
                                          q, derived["coupled"])
    return RobotModel(
        name=name, title=title, source=source, joint_types=joint_types, q=tuple(q), params=dict(params),
        frames=frames, jacobian=jacobian, task_names=tuple(task_names), task=task,
        task_jacobian=task_jacobian, limits=tuple(limits), chain=chain, program=tuple(program.steps),
    )

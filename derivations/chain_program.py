"""The kinematics of a general chain as a straight-line program (:mod:`derivations.program`).

Frames are products of link transforms, one link at a time: ``T_i = T_{i-1} A_i``, each
entry a step of three products; a URDF joint splits its link into its fixed origin and its
motion, ``T_i = (T_{i-1} O_i) M_i(q_i)``, so that the joint's own frame ``T_{i-1} O_i``
(where its axis lies) is a frame of the program too.  The geometric Jacobian's columns read
those frames, ``[z x (p - o); z]`` for a revolute joint and ``[z; 0]`` for a prismatic one,
and the task Jacobian of the pose reads the geometric one: ``dp/dq_j`` is its linear part and
``dR/dq_j = [z_j]x R``.  Where a joint also moves a fixed transform (a URDF mimic joint),
both Jacobians come from the program's own derivatives instead.

Nothing is expanded or simplified here: the steps are as the products write them, and the
common subexpression pass of code generation works on the program.  :func:`explicit_pays`
says when the expanded and simplified form of :mod:`derivations.chain` is the better one (an
exact arm whose products cancel to short entries, as every paper's robot is).
"""
from __future__ import annotations

import sympy as sp

from .chain import PRISMATIC, REVOLUTE, Chain, axis_motion, simplify_product
from .program import Program

__all__ = ["explicit_pays", "program_kinematics", "EXPLICIT_MAX_TERMS", "EXPLICIT_MAX_JOINTS"]

# The expanded, simplified form is kept while every entry of every frame has at most this many
# terms: the zoo's exact six-joint arms have at most 7 in their tool frame (a UR5 6, a KR5 6,
# an LR Mate 7); the Kinova Jaco's 60-degree twists give 22, and its rates and common
# subexpressions then took 10 s, where its program takes a fraction of that.
EXPLICIT_MAX_TERMS = 12
# Seven joints and more always take the program: the expanded Panda spent 16 s in its rates and
# their common subexpressions, kernels of up to 5,900 operations that then took a minute to compile.
EXPLICIT_MAX_JOINTS = 6


def _constants(chain: Chain):
    for joint in chain.joints:
        yield from (joint.a, joint.alpha, joint.d, joint.theta, joint.offset)
        for matrix in (joint.origin, joint.after):
            if matrix is not None:
                yield from matrix
        if joint.axis is not None:
            yield from joint.axis
    yield from chain.base
    yield from chain.tool


def has_floats(chain: Chain) -> bool:
    """Whether the chain holds a floating-point constant (a number as a file wrote it, not exact)."""
    return any(sp.sympify(c).has(sp.Float) for c in _constants(chain))


def explicit_pays(chain: Chain, q) -> list[sp.Matrix] | None:
    """The expanded, simplified frames of ``chain`` where that form pays, else None.

    It pays for an exact chain of at most :data:`EXPLICIT_MAX_JOINTS` joints whose frames stay
    short (at most :data:`EXPLICIT_MAX_TERMS` terms an entry): there the products cancel, and the
    expanded entries are what the papers print.  The frames are built link by link and the
    attempt stops at the first frame past the bound, so it costs no more than short frames do.
    """
    if chain.n > EXPLICIT_MAX_JOINTS or has_floats(chain):
        return None
    frames = [sp.Matrix(chain.base)]
    for i in range(chain.n):
        product = (frames[-1] * chain.link_transform(i, q[i])).applyfunc(simplify_product)
        if max(len(sp.Add.make_args(e)) for e in product) > EXPLICIT_MAX_TERMS:
            return None
        frames.append(product)
    return frames


def _product(program: Program, A, B, name: str) -> sp.Matrix:
    """``A B`` of two rigid transforms (last row 0 0 0 1), each entry of the top three rows a step."""
    out = sp.eye(4)
    for r in range(3):
        for c in range(4):
            entry = sp.Add(*[A[r, m] * B[m, c] for m in range(3)])
            if c == 3:
                entry += A[r, 3]
            out[r, c] = program.define(f"{name}_{r}{c}", entry)
    return out


def _cross(a, b) -> list:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def program_kinematics(chain: Chain, q, taken) -> dict:
    """Frames, joint axes and the geometric Jacobian of ``chain`` as a program.

    Returns ``program`` (the :class:`Program`), ``frames`` ([T_0 .. T_n], then the tool frame),
    ``jacobian`` (6 x n) and ``coupled`` (a joint also moves a fixed transform).  ``taken`` are
    the names the steps must not take (the parameters)."""
    program = Program(taken=set(taken) | {str(s) for s in q})
    T = sp.Matrix(chain.base)
    frames = [T]
    axes = []  # per joint: (unit axis z, point o), world frame
    for i, joint in enumerate(chain.joints):
        k = i + 1
        if chain.convention == "urdf":
            frame = _product(program, T, joint.origin, f"_jf{k}")
            z = [program.define(f"_ax{k}_{r}", sum((frame[r, m] * joint.axis[m] for m in range(3)), sp.S.Zero))
                 for r in range(3)]
            axes.append((z, [frame[r, 3] for r in range(3)]))
            motion = axis_motion(joint.type, joint.axis, q[i] + joint.offset)
            T = _product(program, frame, motion, f"_fr{k}" if joint.after is None else f"_mv{k}")
            if joint.after is not None:
                T = _product(program, T, joint.after, f"_fr{k}")
        else:
            before = T
            T = _product(program, T, chain.link_transform(i, q[i]), f"_fr{k}")
            frame = before if chain.convention == "standard" else T
            axes.append(([frame[r, 2] for r in range(3)], [frame[r, 3] for r in range(3)]))
        frames.append(T)
    if chain.tool != sp.eye(4):
        frames.append(_product(program, T, chain.tool, "_tool"))
    fk = frames[-1]
    p = [fk[r, 3] for r in range(3)]
    coupled = chain.coupled(q)
    columns = []
    for j, (joint, (z, o)) in enumerate(zip(chain.joints, axes)):
        if coupled:
            R = fk[:3, :3]
            dR = R.applyfunc(lambda e: program.derivative(e, q[j]))
            spin = dR * R.T  # [w]x = dR/dq R^T
            column = [program.derivative(e, q[j]) for e in p] + [spin[2, 1], spin[0, 2], spin[1, 0]]
        elif joint.type == REVOLUTE:
            column = _cross(z, [pe - oe for pe, oe in zip(p, o)]) + list(z)
        else:
            column = list(z) + [0, 0, 0]
        columns.append([program.define(f"_jac{r}_{j + 1}", e) for r, e in enumerate(column)])
    jacobian = sp.Matrix(6, chain.n, lambda r, c: columns[c][r])
    return {"program": program, "frames": frames, "jacobian": jacobian, "axes": axes, "coupled": coupled}


def task_jacobian(program: Program, task_names, task, jacobian, fk, axes, joint_types, q, coupled) -> sp.Matrix:
    """``d task / d q`` in the program: the pose's rows from the geometric Jacobian (``dp/dq_j`` its
    linear part, ``dR/dq_j = [z_j]x R``), other coordinates (and a coupled chain's) by the
    program's derivatives."""
    position = {"x": 0, "y": 1, "z": 2}
    rows = []
    for name, value in zip(task_names, task):
        row = []
        for j, qj in enumerate(q):
            if coupled or name in ("phi", "pitch", "roll"):
                entry = program.derivative(value, qj)
            elif name in position:
                entry = jacobian[position[name], j]
            else:  # r_ab (a_x = r13 ...): (z_j x R[:, b])_a for a revolute joint; a prismatic one turns nothing
                a, b = (int(name[1]) - 1, int(name[2]) - 1) if name[0] == "r" else ("xyz".index(name[1]), 2)
                z = axes[j][0]
                entry = (_cross(z, [fk[r, b] for r in range(3)])[a] if joint_types[j] == REVOLUTE
                         else sp.S.Zero)
            row.append(program.define(f"_jx{len(rows) + 1}_{j + 1}", entry))
        rows.append(row)
    return sp.Matrix(rows)


__all__ += ["has_floats", "task_jacobian", "PRISMATIC"]

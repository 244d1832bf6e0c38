"""Equations of motion of a serial chain: recursive Newton-Euler as a straight-line program.

``M(q) qdd + C(q, qd) qd + g(q) = tau`` for an arm whose links carry inertial parameters
(:mod:`derivations.inertia`).  Everything is derived from one recursion, the recursive
Newton-Euler algorithm of Luh, Walker and Paul ("On-line computational scheme for mechanical
manipulators", 1980) in the link frames, as Craig writes it ("Introduction to Robotics", 3rd ed.,
Eqs. 6.45-6.53), with each link's parameters taken about its frame's origin (mass ``m``, first
moment ``h = m c``, inertia ``I_o`` about the origin), the form in which the torques are linear in
the parameters (Atkeson, An and Hollerbach, 1986).  With ``a_0 = -g`` (gravity as an upward
acceleration of the base), for k = 1..n in the frame J_k just after joint k's motion:

    w_k   = R^T w_{k-1} + z qd_k                            (revolute; prismatic: no z term)
    wd_k  = R^T wd_{k-1} + (R^T w_{k-1}) x z qd_k + z qdd_k
    a_k   = R^T (a_{k-1} + wd_{k-1} x p + w_{k-1} x (w_{k-1} x p))  (+ 2 w_k x z qd_k + z qdd_k, prismatic)
    F_k   = m a_k + wd_k x h + w_k x (w_k x h)
    N_k   = I_o wd_k + w_k x I_o w_k + h x a_k

then for k = n..1, with ``R, p`` of joint k+1 (the rotation and the origin of J_{k+1} in J_k):

    f_k = F_k + R f_{k+1},   n_k = N_k + R n_{k+1} + p x R f_{k+1},   tau_k = z . n_k  (z . f_k, prismatic)

Each vector component is a step of a :class:`derivations.program.Program`; nothing is expanded.
The kernels are passes of the same recursion with some inputs zero (the zeros fold away):

* ``inverse_dynamics(q, qd, qdd)``: the whole recursion;
* ``gravity(q)``: qd = qdd = 0; ``coriolis_vector(q, qd)``: qdd = 0 and no gravity;
* ``mass_matrix(q)``: the composite-rigid-body algorithm (:meth:`_Recursion.mass_matrix`), entries
  i <= j, the rest by symmetry;
* ``coriolis(q, qd)``: the Christoffel form ``C_ij = sum_k c_ijk qd_k``, written as
  ``C = (dM/dt + A - A^T) / 2`` with ``A_ij = d(M qd)_i / dq_j``: ``M qd`` is one pass
  (qdd := qd, no velocity, no gravity), ``A`` its derivatives and ``dM/dt`` the time derivative of
  M along qd, both forward-mode derivatives of the program.  ``dM/dt - 2 C = A^T - A`` is skew;
* ``forward_dynamics(q, qd, tau)``: ``M qdd = tau - C qd - g`` solved by the square-root-free
  Cholesky factorisation ``M = L D L^T`` written out as steps (a reciprocal per column);
* ``static_torques(q, wrench)``: ``J^T F``, the joint torques that hold the wrench ``F = [f; n]``
  (base frame, at the tool point) applied by the arm to its environment.

An arm with actuator models (:class:`derivations.inertia.Actuator`, per joint) adds to joint k's
torque ``Ia_k qdd_k + Fv_k qd_k + Fc_k sign(qd_k)``: the armature ``Ia = Ir G^2`` (the rotor reflected
through its gear) is added to M's diagonal, so that ``mass_matrix`` and ``forward_dynamics`` include
it, and the friction is in ``inverse_dynamics`` and in the right-hand side of ``forward_dynamics``
(``tau - C qd - g - F(qd)``).  ``gravity``, ``coriolis`` and ``coriolis_vector`` stay the rigid
bodies' (the armature is constant: it adds nothing to C), and ``sign(0) = 0``: a joint at rest
has no Coulomb friction (no stiction model).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import sympy as sp

from ..chain import REVOLUTE, axis_motion, dh_modified, dh_standard
from ..program import Program

__all__ = ["Dynamics", "dynamics", "derive_dynamics", "DYNAMICS_BUDGET", "link_geometry", "origin_parameters",
           "TAU_PREFIX", "WRENCH_NAMES", "PARAMETER_NAMES", "ACTUATOR_PARAMETER_NAMES", "standard_parameters",
           "actuator_parameters", "parameter_names", "base_parameters", "model_base_parameters",
           "base_combinations"]

# Seconds the equations of motion of one arm may take to derive: the target of issue #30 is 30 s
# cold for a seven-joint arm (the Panda takes about 2 s); past it the arm is generated without them.
DYNAMICS_BUDGET = 60.0
TAU_PREFIX = "tau"
WRENCH_NAMES = ("wrench_fx", "wrench_fy", "wrench_fz", "wrench_nx", "wrench_ny", "wrench_nz")


@dataclass(frozen=True)
class Dynamics:
    """The equations of motion of one arm as a program (``program``) and its kernels."""

    qd: tuple
    qdd: tuple
    tau: tuple
    wrench: tuple
    inverse_dynamics: tuple
    gravity: tuple
    coriolis_vector: tuple
    mass_matrix: sp.Matrix
    coriolis: sp.Matrix
    forward_dynamics: tuple
    program: tuple
    functions: tuple
    note: str = ""  # what the arm lacks (forward_dynamics where M is singular), for model.notes


def _rotation_translation(T):
    T = sp.Matrix(T)
    return T[:3, :3], T[:3, 3]


def link_geometry(chain, k: int):
    """Joint k's link transform split as ``before * motion(q_k) * after`` (each 4 x 4; before and
    after constant): returns (before, axis, after) with the motion about / along ``axis``."""
    j = chain.joints[k]
    if chain.convention == "urdf":
        return sp.Matrix(j.origin), tuple(j.axis), (sp.eye(4) if j.after is None else sp.Matrix(j.after))
    if chain.convention == "standard":  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        if j.type == REVOLUTE:
            return sp.eye(4), (0, 0, 1), dh_standard(0, j.d, j.a, j.alpha)
        return dh_standard(j.theta, 0, 0, 0), (0, 0, 1), dh_standard(0, 0, j.a, j.alpha)
    if j.type == REVOLUTE:  # modified: Rx(alpha) Tx(a) Rz(theta) Tz(d)
        return dh_modified(0, 0, j.a, j.alpha), (0, 0, 1), dh_modified(0, j.d, 0, 0)
    return dh_modified(j.theta, 0, j.a, j.alpha), (0, 0, 1), sp.eye(4)


def origin_parameters(inertial, after: sp.Matrix):
    """A link's parameters in its joint frame J_k about J_k's origin: (m, h, I_o) with ``h = m c``
    and ``I_o = I_c + m (|c|^2 E - c c^T)``; the inertial is given in the link frame k = J_k after."""
    m = sp.sympify(inertial.mass)
    c = sp.Matrix(inertial.com)
    Io = inertial.tensor() + m * ((c.T * c)[0, 0] * sp.eye(3) - c * c.T)
    return to_joint_frame(m, m * c, Io, after)


def to_joint_frame(m, h, Io, after: sp.Matrix):
    """(m, h, I_o) about the link frame's origin, in its axes, moved to J_k (``x_J = R x + p`` by the
    constant ``after``): ``h' = R h + m p``, ``I' = R I R^T + 2 (R h . p) E - R h p^T - p (R h)^T
    + m (|p|^2 E - p p^T)`` (parallel axes), linear in (m, h, I_o)."""
    R, p = _rotation_translation(after)
    Rh = R * sp.Matrix(h)
    I = R * sp.Matrix(Io) * R.T + 2 * (Rh.T * p)[0, 0] * sp.eye(3) - Rh * p.T - p * Rh.T \
        + m * ((p.T * p)[0, 0] * sp.eye(3) - p * p.T)
    return m, (Rh + m * p).applyfunc(sp.expand), I.applyfunc(sp.expand)


# The standard inertial parameters of one link, in the order of the regressor's columns: the mass,
# the first moment m c and the inertia tensor about the link frame's origin, in the link frame k.
PARAMETER_NAMES = ("m", "mx", "my", "mz", "ixx", "ixy", "ixz", "iyy", "iyz", "izz")
# An arm with actuator models has three more per joint, after all the links' (columns 10 n ..):
# the armature Ia = Ir G^2, viscous Fv and Coulomb Fc friction.
ACTUATOR_PARAMETER_NAMES = ("ia", "fv", "fc")


def parameter_names(n: int, actuators: bool = False) -> list[str]:
    """The names of the regressor's columns: ``m1 .. izz1, m2, ..`` then ``ia1, fv1, fc1, ia2, ..``."""
    names = [f"{name}{k + 1}" for k in range(n) for name in PARAMETER_NAMES]
    return names + ([f"{name}{k + 1}" for k in range(n) for name in ACTUATOR_PARAMETER_NAMES] if actuators else [])


def actuator_parameters(actuators, n: int) -> tuple:
    """(Ia_k, Fv_k, Fc_k) for k = 1..n as expressions (zeros for a joint without an actuator)."""
    from .inertia import Actuator
    return tuple(e for a in (actuators or [None] * n) for e in (a or Actuator()).parameters())


def standard_parameters(inertial) -> tuple:
    """A link's ten standard parameters (:data:`PARAMETER_NAMES`) as expressions."""
    m = sp.sympify(inertial.mass)
    c = sp.Matrix(inertial.com)
    Io = inertial.tensor() + m * ((c.T * c)[0, 0] * sp.eye(3) - c * c.T)
    return (m, *(m * c), Io[0, 0], Io[0, 1], Io[0, 2], Io[1, 1], Io[1, 2], Io[2, 2])


def _unit_body(index: int, after: sp.Matrix):
    """The link whose standard parameter ``index`` is 1 and the others 0, in its joint frame."""
    unit = [sp.S.One if i == index else sp.S.Zero for i in range(10)]
    m, h = unit[0], sp.Matrix(unit[1:4])
    xx, xy, xz, yy, yz, zz = unit[4:]
    return to_joint_frame(m, h, sp.Matrix([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]), after)


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


class _Recursion:
    """The Newton-Euler recursion of one chain, run as passes into one program."""

    def __init__(self, model, program: Program):
        chain = model.chain
        self.program = program
        self.n = chain.n
        self.types = [j.type for j in chain.joints]
        self.offsets = [j.offset for j in chain.joints]
        self.axes, self.constant, self.bodies, self.afters = [], [], [], []
        previous_after = sp.Matrix(chain.base)
        for k in range(self.n):
            before, axis, after = link_geometry(chain, k)
            self.constant.append(_rotation_translation(previous_after * before))  # J_{k-1} -> before motion
            self.axes.append(sp.Matrix(axis))
            self.bodies.append(origin_parameters(model.inertials[k], after))
            self.afters.append(after)
            previous_after = after
        self.q = model.q
        self.gravity = sp.Matrix(model.gravity)
        self._motion = {}

    def define_vector(self, name: str, vector) -> list:
        return [self.program.define(f"{name}_{i}", e) for i, e in enumerate(vector)]

    def motion(self, k: int):
        """(Rm, tm) of joint k's motion: rotation and translation (J_k in the frame before it)."""
        if k not in self._motion:
            M = axis_motion(self.types[k], list(self.axes[k]), self.q[k] + self.offsets[k])
            self._motion[k] = _rotation_translation(M)
        return self._motion[k]

    def to_child(self, k: int, x, name: str):
        """R_k^T x: a vector of J_{k-1} in J_k (the constant rotation, then the motion's)."""
        Rc, _ = self.constant[k]
        Rm, _ = self.motion(k)
        if any(e != 0 for e in x):
            y = self.define_vector(f"{name}c", list(Rc.T * sp.Matrix(x)))
            return self.define_vector(name, list(Rm.T * sp.Matrix(y)))
        return [sp.S.Zero] * 3

    def to_parent(self, k: int, x, name: str):
        """R_k x: a vector of J_k in J_{k-1}."""
        Rc, _ = self.constant[k]
        Rm, _ = self.motion(k)
        if any(e != 0 for e in x):
            y = self.define_vector(f"{name}m", list(Rm * sp.Matrix(x)))
            return self.define_vector(name, list(Rc * sp.Matrix(y)))
        return [sp.S.Zero] * 3

    def origin(self, k: int):
        """p_k: the origin of J_k in J_{k-1} (moves with a prismatic joint)."""
        Rc, pc = self.constant[k]
        _, tm = self.motion(k)
        return list(pc + Rc * tm)

    def torques(self, tag: str, qd, qdd, gravity: bool, bodies=None) -> list:
        """tau of the pass ``tag`` (names its steps) at joint rates ``qd``, accelerations ``qdd``
        (expressions or numbers), with or without gravity; ``bodies`` replaces the links' (m, h, I_o)."""
        bodies = self.bodies if bodies is None else bodies
        motion = self.forward(tag, qd, qdd, gravity)
        wrenches = [self.link_wrench(tag, k, bodies[k], *motion[k]) for k in range(self.n)]
        return self.backward(tag, wrenches)

    def forward(self, tag: str, qd, qdd, gravity: bool) -> list:
        """The forward recursion of the pass ``tag``: (w_k, wd_k, a_k) of each link k in J_k."""
        n = self.n
        zero = [sp.S.Zero] * 3
        w, wd = zero, zero
        a = [-e for e in self.gravity] if gravity else zero
        motion = []
        for k in range(n):
            z = list(self.axes[k])
            p = self.origin(k)
            base = [a[i] + e for i, e in enumerate(_add(_cross(wd, p), _cross(w, _cross(w, p))))]
            base = self.define_vector(f"_{tag}b{k + 1}", base)
            a_k = self.to_child(k, base, f"_{tag}a{k + 1}")
            w_in = self.to_child(k, w, f"_{tag}wp{k + 1}")
            wd_in = self.to_child(k, wd, f"_{tag}wdp{k + 1}")
            zqd = [e * qd[k] for e in z]
            zqdd = [e * qdd[k] for e in z]
            if self.types[k] == REVOLUTE:
                w_k = _add(w_in, zqd)
                wd_k = _add(_add(wd_in, _cross(w_in, zqd)), zqdd)
            else:
                w_k, wd_k = w_in, wd_in
                a_k = _add(_add(a_k, [2 * e for e in _cross(w_in, zqd)]), zqdd)
            w_k = self.define_vector(f"_{tag}w{k + 1}", w_k)
            wd_k = self.define_vector(f"_{tag}wd{k + 1}", wd_k)
            a_k = self.define_vector(f"_{tag}ac{k + 1}", a_k)
            motion.append((w_k, wd_k, a_k))
            w, wd, a = w_k, wd_k, a_k
        return motion

    def link_wrench(self, tag: str, k: int, body, w_k, wd_k, a_k):
        """(F_k, N_k): the force and the moment about J_k's origin that link k's motion takes, for
        its parameters ``body`` = (m, h, I_o)."""
        m, h, Io = body
        F = _add(_add([m * e for e in a_k], _cross(wd_k, h)), _cross(w_k, _cross(w_k, h)))
        Iw = list(Io * sp.Matrix(w_k))
        N = _add(_add(list(Io * sp.Matrix(wd_k)), _cross(w_k, Iw)), _cross(h, a_k))
        return self.define_vector(f"_{tag}F{k + 1}", F), self.define_vector(f"_{tag}N{k + 1}", N)

    def backward(self, tag: str, wrenches: list) -> list:
        """tau from the links' wrenches (F_k, N_k), each carried down to the base: links past the
        last one in ``wrenches`` carry none (their torques are zero)."""
        tau = [sp.S.Zero] * self.n
        f, nn = [sp.S.Zero] * 3, [sp.S.Zero] * 3
        top = len(wrenches) - 1
        for k in reversed(range(top + 1)):
            F, N = wrenches[k]
            if k < top:
                Rf = self.to_parent(k + 1, f, f"_{tag}Rf{k + 2}")
                Rn = self.to_parent(k + 1, nn, f"_{tag}Rn{k + 2}")
                p = self.origin(k + 1)
                f = _add(F, Rf)
                nn = _add(_add(N, Rn), _cross(p, Rf))
            else:
                f, nn = F, N
            f = self.define_vector(f"_{tag}f{k + 1}", f)
            nn = self.define_vector(f"_{tag}n{k + 1}", nn)
            z = list(self.axes[k])
            moment = nn if self.types[k] == REVOLUTE else f
            tau[k] = self.program.define(f"_{tag}tau{k + 1}", sum((zi * mi for zi, mi in zip(z, moment)), sp.S.Zero))
        return tau

    def rotate_tensor(self, k: int, tensor: sp.Matrix, name: str) -> sp.Matrix:
        """R_k I R_k^T: a tensor of J_k in the axes of J_{k-1} (the motion's rotation, then the constant one)."""
        Rc, _ = self.constant[k]
        Rm, _ = self.motion(k)
        inner = self.define_tensor(f"{name}m", Rm * tensor * Rm.T)
        return self.define_tensor(name, Rc * inner * Rc.T)

    def define_tensor(self, name: str, tensor: sp.Matrix) -> sp.Matrix:
        """A symmetric 3 x 3 matrix, its six distinct entries each a step."""
        out = sp.zeros(3, 3)
        for r in range(3):
            for c in range(r, 3):
                out[r, c] = out[c, r] = self.program.define(f"{name}_{r}{c}", tensor[r, c])
        return out

    def mass_matrix(self) -> sp.Matrix:
        """M(q) by the composite-rigid-body algorithm (Walker and Orin, 1982; Featherstone, "Rigid Body
        Dynamics Algorithms", Sec. 6.2), in the joint frames: the composite body k (links k..n, rigid
        at qd = 0) has mass ``m^c_k``, first moment ``h^c_k`` and inertia ``I^c_k`` about J_k's origin,

            m^c_k = m_k + m^c_{k+1},   h^c_k = h_k + R h^c_{k+1} + m^c_{k+1} p,
            I^c_k = I_k + R I^c_{k+1} R^T + 2 (R h^c_{k+1} . p) E - R h^c_{k+1} p^T - p (R h^c_{k+1})^T
                    + m^c_{k+1} (|p|^2 E - p p^T)

        (R, p: joint k+1's rotation and origin in J_k; the parallel-axis theorem for a body off the
        origin).  A unit acceleration of joint j moves composite j rigidly: about a revolute axis z it
        takes the force ``f = z x h^c_j`` and moment ``n = I^c_j z``, along a prismatic one
        ``f = m^c_j z``, ``n = h^c_j x z``; M_jj is that force's component along z, and M_ij (i < j)
        the same force carried down to joint i as the backward recursion carries it."""
        n = self.n
        composite = [None] * n
        for k in reversed(range(n)):
            m, h, I = self.bodies[k]
            if k + 1 < n:
                mc, hc, Ic = composite[k + 1]
                Rh = sp.Matrix(self.to_parent(k + 1, list(hc), f"_crRh{k + 2}"))
                RIR = self.rotate_tensor(k + 1, Ic, f"_crRI{k + 2}")
                p = sp.Matrix(self.origin(k + 1))
                dot = (Rh.T * p)[0, 0]
                m = self.program.define(f"_crm{k + 1}", m + mc)
                h = h + Rh + mc * p
                I = I + RIR + 2 * dot * sp.eye(3) - Rh * p.T - p * Rh.T + mc * ((p.T * p)[0, 0] * sp.eye(3) - p * p.T)
            composite[k] = (m, sp.Matrix(self.define_vector(f"_crh{k + 1}", list(h))),
                            self.define_tensor(f"_crI{k + 1}", I))
        M = sp.zeros(n, n)
        for j in range(n):
            m, h, I = composite[j]
            z = self.axes[j]
            if self.types[j] == REVOLUTE:
                f, moment = _cross(list(z), list(h)), list(I * z)
            else:
                f, moment = [m * e for e in z], _cross(list(h), list(z))
            f = self.define_vector(f"_crf{j + 1}_{j + 1}", f)
            moment = self.define_vector(f"_crn{j + 1}_{j + 1}", moment)
            for i in reversed(range(j + 1)):
                if i < j:
                    Rf = self.to_parent(i + 1, f, f"_crRf{i + 2}_{j + 1}")
                    Rn = self.to_parent(i + 1, moment, f"_crRn{i + 2}_{j + 1}")
                    f = self.define_vector(f"_crf{i + 1}_{j + 1}", Rf)
                    moment = self.define_vector(f"_crn{i + 1}_{j + 1}", _add(Rn, _cross(self.origin(i + 1), Rf)))
                along = moment if self.types[i] == REVOLUTE else f
                M[i, j] = M[j, i] = self.program.define(
                    f"_M{j + 1}_{i + 1}", sum((a * b for a, b in zip(self.axes[i], along)), sp.S.Zero))
        return M


def regressor(recursion: "_Recursion", qd, qdd, actuators: bool = False) -> sp.Matrix:
    """Y(q, qd, qdd), n x 10n, with ``tau = Y pi`` for the standard parameters ``pi`` (ten per link,
    :data:`PARAMETER_NAMES`, link frame k): column (k, i) is the Newton-Euler pass in which link k
    alone has parameter i equal to 1 (the torques are linear in the parameters; Atkeson, An and
    Hollerbach, 1986).  Its velocities are the inverse dynamics' own steps; only the links at and
    below k carry its force.  With ``actuators``, 3n more columns (:data:`ACTUATOR_PARAMETER_NAMES`):
    joint k's (Ia, Fv, Fc) act on tau_k alone as ``qdd_k``, ``qd_k`` and ``sign(qd_k)``."""
    n = recursion.n
    zero = ([sp.S.Zero] * 3, [sp.S.Zero] * 3)
    motion = recursion.forward("id", qd, qdd, True)  # the inverse dynamics' own steps
    columns = []
    for k in range(n):
        for i, name in enumerate(PARAMETER_NAMES):
            tag = f"y{k + 1}{name}_"
            # link k's wrench for parameter i alone, carried down to the base: the links before it
            # carry it and add none, the links past it move none of it
            wrench = recursion.link_wrench(tag, k, _unit_body(i, recursion.afters[k]), *motion[k])
            columns.append(recursion.backward(tag, [zero] * k + [wrench]))
    if actuators:
        for k in range(n):
            for factor in (qdd[k], qd[k], sp.sign(qd[k])):
                columns.append([factor if r == k else sp.S.Zero for r in range(n)])
    return sp.Matrix(n, len(columns), lambda r, c: columns[c][r])


def base_parameters(regressor, n: int, limits=None, samples: int = 40, seed: int = 0, tolerance: float = 1e-9):
    """The base (identifiable) parameters of an arm, by a numeric QR of its regressor at random states
    (Gautier, "Numerical calculation of the base inertial parameters of robots", 1991).

    ``regressor(q, qd, qdd)`` is the package's kernel (batched).  The columns of the stacked
    regressor W are taken from the last back, each kept when it adds to the rank (its residual after projection
    on the kept ones, from a QR, is past ``tolerance`` of the largest column); the others are
    combinations ``W_d = W_b K`` of the kept ones.  Returns (base, K, names): the indices of the kept
    columns, K (kept x dropped, with the dropped indices) and the parameter names, so that
    ``beta = pi_b + K pi_d`` (:func:`base_combinations` prints it) gives ``tau = W_b beta``."""
    import numpy as np
    rng = np.random.default_rng(seed)
    low = np.array([lim[0] if lim else -np.pi for lim in (limits or [None] * n)])
    high = np.array([lim[1] if lim else np.pi for lim in (limits or [None] * n)])
    q = rng.uniform(low, high, (samples, n))
    W = np.asarray(regressor(q, rng.uniform(-2, 2, (samples, n)), rng.uniform(-5, 5, (samples, n))))
    W = W.reshape(samples * n, W.shape[-1])  # 10 n columns, or 13 n with the actuators' (parameter_names)
    scale = max(np.linalg.norm(W, axis=0).max(), 1e-300)
    kept: list[int] = []
    # From the last column (the last link's izz) back: a parameter that the torques only see through
    # the motion of the links beyond is regrouped into theirs, the classic grouping (Khalil and
    # Dombre, "Modeling, Identification and Control of Robots", Sec. 12.5: the masses into the inertias).
    for column in reversed(range(W.shape[1])):
        trial = W[:, kept + [column]]
        r = np.linalg.qr(trial, mode="r")
        if abs(r[-1, -1]) > tolerance * scale:
            kept.append(column)
    kept.sort()
    dropped = [c for c in range(W.shape[1]) if c not in kept]
    K = np.linalg.lstsq(W[:, kept], W[:, dropped], rcond=None)[0] if dropped else np.zeros((len(kept), 0))
    names = parameter_names(n, actuators=W.shape[1] == 13 * n)
    return kept, dropped, K, names


def model_base_parameters(model, samples: int = 40, seed: int = 0):
    """:func:`base_parameters` of ``model``'s regressor at its parameters' defaults, the program
    evaluated in double precision (:func:`derivations.program.evaluate_arrays`): no generated
    kernel needed.  None for an arm without dynamics."""
    import numpy as np

    from ..program import evaluate_arrays
    dynamics = model.dynamics
    if dynamics is None:
        return None
    (function,) = [f for f in dynamics.functions if f.name == "regressor"]
    Y = function.outputs[0].values
    defaults = {s: float(v) for s, v in model.params.items()}
    n = model.n

    def regressor(q, qd, qdd):
        point = dict(defaults)
        point.update({s: q[:, k] for k, s in enumerate(model.q)})
        point.update({s: qd[:, k] for k, s in enumerate(dynamics.qd)})
        point.update({s: qdd[:, k] for k, s in enumerate(dynamics.qdd)})
        with np.errstate(all="ignore"):
            values = evaluate_arrays(function.definitions, list(Y), point)
        return np.stack([np.broadcast_to(v, (len(q),)) for v in values], axis=-1).reshape(len(q), n, len(Y) // n)
    return base_parameters(regressor, n, model.limits, samples=samples, seed=seed)


# A coefficient of K smaller than this is the least-squares fit's rounding, not a term.
COMBINATION_NOISE = 1e-10


def base_terms(kept, dropped, K, row: int) -> list[tuple[float, int]]:
    """The terms (coefficient, standard parameter index) of base parameter ``row``: its own with 1,
    then each dropped one whose coefficient is past :data:`COMBINATION_NOISE`."""
    return [(1.0, kept[row])] + [(float(K[row, j]), d) for j, d in enumerate(dropped)
                                 if abs(K[row, j]) > COMBINATION_NOISE]


def base_combinations(kept, dropped, K, names, digits: int = 6) -> list[str]:
    """Each base parameter as its combination of the standard ones, each coefficient to ``digits``
    significant digits: ``iyy2 + 0.25 m3 - ...``."""
    lines = []
    for row in range(len(kept)):
        (_, own), *rest = base_terms(kept, dropped, K, row)
        terms = [names[own]]
        for c, d in rest:
            sign = "-" if c < 0 else "+"
            terms.append(f"{sign} {names[d]}" if f"{abs(c):.{digits}g}" == "1" else f"{sign} {abs(c):.{digits}g} {names[d]}")
        lines.append(" ".join(terms))
    return lines


def _add(a, b):
    return [x + y for x, y in zip(a, b)]


def rate_symbols(prefix: str, n: int):
    return tuple(sp.Symbol(f"{prefix}{i + 1}", real=True) for i in range(n))


def derive_dynamics(model) -> Dynamics:
    """The equations of motion of ``model`` (which has ``inertials`` and ``gravity``) as a program."""
    from ..support.budget import stage
    from ..model import Argument, Output, SymbolicFunction, with_program
    n = model.n
    qd, qdd, tau = rate_symbols("qd", n), rate_symbols("qdd", n), rate_symbols(TAU_PREFIX, n)
    wrench = tuple(sp.Symbol(name, real=True) for name in WRENCH_NAMES)
    taken = {str(s) for s in model.params} | {str(s) for s in (*model.q, *qd, *qdd, *tau, *wrench)}
    taken |= {str(s) for s, _ in model.program}
    program = Program(taken=taken)
    recursion = _Recursion(model, program)
    zeros = [sp.S.Zero] * n
    with stage("deriving the equations of motion: Newton-Euler passes"):
        inverse = recursion.torques("id", qd, qdd, True)
        gravity = recursion.torques("g", zeros, zeros, True)
        bias_c = recursion.torques("c", qd, zeros, False)
        bias = recursion.torques("h", qd, zeros, True)  # C qd + g, for the forward dynamics
    with stage("deriving the equations of motion: the composite-rigid-body mass matrix"):
        M = recursion.mass_matrix()
    with stage("deriving the equations of motion: the Christoffel form of C"):
        momentum = recursion.torques("p", zeros, qd, False)  # M qd
        along = dict(zip(model.q, qd))
        M_dot = sp.Matrix(n, n, lambda i, j: program.time_derivative(M[i, j], along) if i >= j else 0)
        M_dot = sp.Matrix(n, n, lambda i, j: M_dot[max(i, j), min(i, j)])
        A = sp.Matrix(n, n, lambda i, j: program.derivative(momentum[i], model.q[j]))
        C = sp.Matrix(n, n, lambda i, j: program.define(f"_C{i + 1}_{j + 1}", (M_dot[i, j] + A[i, j] - A[j, i]) / 2))
    actuators = tuple(getattr(model, "actuators", ()) or ())
    friction = [sp.S.Zero] * n
    if actuators:  # Ia qdd + Fv qd + Fc sign(qd) on each joint; the armature on M's diagonal (after C: constant)
        parameters = actuator_parameters(actuators, n)
        for k in range(n):
            armature, viscous, coulomb = parameters[3 * k:3 * k + 3]
            friction[k] = viscous * qd[k] + coulomb * sp.sign(qd[k])
            if friction[k] != 0:
                friction[k] = program.define(f"_fr{k + 1}", friction[k])
            if armature != 0 or friction[k] != 0:
                inverse[k] = program.define(f"_idat{k + 1}", inverse[k] + armature * qdd[k] + friction[k])
            if armature != 0:
                M[k, k] = program.define(f"_Ma{k + 1}_{k + 1}", M[k, k] + armature)
    singular = singular_mass_matrix(model, program, M)
    if singular is None:
        with stage("deriving the equations of motion: Cholesky solve of M"):
            qdd_solved = _cholesky_solve(program, M, [t - b - f for t, b, f in zip(tau, bias, friction)])
    else:  # no forward dynamics: the note says why
        qdd_solved = ()
    with stage("deriving the equations of motion: the regressor"):
        Y = regressor(recursion, qd, qdd, actuators=bool(actuators))
    J = model.jacobian
    static = [sum((J[r, k] * wrench[r] for r in range(6)), sp.S.Zero) for k in range(n)]

    units = ", ".join(f"{s}: {'N m' if t == REVOLUTE else 'N'}" for s, t in zip(tau, model.joint_types))
    qa = Argument("q", tuple(model.q), f"joint coordinates, shape (..., {n})")
    qda = Argument("qd", qd, f"joint rates, shape (..., {n}) (per second)")
    qdda = Argument("qdd", qdd, f"joint accelerations, shape (..., {n}) (per second squared)")
    taua = Argument("tau", tau, f"joint torques and forces, shape (..., {n}) ({units})")
    wrencha = Argument("wrench", wrench, "wrench [f; n] the tool applies, base frame, at the tool point, "
                                         "shape (..., 6) (N, N m)")
    g_text = ", ".join(str(e) for e in model.gravity)
    driven = (" + F(qd), with F_k = Fv_k qd_k + Fc_k sign(qd_k) the joints' friction (sign(0) = 0)"
              if any(f != 0 for f in friction) else "")
    armature = " (with the actuators' armature Ia = Ir G^2 on the diagonal)" if actuators and any(
        a is not None and a.armature != 0 for a in actuators) else ""
    columns = Y.cols
    functions = [
        SymbolicFunction("inverse_dynamics", (qa, qda, qdda), (Output("tau", tuple(inverse), (n,)),),
                         f"Joint torques M(q) qdd + C(q, qd) qd + g(q){driven} (recursive Newton-Euler), "
                         f"shape (..., {n}); gravity ({g_text}) m/s^2 in the base frame."),
        SymbolicFunction("mass_matrix", (qa,), (Output.from_matrix("M", M),),
                         f"Joint-space inertia matrix M(q){armature}, symmetric positive definite, "
                         f"shape (..., {n}, {n})."),
        SymbolicFunction("gravity", (qa,), (Output("g", tuple(gravity), (n,)),),
                         f"Gravity torques g(q), shape (..., {n}); gravity ({g_text}) m/s^2 in the base frame."),
        SymbolicFunction("coriolis", (qa, qda), (Output.from_matrix("C", C),),
                         f"Coriolis matrix C(q, qd) (Christoffel symbols: dM/dt - 2 C is skew), "
                         f"shape (..., {n}, {n})."),
        SymbolicFunction("coriolis_vector", (qa, qda), (Output("c", tuple(bias_c), (n,)),),
                         f"Coriolis and centrifugal torques C(q, qd) qd, shape (..., {n})."),
        SymbolicFunction("regressor", (qa, qda, qdda), (Output.from_matrix("Y", Y),),
                         f"Regressor Y(q, qd, qdd) with tau = Y pi, shape (..., {n}, {columns}): pi holds ten standard "
                         f"parameters per link, (m, m cx, m cy, m cz, ixx, ixy, ixz, iyy, iyz, izz) with the inertia about "
                         f"the origin of the link's frame k, in its axes"
                         + (", then three per joint, (Ia, Fv, Fc): armature, viscous and Coulomb friction." if actuators
                            else ".")),
        SymbolicFunction("forward_dynamics", (qa, qda, taua), (Output("qdd", tuple(qdd_solved), (n,)),),
                         f"Joint accelerations M^-1 (tau - C qd - g{' - F(qd)' if driven else ''}) "
                         f"(Cholesky L D L^T of M), shape (..., {n})."),
    ]
    if singular is not None:
        functions = [f for f in functions if f.name != "forward_dynamics"]
    # the Newton-Euler kernels are programs through and through: their CSE looks for repeated subtrees only
    functions = with_program([replace(f, cse="tree") for f in functions], tuple(program.steps))
    functions += with_program([SymbolicFunction(
        "static_torques", (qa, wrencha), (Output("tau", tuple(static), (n,)),),
        f"Joint torques J(q)^T wrench that hold the wrench [f; n] (base frame, at the tool point), "
        f"shape (..., {n}).")], tuple(model.program))
    return Dynamics(qd, qdd, tau, wrench, tuple(inverse), tuple(gravity), tuple(bias_c), M, C,
                    tuple(qdd_solved), tuple(program.steps), tuple(functions),
                    note="" if singular is None else f"no forward_dynamics: {singular}")


def singular_mass_matrix(model, program: Program, M: sp.Matrix, samples: int = 3) -> str | None:
    """Why M(q) is singular (a joint that moves no mass about its axis: a URDF of point masses on the
    axes, as the Lynxmotion AL5D's), or None where it is positive definite at ``samples`` random
    configurations with the default parameters (a 30-digit evaluation of the program)."""
    import random

    import mpmath

    from ..program import evaluator
    rng = random.Random(30)
    defaults = [mpmath.mpf(repr(float(v))) for v in model.params.values()]
    n = M.rows
    mass_matrix = evaluator(program.steps, list(M), [*model.q, *model.params])
    with mpmath.workdps(30):
        for _ in range(samples):
            q = [mpmath.mpf(repr(rng.uniform(-1.5, 1.5))) for _ in model.q]
            matrix = mpmath.matrix(n, n)
            for index, value in enumerate(mass_matrix(*q, *defaults)):
                matrix[index // n, index % n] = value
            scale = max(abs(v) for v in matrix) or 1
            minors = [mpmath.mpf(1)] + [mpmath.det(matrix[:j + 1, :j + 1]) for j in range(n)]
            for j in range(n):  # the leading minors' ratios: the pivots of M = L D L^T
                if minors[j + 1] <= mpmath.mpf("1e-20") * scale * minors[j]:
                    return (f"the mass matrix is singular: joint {j + 1} ({model.joint_labels[j]}) moves no inertia "
                            "independently of the joints before it (point masses on its axis?)")
    return None


def _cholesky_solve(program: Program, M: sp.Matrix, rhs) -> list:
    """x with ``M x = rhs`` by the square-root-free Cholesky factorisation ``M = L D L^T`` (L unit
    lower triangular; Golub and Van Loan, "Matrix Computations", Algorithm 4.1.2), every entry a step:
    ``D_j = M_jj - sum_k L_jk^2 D_k``, ``L_ij = (M_ij - sum_k L_ik L_jk D_k) / D_j``, then
    ``L y = rhs``, ``L^T x = D^-1 y``, multiplying by the reciprocal of each ``D_j``.  No square root:
    the batched C vectorises it (a square root that may set errno does not)."""
    n = M.rows
    L = [[None] * n for _ in range(n)]
    LD = [[None] * n for _ in range(n)]  # L_ik D_k
    D, inverse = [None] * n, [None] * n
    for j in range(n):
        D[j] = program.define(f"_chD{j + 1}", M[j, j] - sum((L[j][k] * LD[j][k] for k in range(j)), sp.S.Zero))
        inverse[j] = program.define(f"_chI{j + 1}", 1 / D[j])
        for i in range(j + 1, n):
            LD[i][j] = program.define(f"_chLD{i + 1}_{j + 1}",
                                      M[i, j] - sum((LD[i][k] * L[j][k] for k in range(j)), sp.S.Zero))
            L[i][j] = program.define(f"_chL{i + 1}_{j + 1}", LD[i][j] * inverse[j])
    y = [None] * n
    for i in range(n):
        y[i] = program.define(f"_chy{i + 1}", rhs[i] - sum((L[i][k] * y[k] for k in range(i)), sp.S.Zero))
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = program.define(f"_chx{i + 1}", y[i] * inverse[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)),
                                                                     sp.S.Zero))
    return x


def dynamics(model) -> Dynamics | None:
    """The equations of motion of ``model``, derived once (cached on disk) under
    :data:`DYNAMICS_BUDGET`; None for an arm without inertial parameters (or whose budget ran out:
    ``model.notes["dynamics"]`` says so)."""
    if model.chain is None or not getattr(model, "inertials", ()):
        return None
    if "_dynamics" in model.__dict__:
        return model.__dict__["_dynamics"]
    from ..support.budget import BudgetExceeded, budget, degraded
    from ..support.cache import cached
    key = "\n".join([model.name, repr(model.chain), sp.srepr(sp.Tuple(*model.q)),
                     sp.srepr(sp.Tuple(*model.params)), repr(model.inertials), repr(model.gravity),
                     repr(getattr(model, "actuators", ())),
                     sp.srepr(sp.ImmutableMatrix(model.jacobian)), sp.srepr(sp.Tuple(*map(sp.Tuple, model.program)))])
    try:
        with budget(DYNAMICS_BUDGET, f"{model.name}: equations of motion"):
            result = cached(f"dynamics-{model.name}", key.encode(), lambda: derive_dynamics(model))
    except BudgetExceeded as error:
        model.notes["dynamics"] = f"no dynamics kernels: {error}"
        degraded(model.notes["dynamics"])
        result = None
    if result is not None and result.note:
        model.notes["dynamics"] = result.note
    model.__dict__["_dynamics"] = result
    return result

"""The general 6R: every real solution, by Raghavan and Roth's elimination, numerically per pose.

Method: M. Raghavan and B. Roth, "Inverse kinematics of the general 6R manipulator and related
linkages", ASME J. Mech. Design 115 (1993) 502-508; in the numeric form of D. Manocha and
J. F. Canny, "Efficient inverse kinematics for general 6R manipulators", IEEE Trans. Robotics
and Automation 10(5) (1994) 648-657 (Sections III-IV: the coefficient matrices are closed forms
evaluated per pose, the elimination and the roots are numeric linear algebra).

The chain, with every joint revolute about its frame's z axis, is written as

    W = Rz(phi_1) F_1 Rz(phi_2) F_2 Rz(phi_3) F_3 Rz(phi_4) F_4 Rz(phi_5) F_5 Rz(phi_6),

``W = G_0^-1 X (F_6 G_7)^-1`` for the target pose ``X`` (``G_0`` the base and whatever of the
first link precedes its turn, ``G_7`` the tool), ``phi_i = q_i + offset_i - delta_i``, each
``F_i`` constant.  The shifts ``delta_i`` (angles with rational sine and cosine) move the
half-angle tangents' poles (phi = pi) away from the joint values 0, +-pi/2, pi that real
arms sit at; they change nothing else.  Raghavan-Roth's rearrangement (their Eq. 2)

    F_2^-1 Rz(phi_2)^T F_1^-1 Rz(phi_1)^T W = Rz(phi_3) F_3 Rz(phi_4) F_4 Rz(phi_5) F_5 Rz(phi_6)

applied to the origin ``p`` and the z axis ``l`` of the last frame (which ``Rz(phi_6)`` does
not move) gives 6 equations (the same on any rotation of the loop, forwards or backwards: the
loop of :func:`chain_loop`, its links ``E_k``; an arm with parallel or orthogonal axes makes some
loops singular, :func:`choose_loops` takes the first two regular ones); with ``p.p``, ``p.l``, ``p x l`` and ``(p.p) l - 2 (p.l) p``
(their Eq. 6) 14, each of them bilinear in the sines and cosines of joints 1 and 2 on the
left and of joints 4 and 5 on the right, and linear in those of joint 3 (Manocha-Canny Eq. 9):

    P(phi_3) [s4 s5, s4 c5, c4 s5, c4 c5, s4, c4, s5, c5, 1]^T = Q [s1 s2, s1 c2, c1 s2, c1 c2, s1, c1, s2, c2]^T,

``P = P_1 + P_c cos(phi_3) + P_s sin(phi_3)`` (14 x 9) and ``Q`` (14 x 8), every entry a
polynomial in the pose and the parameters.  This module derives those entries (a product
that leaves the bilinear form, which the theory rules out, is refused naming it); the
generated code eliminates joints 1 and 2 with the left null space of ``Q`` (6 equations),
turns the remaining sines and cosines into half-angle tangents (Manocha-Canny Eq. 11-13: a
12 x 12 matrix quadratic in ``x_3 = tan(phi_3 / 2)``), solves it as a 24 x 24 eigenproblem,
reads joints 4 and 5 from each real eigenvector, joints 1 and 2 from the 14 equations,
joint 6 from the pose, and polishes each answer by Newton steps on the chain's own
forward kinematics (a spurious or inaccurate root fails the residual test and is dropped).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import sympy as sp

from ..chain import REVOLUTE
from ..program import Program

__all__ = ["General6R", "general_6r", "NotGeneral6R", "SHIFTS", "MONOMIALS_45", "MONOMIALS_12",
           "fast_equations_function"]

# (cos, sin) of the shift delta_i of each joint: rational points on the unit circle, so the
# derived coefficients stay exact.
SHIFTS = ((sp.Rational(3, 5), sp.Rational(4, 5)), (sp.Rational(5, 13), sp.Rational(12, 13)),
          (sp.Rational(8, 17), sp.Rational(15, 17)), (sp.Rational(7, 25), sp.Rational(24, 25)),
          (sp.Rational(20, 29), sp.Rational(21, 29)), (sp.Rational(12, 37), sp.Rational(35, 37)))

# The monomials of Manocha-Canny Eq. 9, as exponents (c_a, s_a, c_b, s_b) of the two joints.
MONOMIALS_45 = ((0, 1, 0, 1), (0, 1, 1, 0), (1, 0, 0, 1), (1, 0, 1, 0), (0, 1, 0, 0), (1, 0, 0, 0),
                (0, 0, 0, 1), (0, 0, 1, 0), (0, 0, 0, 0))
MONOMIALS_12 = MONOMIALS_45[:8]


class NotGeneral6R(ValueError):
    """The chain is not one this method takes (not six revolute joints)."""


@dataclass(frozen=True)
class General6R:
    """The closed forms of Manocha-Canny Eq. 9 for one arm on one loop.

    ``X``: the 4 x 4 of pose symbols the loop is written in; ``definitions``: (symbol, expression
    in X and the parameters) of the link that holds the pose, then the steps of the program the
    entries of ``P`` and ``Q`` that depend on the pose are written in; ``P`` (3, 14, 9): P_1, P_c, P_s;
    ``Q`` (14, 8); ``E``: the loop's links E_1 .. E_6 (4 x 4); loop joint k is joint
    ``order[k]``, its angle ``signs[k] psi_k = q + offset - delta``; ``loop``: (start, reverse).
    """

    X: sp.Matrix
    definitions: tuple
    P: tuple
    Q: tuple
    E: tuple
    signs: tuple
    order: tuple
    offsets: tuple
    loop: tuple


def _rz(c, s):
    return sp.Matrix([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _tz(d):
    return sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d], [0, 0, 0, 1]])


def _tx(a):
    return sp.Matrix([[1, 0, 0, a], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _rx(alpha):
    c, s = sp.cos(alpha), sp.sin(alpha)
    return sp.Matrix([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def _inverse(T):
    if isinstance(T, _FloatMatrix):
        return _inverse_float(T)
    R, p = T[:3, :3], T[:3, 3]
    out = sp.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T * p
    return out


def link_split(chain):
    """(G_0, [F_1 .. F_6], offsets): the chain as G_0 Rz(q_1 + o_1) F'_1 ... Rz(q_6 + o_6) F'_6 tool
    (standard DH: F'_i = Tz Tx Rx; modified: the next link's Rx Tx moves in front of its turn)."""
    if chain.convention not in ("standard", "modified", "urdf"):
        raise NotGeneral6R(f"a chain of convention {chain.convention!r}")
    if chain.n != 6 or any(j.type != REVOLUTE for j in chain.joints):
        raise NotGeneral6R("the general 6R takes six revolute joints")
    if chain.convention == "urdf":
        return _urdf_split(chain)
    first = sp.Matrix(chain.base)
    after = []
    for i, j in enumerate(chain.joints):
        if chain.convention == "standard":
            after.append(_tz(j.d) * _tx(j.a) * _rx(j.alpha))
        else:
            pre = _rx(j.alpha) * _tx(j.a)
            if i == 0:
                first = first * pre
            else:
                after[-1] = after[-1] * pre
            after.append(_tz(j.d))
    return first, after, tuple(j.offset for j in chain.joints)


def _onto_axis(axis) -> sp.Matrix:
    """A rotation R (4 x 4) that turns z onto the unit ``axis``, so that the turn about the axis is
    R Rz(q) R^T: the identity for z, a half turn about x for -z, else the turn about z x axis."""
    a = sp.Matrix([sp.sympify(v) for v in axis])
    out = sp.eye(4)
    if a[0].is_zero and a[1].is_zero:   # (is_zero: a Float 0.0 is not == 0 in SymPy)
        if a[2].is_positive:
            return out
        out[1, 1] = out[2, 2] = -1
        return out
    c = a[2]                                            # cos of the angle between z and the axis
    k = sp.Matrix([-a[1], a[0], 0])                     # z x axis, of length sin(angle)
    s2 = k.dot(k)
    K = sp.Matrix([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    out[:3, :3] = sp.eye(3) + K + K * K * (1 - c) / s2  # Rodrigues with the unnormalised k
    return out


def _urdf_split(chain):
    """link_split of a chain read from a URDF: joint i is ``origin_i Rot(axis_i, q_i)`` (then the
    last joint's fixed links), and ``Rot(a, q) = R_a Rz(q) R_a^T`` with R_a turning z onto a, so
    that G_0 = base origin_1 R_1, F'_i = R_i^T origin_(i+1) R_(i+1), F'_6 = R_6^T after_6."""
    turns = [_onto_axis(j.axis) for j in chain.joints]
    first = sp.Matrix(chain.base) * sp.Matrix(chain.joints[0].origin) * turns[0]
    after = [turns[i].T * sp.Matrix(chain.joints[i + 1].origin) * turns[i + 1] for i in range(5)]
    last = chain.joints[5].after
    after.append(turns[5].T * (sp.Matrix(last) if last is not None else sp.eye(4)))
    return first, after, tuple(j.offset for j in chain.joints)


# A polynomial in the sines and cosines of the six joints: {exponents (c1, s1, ..., c6, s6): coefficient}.
def _poly_rotation(k):
    """Rz(phi_k) (k from 0) as a matrix of polynomials."""
    one = (0,) * 12
    c = tuple(1 if i == 2 * k else 0 for i in range(12))
    s = tuple(1 if i == 2 * k + 1 else 0 for i in range(12))
    rows = [[{c: 1}, {s: -1}, {}], [{s: 1}, {c: 1}, {}], [{}, {}, {one: 1}]]
    return rows


def _add(a, b, scale=1):
    out = dict(a)
    for m, v in b.items():
        out[m] = out.get(m, 0) + scale * v
    return out


def _reduce(m):
    """s^2 = 1 - c^2 for each joint: ((monomial, factor), ...) with every s exponent at most 1."""
    terms = [(m, 1)]
    for k in range(6):
        out = []
        for mono, f in terms:
            e = mono[2 * k + 1]
            if e < 2:
                out.append((mono, f))
                continue
            base = list(mono)
            base[2 * k + 1] = e % 2
            half = e // 2
            for j in range(half + 1):  # (1 - c^2)^half
                nxt = list(base)
                nxt[2 * k] += 2 * j
                out.append((tuple(nxt), f * math.comb(half, j) * (-1) ** j))
        terms = out
    return terms


def _mul(a, b):
    out = {}
    for ma, va in a.items():
        for mb, vb in b.items():
            for m, f in _reduce(tuple(x + y for x, y in zip(ma, mb))):
                out[m] = out.get(m, 0) + f * va * vb
    return out


def _const(v):
    return {(0,) * 12: v} if v != 0 else {}


def _mat_vec(M, v):
    """A constant 3 x 3 matrix times a polynomial 3-vector."""
    return [_sum(_scale(v[j], M[i, j]) for j in range(3)) for i in range(3)]


def _scale(p, f):
    return {m: f * c for m, c in p.items()} if f != 0 else {}


def _sum(polys):
    out = {}
    for p in polys:
        out = _add(out, p)
    return out


def _rot_vec(k, v, transpose=False):
    R = _poly_rotation(k)
    if transpose:
        R = [[R[j][i] for j in range(3)] for i in range(3)]
    return [_sum(_mul(R[i][j], v[j]) for j in range(3)) for i in range(3)]


def _dot(a, b):
    return _sum(_mul(x, y) for x, y in zip(a, b))


def _cross(a, b):
    return [_add(_mul(a[1], b[2]), _mul(a[2], b[1]), -1), _add(_mul(a[2], b[0]), _mul(a[0], b[2]), -1),
            _add(_mul(a[0], b[1]), _mul(a[1], b[0]), -1)]


def _mapped(p, f):
    """The polynomial ``p`` ({monomial: coefficient}) with each coefficient passed through ``f``,
    the zeros dropped."""
    out = {}
    for m, v in p.items():
        v = f(v)
        if v != 0:
            out[m] = v
    return out


def _expand(p):
    return _mapped(p, _simplified)


def _invariants(p, l):
    """Raghavan-Roth Eq. 6 of a point p and a direction l: (p, l, p.p, p.l, p x l, (p.p) l - 2 (p.l) p)."""
    pp, pl = _dot(p, p), _dot(p, l)
    return (p, l, pp, pl, _cross(p, l), [_add(_mul(pp, l[i]), _mul(pl, p[i]), -2) for i in range(3)])


def _turn(inv, k, transpose=False):
    """The invariants after the turn Rz(psi_k) (or its transpose): vectors turn, scalars stay."""
    p, l, pp, pl, pxl, last = inv
    return (_rot_vec(k, p, transpose), _rot_vec(k, l, transpose), pp, pl, _rot_vec(k, pxl, transpose),
            _rot_vec(k, last, transpose))


def _move(inv, T):
    """The invariants after the rigid motion y = R x + t (T = [R t]), by identities that hold for
    every rotation R, so that a matrix of symbols (the pose) needs no R^T R = I:
    p.p' = p.p + 2 t.Rp + t.t, p.l' = p.l + t.Rl, (p x l)' = R (p x l) + t x Rl,
    ((p.p) l - 2 (p.l) p)' = R(...) - 2 t x R(p x l) + (t.t) Rl - 2 (p.l) t - 2 (t.Rl) t."""
    p, l, pp, pl, pxl, last = inv
    R, t = T[:3, :3], [T[i, 3] for i in range(3)]
    Rp, Rl, Rpxl, Rlast = (_mat_vec(R, v) for v in (p, l, pxl, last))
    tRp, tRl = (_sum(_scale(v[i], t[i]) for i in range(3)) for v in (Rp, Rl))
    tt = sum(x * x for x in t)

    def t_cross(v):  # t x v
        return [_add(_scale(v[2], t[1]), _scale(v[1], t[2]), -1), _add(_scale(v[0], t[2]), _scale(v[2], t[0]), -1),
                _add(_scale(v[1], t[0]), _scale(v[0], t[1]), -1)]

    t_Rl, t_Rpxl = t_cross(Rl), t_cross(Rpxl)
    p2 = [_add(Rp[i], _const(t[i])) for i in range(3)]
    pp2 = _add(_add(pp, tRp, 2), _const(tt))
    pl2 = _add(pl, tRl)
    pxl2 = [_add(Rpxl[i], t_Rl[i]) for i in range(3)]
    last2 = [_sum((Rlast[i], _scale(t_Rpxl[i], -2), _scale(Rl[i], tt), _scale(pl, -2 * t[i]), _scale(tRl, -2 * t[i])))
             for i in range(3)]
    return (p2, Rl, pp2, pl2, pxl2, last2)


def _rows(inv):
    p, l, pp, pl, pxl, last = inv
    return [_expand(e) for e in (*p, *l, pp, pl, *pxl, *last)]


def _negligible(v):
    """A coefficient that cancels up to rounding (a loop of floating-point numbers)."""
    if isinstance(v, float):
        return abs(v) < 1e-12
    return v.is_Number and abs(float(v)) < 1e-12


def _simplified(v):
    """A coefficient expanded (a SymPy expression), or as it is (a float: a numeric loop)."""
    return sp.expand(v) if isinstance(v, sp.Basic) else v


def _named(inv, name):
    """The invariants with each coefficient passed through ``name``, the zeros dropped."""
    def named(p):
        return _mapped(p, name)
    p, l, pp, pl, pxl, last = inv
    return ([named(v) for v in p], [named(v) for v in l], named(pp), named(pl), [named(v) for v in pxl],
            [named(v) for v in last])


def _unchanged(v):
    return v


def loop_equations(E, w=None, name=None):
    """Manocha-Canny Eq. 9 for the loop Rz(psi_1) E_1 Rz(psi_2) E_2 ... Rz(psi_6) E_6 = I:
    (P (3, 14, 9), Q (14, 8)) as nested tuples.  ``w`` (6 symbols or values): the origin and
    z axis of E_6^-1, which the equations take as given (their closed forms are the caller's).

    ``name`` (a coefficient -> what the equations carry for it), where given, is applied to every
    coefficient of the invariants after each motion: :func:`general_6r` makes a coefficient that
    depends on the pose a step of a straight-line program (a short expression in the previous
    stage's steps) and expands the others.  Without it every entry is expanded (the numeric
    loops of :func:`_regular`)."""
    if w is None:
        Winv = _inverse(E[5])
        w = (Winv[0, 3], Winv[1, 3], Winv[2, 3], Winv[0, 2], Winv[1, 2], Winv[2, 2])
    if name is None:
        def named(inv):
            return inv
        rows = _rows
    else:
        def named(inv):
            return _named(inv, name)

        def rows(inv):
            p, l, pp, pl, pxl, last = named(inv)
            return [*p, *l, pp, pl, *pxl, *last]

    # Left side (joints 1, 2 and W = E_6^-1): E_2^-1 Rz2^T E_1^-1 Rz1^T on W's origin and z axis.
    inv = named(_invariants([_const(x) for x in w[:3]], [_const(x) for x in w[3:]]))
    for k in (0, 1):
        inv = named(_move(_turn(inv, k, transpose=True), _inverse(E[k])))
    left = rows(inv)

    # Right side (joints 3, 4, 5): Rz3 E_3 Rz4 E_4 Rz5 E_5 on the origin and the z axis.
    inv = named(_invariants([_const(E[4][i, 3]) for i in range(3)], [_const(E[4][i, 2]) for i in range(3)]))
    for k in (3, 2):  # Rz5, then E_4, Rz4, E_3, Rz3
        inv = named(_move(_turn(inv, k + 1), E[k]))
    right = rows(_turn(inv, 2))

    def exponents(a, b, pair):
        return tuple(pair[0] if k == 2 * a else pair[1] if k == 2 * a + 1 else
                     pair[2] if k == 2 * b else pair[3] if k == 2 * b + 1 else 0 for k in range(12))

    allowed = {}
    for j, mono in enumerate(MONOMIALS_45):
        base = exponents(3, 4, mono)
        for part, extra in ((0, None), (1, 4), (2, 5)):
            m = list(base)
            if extra is not None:
                m[extra] += 1
            allowed[tuple(m)] = (part, j)
    lefts = {exponents(0, 1, mono): j for j, mono in enumerate(MONOMIALS_12)}
    P = [[[0] * 9 for _ in range(14)] for _ in range(3)]
    Q = [[0] * 8 for _ in range(14)]
    for row in range(14):
        for m, v in right[row].items():
            if m not in allowed and _negligible(v):
                continue
            if m not in allowed:
                raise NotGeneral6R(f"equation {row + 1} leaves the bilinear form on joints 3-5 ({m})")
            part, j = allowed[m]
            P[part][row][j] += v
        for m, v in left[row].items():
            if m == (0,) * 12:
                P[0][row][8] -= v
            elif m in lefts:
                Q[row][lefts[m]] += v
            elif not _negligible(v):
                raise NotGeneral6R(f"equation {row + 1} leaves the bilinear form on joints 1-2 ({m})")
    finish = _simplified if name is None else _unchanged
    P = tuple(tuple(tuple(finish(e) for e in r) for r in part) for part in P)
    Q = tuple(tuple(finish(e) for e in r) for r in Q)
    return P, Q


def chain_loop(chain, X, start=0, reverse=False):
    """The loop of a six-revolute DH chain reaching the pose X, as (E_1 .. E_6, signs, order):
    joint ``order[k]`` (from 0) is loop joint k, its angle ``phi = sign psi_k``, with
    ``phi_i = q_i + offset_i - delta_i``.  ``start`` rotates the loop (it begins at that joint),
    ``reverse`` runs it backwards (the inverse loop).  ``X`` is the pose, or the link that
    closes the loop itself (``pose_link``) when ``X`` is None (``E`` then holds a
    symbol matrix for it: see :func:`general_6r`)."""
    first, after, offsets = link_split(chain)
    F = [_rz(c, s) * f for (c, s), f in zip(SHIFTS, after)]  # F_i = Rz(delta_i) F'_i
    F[5] = F[5] * sp.Matrix(chain.tool) * _inverse(X) * first   # the loop closes through the pose
    order = list(range(6))
    E = list(F)
    signs = [1] * 6
    if reverse:  # (Rz1 F1 ... Rz6 F6)^-1 = F6^-1 Rz(-phi6) ... F1^-1 Rz(-phi1): cyclically Rz(-phi6) F5^-1 ...
        order = order[::-1]
        E = [_inverse(F[(i - 1) % 6]) for i in order]
        signs = [-1] * 6
    order = order[start:] + order[:start]
    E = E[start:] + E[:start]
    return E, tuple(signs), tuple(order)


# The loops tried, in order: (start, reverse).  An arm with parallel or orthogonal axes can make
# the 12 x 12 matrix singular for every x_3 (the Jaco's axes 2 and 3 are parallel: its first
# loop is); the first loop whose matrix is regular at a random pose is taken.
LOOPS = tuple((start, reverse) for reverse in (False, True) for start in range(6))


class _FloatMatrix:
    """A 4 x 4 of Python floats with the indexing loop_equations uses (M[i, j], M[:3, :3], M[:3, 3])."""

    def __init__(self, rows):
        self.rows = rows

    def __getitem__(self, key):
        i, j = key
        if isinstance(i, slice) or isinstance(j, slice):
            ri = range(4)[i] if isinstance(i, slice) else [i]
            rj = range(4)[j] if isinstance(j, slice) else [j]
            return _FloatMatrix([[self.rows[a][b] for b in rj] for a in ri])
        return self.rows[i][j]


def _inverse_float(T):
    R = [[T.rows[j][i] for j in range(3)] for i in range(3)]
    t = [-sum(R[i][j] * T.rows[j][3] for j in range(3)) for i in range(3)]
    return _FloatMatrix([R[0] + [t[0]], R[1] + [t[1]], R[2] + [t[2]], [0.0, 0.0, 0.0, 1.0]])


# The seed of the random configuration and x_3 that :func:`_regular` tries a loop at.
LOOP_SEED = 20261126


class _NumericChain:
    """The chain at the default parameters in double precision: its pose at a configuration, and
    :func:`chain_loop`'s links at a pose (the same products, with numpy: a loop's links at a pose in
    about 0.1 ms, where SymPy took 15 ms)."""

    def __init__(self, chain, params):
        import numpy as np
        numbers = {s: sp.Float(v, 30) for s, v in params.items()}

        def numeric(m):
            return np.array(sp.Matrix(m).xreplace(numbers).evalf(20), float)
        first, after, offsets = link_split(chain)  # G_0 Rz(q_1 + o_1) F'_1 ... Rz(q_6 + o_6) F'_6 tool
        self.first, self.after, self.tool = numeric(first), [numeric(f) for f in after], numeric(chain.tool)
        self.offsets = [float(sp.sympify(o).xreplace(numbers)) for o in offsets]
        self.shifted = [self.rz(math.atan2(float(s), float(c))) @ f for (c, s), f in zip(SHIFTS, self.after)]

    @staticmethod
    def rz(angle):
        import numpy as np
        c, s = math.cos(angle), math.sin(angle)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], float)

    def pose(self, q):
        T = self.first
        for i, angle in enumerate(q):
            T = T @ self.rz(float(angle) + self.offsets[i]) @ self.after[i]
        return T @ self.tool

    def loop(self, T, start, reverse):
        """chain_loop(chain, T, start, reverse)'s links E_1 .. E_6 (4 x 4 arrays)."""
        import numpy as np
        F = list(self.shifted)
        F[5] = F[5] @ self.tool @ np.linalg.inv(T) @ self.first  # the loop closes through the pose
        E = [np.linalg.inv(F[(i - 1) % 6]) for i in range(5, -1, -1)] if reverse else F
        return E[start:] + E[:start]


def _sample_pose(chain, params, seed=LOOP_SEED, numeric=None):
    """The pose of :func:`_regular`'s random configuration at the default parameters."""
    import numpy as np
    numeric = numeric or _NumericChain(chain, params)
    return numeric.pose(np.random.default_rng(seed).uniform(-3, 3, 6))


def _regular(chain, params, start, reverse, seed=LOOP_SEED, pose=None, numeric=None):
    """The smallest singular value of the 12 x 12 matrix of the loop, at a random pose and x_3,
    relative to the largest (default parameters, double precision).  ``pose``: what
    :func:`_sample_pose` gives for ``seed`` (the same for every loop: :func:`choose_loops` draws it once)."""
    import numpy as np
    numeric = numeric or _NumericChain(chain, params)
    T = pose if pose is not None else _sample_pose(chain, params, seed, numeric)
    rng = np.random.default_rng(seed)
    rng.uniform(-3, 3, 6)  # the configuration's draw, then x_3's
    P, Q = loop_equations([_FloatMatrix(e.tolist()) for e in numeric.loop(T, start, reverse)])
    M2, M1, M0 = numeric_pencil(np.array(P, float), np.array(Q, float))
    x = rng.uniform(-2, 2)
    sv = np.linalg.svd(M2 * x * x + M1 * x + M0, compute_uv=False)
    return sv[-1] / sv[0]


def half_angle_matrix():
    """9 x 9: each monomial of MONOMIALS_45 times (1 + x_a^2)(1 + x_b^2), over x_a^i x_b^j (i*3 + j):
    s = 2x, c = 1 - x^2, 1 = 1 + x^2 (Manocha-Canny Eq. 11)."""
    import numpy as np

    def factor(c, s):
        return np.array([1.0, 0.0, -1.0]) if c else np.array([0.0, 2.0, 0.0]) if s else np.array([1.0, 0.0, 1.0])
    return np.array([np.outer(factor(ca, sa), factor(cb, sb)).ravel() for ca, sa, cb, sb in MONOMIALS_45])


def numeric_pencil(P, Q):
    """(M_2, M_1, M_0), each 12 x 12, from P (3, 14, 9) and Q (14, 8) of one pose: the left null
    space N of Q (6 x 14, by Householder QR) eliminates joints 1 and 2; N P(psi_3) with the
    half-angle tangents, and the same times x_a, is (M_2 x^2 + M_1 x + M_0) [x_a^i x_b^j] = 0
    (Manocha-Canny Eqs. 10-13).  A reference version of what the generated code does."""
    import numpy as np
    H = half_angle_matrix()
    basis, _ = np.linalg.qr(Q, mode="complete")
    N = basis[:, 8:].T
    S1, Sc, Ss = (N @ P[k] @ H for k in range(3))
    out = []
    for A in (S1 - Sc, 2 * Ss, S1 + Sc):
        M = np.zeros((12, 12))
        for i in range(3):
            M[:6, 3 * i:3 * i + 3] = A[:, 3 * i:3 * i + 3]
            M[6:, 3 * i + 3:3 * i + 6] = A[:, 3 * i:3 * i + 3]
        out.append(M)
    return tuple(out)


# How many regular loops the ik solves on: a pose can make one loop's pencil singular (the Jaco
# with q2 = q3 = pi/2 and q5 = 0) or one loop's eigenvector lose a double root's accuracy; the
# union of two loops' solutions covers that.
LOOP_COUNT = 2


def choose_loops(chain, params, count=LOOP_COUNT, threshold=1e-9):
    """The first ``count`` loops of LOOPS whose 12 x 12 matrix is regular (see :func:`_regular`)."""
    numeric = _NumericChain(chain, params)
    pose = _sample_pose(chain, params, numeric=numeric)
    found = [(start, reverse) for start, reverse in LOOPS
             if _regular(chain, params, start, reverse, pose=pose, numeric=numeric) > threshold]
    if not found:
        raise NotGeneral6R("the 12 x 12 matrix of Raghavan-Roth is singular for every choice of loop")
    return (found * count)[:count]


# The poses (random configurations, LOOP_SEED) on which :func:`fast_loop` compares the loops.
FAST_POSES = 12


def fast_loop(chain, params, loops, count=FAST_POSES, seed=LOOP_SEED) -> int:
    """Which of ``loops`` the C ik solves first, by the real roots of det M(psi_3) (general_6r.c.j2's
    fast pass): the one whose real roots in psi_3 lie furthest apart, the median over ``count``
    random poses of the smallest gap between two of them (double precision, the companion
    matrix's eigenvalues with numpy).  Near roots are what that pass resolves worst: on the Kinova
    Jaco, loop psi_3 = q2 puts half its poses' nearest two roots within 0.0055 rad, psi_3 = q5
    within 0.017 (30 poses).  The first of equal ones; 0 where no pose has two real roots.  About
    0.07 s (the Jaco, the Mico)."""
    import numpy as np
    numeric = _NumericChain(chain, params)
    rng = np.random.default_rng(seed)
    poses = [numeric.pose(rng.uniform(-np.pi, np.pi, 6)) for _ in range(count)]
    scores = []
    for start, reverse in loops:
        gaps = []
        for T in poses:
            E = numeric.loop(T, start, reverse)
            P, Q = loop_equations([_FloatMatrix(e.tolist()) for e in E])
            M2, M1, M0 = numeric_pencil(np.array(P, float), np.array(Q, float))
            C = np.zeros((24, 24))
            C[:12, 12:] = np.eye(12)
            try:
                C[12:] = -np.linalg.solve(M2, np.hstack([M0, M1]))
            except np.linalg.LinAlgError:
                continue
            roots = np.linalg.eigvals(C)
            real = roots.real[np.abs(roots.imag) <= 1e-6 * (1 + np.abs(roots.real))]
            psi = np.sort(2 * np.arctan(real) % (2 * np.pi))
            if len(psi) > 1:
                gaps.append(np.diff(np.concatenate([psi, psi[:1] + 2 * np.pi])).min())
        scores.append(float(np.median(gaps)) if gaps else 0.0)
    return int(np.argmax(scores))


def q_blocks(Q) -> tuple:
    """Q's rows and columns (Manocha-Canny Eq. 9, 14 x 8) in independent blocks: ((rows, columns), ...),
    the connected components of its entries that are not zero for every pose, in order of their first
    row.  On a block-diagonal Q (after permuting rows and columns) the left null space and the least
    squares for m_12 split by blocks: on the Kinova Jaco's loop psi_3 = q5, rows 0-2 and 6 (the z
    components of p and l, p.p and p.l, which Rz(psi_1) leaves alone) hold only s2 and c2, the other
    10 rows the other 6 columns, so the C's Householder QR takes 52 row operations where the whole
    took 84.  A row of zeros is a block of its own with no column (a null row as it is).  Where some
    block has fewer rows than columns (Q of rank under 8 on every pose), one block of everything."""
    rows, columns = len(Q), len(Q[0])
    parent = list(range(rows + columns))  # union-find over rows 0..13 and columns 14..21

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i in range(rows):
        for j in range(columns):
            if sp.sympify(Q[i][j]).is_zero is not True:
                parent[root(i)] = root(rows + j)
    found = {}
    for i in range(rows + columns):
        found.setdefault(root(i), []).append(i)
    blocks = sorted((tuple(i for i in members if i < rows), tuple(i - rows for i in members if i >= rows))
                    for members in found.values())
    everything = ((tuple(range(rows)), tuple(range(columns))),)
    if any(len(r) < len(c) or not r for r, c in blocks):
        return everything
    return tuple(blocks)


def p_nonzero(P) -> tuple:
    """Which entries of P_1, P_c, P_s (Manocha-Canny Eq. 9, 3 x 14 x 9) are not zero for every pose: 1 where
    an entry may be nonzero, 0 where it is zero in the equations themselves (a step of the equations' program
    counts as nonzero, and so does a sum of the file's decimals and sqrt(3) terms that cancels only in the
    numbers: 12 of the Jaco's fast loop's, some products with zero for the C, none left out).  On the Kinova
    Jaco's loop psi_3 = q5, 142 of the 378, so that the C's fast pass forms N P and the least squares' rows as
    sums over those alone.  SymPy's zero by equality, not ``is_zero`` (which asks the assumptions of every
    expanded entry: 0.3 s of the Jaco's derivation, where this takes 1 ms; the same pattern on the Jaco, the
    Mico and the IRB 140)."""
    return tuple(tuple(tuple(int(sp.sympify(e) != 0) for e in row) for row in part) for part in P)


# The working precision of a link's irrational constants in the equations (digits).
CONSTANT_DIGITS = 30


def _numeric_constant(v):
    """A constant link entry as the equations take it: exact where it is a rational (0, 1, 3/5, a
    decimal the file writes), a 30-digit float where it is irrational (cos(1.3127) of a twist
    written as a decimal), so that the expansion multiplies numbers instead of carrying such
    terms as symbols (a synthetic general 6R's equations: 21 -> about 2 s); an entry with a
    parameter in it stays as it is."""
    v = sp.sympify(v)
    if v.is_Rational or not v.is_number:
        return v
    return sp.Float(v.evalf(CONSTANT_DIGITS), CONSTANT_DIGITS)


def general_6r(chain, params, loop) -> General6R:
    """The coefficient matrices of Manocha-Canny Eq. 9 for a six-revolute DH chain on the loop
    ``loop`` = (start, reverse) (see :func:`choose_loops`)."""
    start, reverse = loop
    X = sp.Matrix(4, 4, sp.symbols("X0:16", real=True))
    X[3, :] = sp.Matrix([[0, 0, 0, 1]])
    E, signs, order = chain_loop(chain, X, start, reverse)
    # The link that holds the pose becomes a matrix of symbols, defined once per pose.
    links, values = [], []
    for k, e in enumerate(E):
        if e.free_symbols & set(X):
            names = sp.symbols(f"loop{start}{'r' if reverse else ''}_e{k + 1}_0:3_0:4", real=True)
            links.append(sp.Matrix(3, 4, names).col_join(sp.Matrix([[0, 0, 0, 1]])))
            values.extend(zip(names, e[:3, :]))
        else:
            links.append(e.applyfunc(_numeric_constant))
    # The equations as a straight-line program after the link's definitions: each coefficient of
    # each stage (loop_equations) that depends on the pose is a step, named after the loop, instead
    # of a polynomial in the pose and the parameters expanded (the Jaco's kernel: 14,602 -> 2,044
    # operations, its derivation 9.7 -> 1.6 s, its CSE 4.7 -> 0.6 s, its C -O2 compile 10 -> 1.5 s;
    # 2026-11-26).  What the pose does not reach (the side of joints 3 to 5, which the arm's
    # constants and parameters fix) stays expanded, so that what cancels there cancels exactly:
    # as steps too, the Jaco's numpy ik missed 4 of the 65 singular degenerate poses of
    # tests/ik/test_general_6r.py against 0.
    program = Program(taken=[str(s) for s in X] + [str(s) for s, _ in values] + [str(s) for s in params])
    prefix = f"loop{start}{'r' if reverse else ''}_c"
    posed = {s for s, _ in values}

    def name(v):
        if isinstance(v, sp.Basic) and v.free_symbols & posed:
            step = program.define(f"{prefix}{len(program)}", v)
            if isinstance(step, sp.Symbol):
                posed.add(step)
            return step
        return _simplified(v)
    P, Q = loop_equations(links, name=name)
    _, _, offsets = link_split(chain)
    return General6R(X=X, definitions=tuple(values) + tuple(program.steps), P=P, Q=Q, E=tuple(links),
                     signs=signs, order=order, offsets=offsets, loop=(start, reverse))


def applies(model) -> bool:
    """Whether ``model``'s ik is the general 6R: six revolute joints (a DH table or a URDF chain), the pose as
    its task, and no closed form."""
    from ..model import POSE_NAMES
    chain = getattr(model, "chain", None)
    return (chain is not None and not model.ik and tuple(model.task_names) == POSE_NAMES and chain.n == 6
            and chain.convention in ("standard", "modified", "urdf") and all(j.type == REVOLUTE for j in chain.joints))


def equations_function(model):
    """(the kernel ``ik_6r_equations(x) -> (P (L, 3, 14, 9), Q (L, 14, 8), E (L, 6, 3, 4))`` of a
    general 6R on its L loops (Manocha-Canny Eq. 9 and the loops' links), the layout its ik needs),
    or None; derived once per arm (1-2 s), then read from the derivation cache."""
    if not applies(model):
        return None
    found = getattr(model, "_general_6r", None)
    if found is None:  # () where the arm turned out not to be one
        from ..support.budget import stage
        from ..support.cache import cached
        chain = model.chain
        key = repr((chain.convention, [(j.a, j.alpha, j.d, j.offset, j.origin, j.axis, j.after) for j in chain.joints],
                    chain.base, chain.tool,
                    sorted((str(k), v) for k, v in model.params.items()), model.task_symbols)).encode()
        # a step of its own, so that a time budget or memory cap that stops it says so (the first caller
        # may be `generate` asking for the arm's ik method, outside the render's steps)
        with stage(f"working on the general 6R's equations ({model.name})"):
            found = model._general_6r = cached(f"general6r-{model.name}", key, lambda: _equations_function(model))
    return found or None


def fast_equations_function(function, layout):
    """``ik_6r_equations_fast(x) -> (P (3, 14, 9), Q (14, 8), E (6, 3, 4))``: ``ik_6r_equations`` of the
    loop the C's fast pass solves (``layout["fast"]``) alone, for that pass, which reads no other (the
    eigen-solve that still runs on 1 % of poses reads both).  The same outputs' entries and program
    (the code generator keeps the steps they read): on the Jaco, the kernel's 5,000 instructions a
    pose less what the other loop alone needed."""
    from ..model import Output, SymbolicFunction
    fast, count = layout["fast"], len(layout["loops"])
    outputs = []
    for out in function.outputs:
        size = len(out.values) // count
        outputs.append(Output(out.name, out.values[fast * size:(fast + 1) * size], out.shape[1:], out.dtype,
                              f"{out.doc} (the fast pass's loop)"))
    return SymbolicFunction(
        "ik_6r_equations_fast", function.arguments, tuple(outputs),
        f"ik_6r_equations of loop {fast} alone (the general 6R's fast pass in C): P (..., 3, 14, 9), "
        f"Q (..., 14, 8), E (..., 6, 3, 4).", definitions=function.definitions)


def _equations_function(model):
    """(the kernel, the layout), or () where no loop's matrix is regular (the arm keeps the seeded ik)."""
    from ..model import Argument, Output, SymbolicFunction
    try:
        loops = [general_6r(model.chain, model.params, loop) for loop in choose_loops(model.chain, model.params)]
    except NotGeneral6R:
        return ()
    X = loops[0].X
    task = model.task_symbols
    pose = {X[i, 3]: task[i] for i in range(3)}
    pose.update({X[i, j]: task[3 + 3 * i + j] for i in range(3) for j in range(3)})
    definitions = tuple((s, sp.sympify(v).xreplace(pose)) for g in loops for s, v in g.definitions)
    x = Argument("x", task, "the pose as task coordinates x, y, z, r11 .. r33, shape (..., 12)")
    count = len(loops)
    P = tuple(e for g in loops for part in g.P for row in part for e in row)
    Q = tuple(e for g in loops for row in g.Q for e in row)
    E = tuple(e for g in loops for link in g.E for e in sp.Matrix(link)[:3, :])
    function = SymbolicFunction(
        "ik_6r_equations", (x,),
        (Output("P", P, (count, 3, 14, 9), "float", "P_1, P_c, P_s of Manocha-Canny Eq. 9, per loop"),
         Output("Q", Q, (count, 14, 8), "float", "Q of Manocha-Canny Eq. 9, per loop"),
         Output("E", E, (count, 6, 3, 4), "float", "the links E_1 .. E_6 (3 x 4) of each loop")),
        f"The 14 equations of Raghavan and Roth (1993) in the matrix form of Manocha and Canny (1994), "
        f"Eq. 9, P(psi_3) m_45 = Q m_12, on {count} loops: P (..., {count}, 3, 14, 9), Q (..., {count}, 14, 8), "
        f"and the loops' links E (..., {count}, 6, 3, 4); the general 6R ik solves them.",
        definitions=definitions)
    shifts = [sp.atan2(s, c) for c, s in SHIFTS]
    layout = {"order": [g.order for g in loops], "signs": [g.signs for g in loops],
              "shifts": tuple(float(shift) for shift in shifts),
              "offsets": tuple(float(sp.sympify(o).evalf(17)) for o in loops[0].offsets),
              # cos and sin of shift - offset per joint (the C's candidates' cos q and sin q from psi's)
              "turns": tuple((float(sp.cos(shift - sp.sympify(o)).evalf(30)),
                              float(sp.sin(shift - sp.sympify(o)).evalf(30)))
                             for shift, o in zip(shifts, loops[0].offsets)),
              "loops": [g.loop for g in loops],
              "fast": fast_loop(model.chain, model.params, [g.loop for g in loops]),
              "blocks": [q_blocks(g.Q) for g in loops],
              "p_nonzero": [p_nonzero(g.P) for g in loops]}
    return function, layout

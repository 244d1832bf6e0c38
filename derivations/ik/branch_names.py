"""Branch names by geometry: shoulder right/left, elbow up/down, wrist noflip/flip (issue #26, item 5).

The decomposition (:mod:`derivations.ik.decompose`) names a branch by its root choices, ``plus`` or
``minus`` (the sign of an ``acos`` term), so that the same words meant different configurations on
different arms.  :func:`geometric_names` renames the branches after they are solved, from the chain's
axes alone, so it applies to any family that writes ``shoulder``, ``elbow`` and ``wrist`` choices.

The words are read off the configuration's frames, as Paul's ARM, ELBOW and WRIST indicators for the
Puma (Paul, *Robot Manipulators*, 1981; Lee and Ziegler, 1984), made independent of the arm:

* ``u`` (up): axis 1, turned to point along the base's +z (a ceiling arm's up is its base's);
* ``S`` the shoulder point (on axis 2, nearest axis 1), ``E`` the elbow point (on the elbow's axis,
  axis 3, nearest S at q = 0), ``W`` the wrist centre (where the wrist's axes meet; on a UR or a
  pitch arm the point of axis 4 in the arm's plane; the tool point of a 3-joint arm);
* ``f`` forward: the direction across u and the shoulder axis, fixed to link 1, pointing at q = 0
  towards the wrist centre (an arm straight up at q = 0, as the LWR 4: along ``h2 x u``);
* **shoulder right**: ``(W - p1) . f >= 0``, the wrist centre ahead of axis 1 (on an arm with a
  shoulder offset, the Puma's right arm); **left**: behind it, the base turned by about pi, reaching
  over the back;
* **elbow up**: ``((W - S) x (E - S)) . n > 0`` with ``n`` the elbow's axis pointing along
  ``r x u``, ``r`` the reach (f on a right shoulder, -f on a left one): the elbow above the line from
  the shoulder to the wrist centre, seen from the side with the reach to the right;
  on a planar arm (every axis along z), ``n`` = +z: the elbow left of that line seen from above;
* **wrist noflip**: ``(h4 x h6) . h5 >= 0`` (h6 the tool's approach on a 5-joint arm), the axes in
  the joints' positive senses: the sine of the wrist's middle joint, measured from the wrist
  straight, is >= 0 (the Puma's ``sin(theta5) >= 0``).

For each arm the mapping from root choices to these words is found numerically at derivation time:
each branch is evaluated (its steps in numpy) at targets from seeded random configurations, the
predicates computed on its answers, and each branch must give one label on every answer where the
predicate is not degenerate, and the branches must have both words.  The parts are found so, from
the answers, not from what the family called its roots.  The root choices no part explains are kept,
as few as tell the branches apart, under their root-choice names (``slide_plus``, a Stanford arm's
prismatic joint); if even all of them do not, every branch keeps its root choices.
The branches are then ordered shoulder right before left, elbow up before down, noflip before flip.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from ..chain import REVOLUTE
from ..program import _Arithmetic, _walk, evaluate_arrays
from .primitives import UNIT_SNAP, ClampUnit, Ramp, WrapAngle

__all__ = ["geometric_names", "WORDS", "SAMPLES"]

# Each part's two words, the first of each pair first in BRANCHES.
WORDS = {"shoulder": ("right", "left"), "elbow": ("up", "down"), "wrist": ("noflip", "flip")}
ORDER = ("shoulder", "elbow", "slide", "wrist")
SAMPLES = 48               # seeded random configurations the mapping is read from
DEGENERATE = 1e-7          # a predicate within this (relative) of zero says nothing


# --- the branches in numpy ------------------------------------------------------------------

def _wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _clamp(c):
    snap = float(UNIT_SNAP)
    return np.where(c >= 1 - snap, 1.0, np.where(c <= -1 + snap, -1.0, c))


_RELATIONS = {sp.LessThan: np.less_equal, sp.StrictLessThan: np.less, sp.GreaterThan: np.greater_equal,
              sp.StrictGreaterThan: np.greater}


def _arithmetic():
    def other(e, known):
        if isinstance(e, sp.Piecewise):
            out = walk(e.args[-1][0], known)
            for value, condition in reversed(e.args[:-1]):
                out = np.where(walk(condition, known), walk(value, known), out)
            return out
        if type(e) in _RELATIONS:
            return _RELATIONS[type(e)](walk(e.lhs, known), walk(e.rhs, known))
        if isinstance(e, sp.And):
            return np.logical_and.reduce([walk(a, known) for a in e.args])
        if isinstance(e, sp.Or):
            return np.logical_or.reduce([walk(a, known) for a in e.args])
        if e is sp.true:
            return np.bool_(True)
        raise ValueError(f"cannot evaluate {e.func.__name__} in double precision")

    def power(base, exponent, walk_):
        exponent = walk_(exponent)
        return 1.0 / base if exponent == -1 else np.sqrt(base) if exponent == 0.5 else base ** exponent

    functions = {sp.sin: np.sin, sp.cos: np.cos, sp.tan: np.tan, sp.atan2: np.arctan2, sp.acos: np.arccos,
                 sp.asin: np.arcsin, sp.atan: np.arctan, sp.Abs: np.abs, sp.sign: np.sign, sp.sqrt: np.sqrt,
                 sp.Min: np.minimum, sp.Max: np.maximum, WrapAngle: _wrap, ClampUnit: _clamp,
                 Ramp: lambda v: np.maximum(v, 0.0)}
    def product(values):
        out = values[0]
        for v in values[1:]:
            out = out * v
        return out
    arithmetic = _Arithmetic(float, lambda values: sum(values[1:], values[0]), product, power, functions, other)

    def walk(e, known):
        return _walk(e, known, arithmetic)
    return walk


def evaluate_branch(model, branch, point: dict) -> tuple[np.ndarray, np.ndarray]:
    """(Q (N, n), valid (N,)) of ``branch`` at ``point`` ({symbol: (N,) array}: the task symbols, the
    parameters and a free joint), its steps evaluated in order."""
    walk = _arithmetic()
    known = {s: np.asarray(v, dtype=float) for s, v in point.items()}
    count = len(next(iter(point.values())))
    with np.errstate(all="ignore"):
        for symbol, expr in branch.steps:
            known[symbol] = np.broadcast_to(np.asarray(walk(sp.sympify(expr), known), dtype=float), (count,))
        Q = np.stack([np.broadcast_to(known[q], (count,)) for q in model.q], axis=-1)
        condition = branch.step_condition if branch.step_condition is not None else sp.true
        valid = np.broadcast_to(walk(condition, known), (count,))
    return Q, valid & np.isfinite(Q).all(axis=-1)


# --- the chain's geometry in numbers ---------------------------------------------------------

def _rotation(h, angle):
    """(N, 3, 3) rotations about the unit vector h by the angles (N,) (Rodrigues)."""
    K = np.array([[0, -h[2], h[1]], [h[2], 0, -h[0]], [-h[1], h[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


class _Geometry:
    """The chain's axes at q = 0 in numbers (default parameters), and its frames at configurations."""

    def __init__(self, model, structure):
        values = {k: sp.Float(float(v)) for k, v in model.params.items()}

        def number(vec):
            return np.array([float(sp.sympify(e).xreplace(values).evalf()) for e in vec])
        self.kinds = [a.kind for a in structure.axes]
        self.h = [number(a.h) for a in structure.axes]
        self.p = [number(a.p) for a in structure.axes]
        home = structure.home
        self.home_R = np.array([[float(sp.sympify(home[i, j]).xreplace(values).evalf()) for j in range(3)]
                                for i in range(3)])
        self.home_p = number(home[:3, 3])
        self.scale = 1.0 + sum(np.linalg.norm(p) for p in self.p) + np.linalg.norm(self.home_p)

    def products(self, q: np.ndarray):
        """[(R, t) of E_1 ... E_i for i = 0 .. n], each (N, 3, 3) and (N, 3), at q (N, n)."""
        N = len(q)
        R, t = np.broadcast_to(np.eye(3), (N, 3, 3)).copy(), np.zeros((N, 3))
        out = [(R, t)]
        for i, kind in enumerate(self.kinds):
            if kind == REVOLUTE:
                Ri = _rotation(self.h[i], q[:, i])
                ti = self.p[i] - np.einsum("nij,j->ni", Ri, self.p[i])
            else:
                Ri, ti = np.broadcast_to(np.eye(3), (N, 3, 3)), q[:, i:i + 1] * self.h[i]
            t = t + np.einsum("nij,nj->ni", R, ti)
            R = R @ Ri
            out.append((R, t))
        return out


def _nearest_on(p, h, point):
    """The point of the line (p, h) nearest ``point``."""
    return p + h * np.dot(point - p, h)


def _closest_between(p1, h1, p2, h2):
    """The point of line 2 nearest line 1 (the meeting point if they meet)."""
    w = p1 - p2
    b = np.dot(h1, h2)
    den = 1 - b * b
    if den < 1e-12:
        return _nearest_on(p2, h2, p1)
    t = (np.dot(h2, w) - b * np.dot(h1, w)) / den
    return p2 + h2 * t


def _meeting(p1, h1, p2, h2, scale):
    """The point where two lines meet, or None."""
    a, b = _closest_between(p2, h2, p1, h1), _closest_between(p1, h1, p2, h2)
    return b if np.linalg.norm(a - b) < 1e-9 * scale else None


def _unit(v):
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else v * 0.0


def _carry(products, k, point):
    R, t = products[k]
    return np.einsum("nij,j->ni", R, point) + t


def _turn(products, k, vec):
    return np.einsum("nij,j->ni", products[k][0], vec)


class _Parts:
    """The shoulder, elbow and wrist of an arm: their points at q = 0 and the predicates at q.

    ``axes`` are the chain's indices of the solved arm's axes in its order (a held joint left out)."""

    def __init__(self, g: _Geometry, axes: list[int], planar: bool, approach: bool):
        self.g, self.axes, self.planar, self.approach = g, axes, planar, approach
        h, p = g.h, g.p
        if planar:  # every axis along z: the first two revolute joints and the next point
            revolute = [k for k in axes if g.kinds[k] == REVOLUTE]
            self.s_axis, self.e_axis = revolute[0], revolute[1]
            self.S, self.E = p[self.s_axis], p[self.e_axis]
            self.w_axis = revolute[2] if len(revolute) > 2 else None
            self.W = p[self.w_axis] if self.w_axis is not None else g.home_p
            self.v_axis, self.V = self.w_axis, self.W
            return
        a1, a2 = axes[0], axes[1]
        z = np.array([0.0, 0.0, 1.0])
        self.u = h[a1] if np.dot(h[a1], z) >= -1e-12 else -h[a1]
        self.S = _closest_between(p[a1], h[a1], p[a2], h[a2])
        self.e_axis = axes[2]
        self.E = _nearest_on(p[self.e_axis], h[self.e_axis], self.S)
        # W: the point whose height along the shoulder axis the base turn is solved for (the wrist
        # centre; a UR's o, where axes 5 and 6 meet; the tool point of a pitch or position arm);
        # V: the point the elbow places (W, or on a UR or a pitch arm the point of axis 4)
        meet = lambda i, j: _meeting(p[axes[i]], h[axes[i]], p[axes[j]], h[axes[j]], g.scale)  # noqa: E731
        self.w_axis, self.W = None, g.home_p
        self.v_axis, self.V = None, g.home_p
        if len(axes) >= 4:
            self.v_axis, self.V = axes[3], _nearest_on(p[axes[3]], h[axes[3]], self.S)
        if len(axes) >= 6 and not approach:
            wrist, o = meet(3, 4), meet(4, 5)
            if wrist is not None and o is not None and np.linalg.norm(wrist - o) < 1e-9 * g.scale:
                self.w_axis, self.W = axes[3], wrist
                self.V = wrist
            elif o is not None:
                self.w_axis, self.W = axes[4], o
        elif len(axes) >= 5:
            o = _meeting(g.home_p, g.home_R[:, 2], p[axes[4]], h[axes[4]], g.scale)
            if o is not None:
                self.w_axis, self.W = axes[4], o
                wrist = meet(3, 4)
                if wrist is not None and np.linalg.norm(wrist - o) < 1e-9 * g.scale:
                    self.V = o
        across = np.cross(h[a2], self.u)
        forward = _unit(across - self.u * np.dot(across, self.u))
        for point in (self.W, self.E):
            ahead = np.dot(point - p[a1], forward)
            if abs(ahead) > 1e-9 * g.scale:
                forward = forward if ahead > 0 else -forward
                break
        self.forward = forward
        side = np.dot(h[self.e_axis], np.cross(forward, self.u))
        self.elbow_sense = 0.0 if abs(side) < 1e-9 else np.sign(side)

    def _point(self, products, axis, point):
        """A point at q: fixed to the link before ``axis`` (None: the tool point)."""
        if axis is None:
            R, t = products[-1]
            return np.einsum("nij,j->ni", R, self.g.home_p) + t
        return _carry(products, axis, point)

    def predicates(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """{part: value (N,)}: positive for the first word, negative for the second (near 0: degenerate)."""
        g = self.g
        P = g.products(q)
        out = {}
        W, V = self._point(P, self.w_axis, self.W), self._point(P, self.v_axis, self.V)
        if self.planar:
            S, E = _carry(P, self.s_axis, self.S), _carry(P, self.e_axis, self.E)
            out["elbow"] = np.cross(V - S, E - S)[:, 2] / g.scale**2
            return out
        a1 = self.axes[0]
        p1 = _carry(P, a1, g.p[a1])
        forward = _turn(P, a1 + 1, self.forward)
        ahead = np.einsum("ni,ni->n", W - p1, forward) / g.scale
        out["shoulder"] = ahead
        if g.kinds[self.e_axis] == REVOLUTE and self.elbow_sense != 0:
            S = _carry(P, self.axes[1], self.S)
            E = _carry(P, self.e_axis, self.E)
            n = _turn(P, self.e_axis, g.h[self.e_axis]) * (self.elbow_sense * np.sign(ahead))[:, None]
            out["elbow"] = np.einsum("ni,ni->n", np.cross(V - S, E - S), n) / g.scale**2
        if len(self.axes) >= 5:
            a4, a5 = self.axes[3], self.axes[4]
            h4, h5 = _turn(P, a4, g.h[a4]), _turn(P, a5, g.h[a5])
            if len(self.axes) >= 6 and not self.approach:
                h6 = _turn(P, self.axes[5], g.h[self.axes[5]])
            else:  # the tool's approach, its z axis
                h6 = np.einsum("nij,j->ni", P[-1][0], g.home_R[:, 2])
            out["wrist"] = np.einsum("ni,ni->n", np.cross(h4, h6), h5)
        return out


# --- the renaming -----------------------------------------------------------------------------

def _words(name: str) -> list[tuple[str, str]]:
    """``shoulder_plus_elbow_minus`` -> [("shoulder", "plus"), ("elbow", "minus")]."""
    parts = name.split("_")
    return [(parts[i], parts[i + 1]) for i in range(0, len(parts) - 1, 2)]


def _samples(model, free: int | None, count: int):
    rng = np.random.default_rng(20261126)
    columns = []
    for kind, limit in zip(model.joint_types, getattr(model, "limits", None) or [None] * model.n):
        if kind == REVOLUTE:
            columns.append(rng.uniform(-np.pi, np.pi, count))
        else:
            low, high = (float(limit[0]), float(limit[1])) if limit else (-1.0, 1.0)
            columns.append(rng.uniform(low, high, count))
    q = np.stack(columns, axis=-1)
    params = {k: float(v) for k, v in model.params.items()}
    # the task walked step by step over the batch (a program-form arm's flat fk, lambdified, took
    # 0.5-1.3 s of the Romeo arm's model to print and compile)
    at = {s: q[:, k] for k, s in enumerate(model.q)} | params
    x = np.stack([np.broadcast_to(np.asarray(v, float), (count,))
                  for v in evaluate_arrays(model.program, list(model.task), at)], axis=-1)
    point = {s: x[:, i] for i, s in enumerate(model.task_symbols)}
    point.update({k: np.full(count, v) for k, v in params.items()})
    if free is not None:
        point[model.q[free]] = q[:, free]
    return point


def geometric_names(model, structure, axes: list[int], family: str, branches: list, free: int | None = None):
    """``branches`` renamed by geometry and ordered (see the module's docstring), or as they are where
    no part has a geometric word.  ``structure``: the chain's axes (all joints); ``axes``: the chain's
    indices of the axes the family solved, in its order (a seven-joint arm's held joint left out)."""
    choices = [_words(b.name) for b in branches]
    if len(branches) < 2 or any(not c for c in choices):
        return branches
    axes = sorted(axes)  # the roles (axis 1 the shoulder's turn, ...) are the chain's, from its base
    planar = family.startswith("parallel axes")
    kinds = "".join(structure.axes[k].kind for k in axes)
    if not planar and not (kinds[:2] == "RR" and len(axes) >= 3):
        return branches  # a shoulder of slides: no shoulder, elbow or wrist to speak of
    g = _Geometry(model, structure)
    shape = _Parts(g, axes, planar, approach="approach" in family)
    point = _samples(model, free, SAMPLES)
    labels = [dict() for _ in branches]     # part -> set of signs seen
    for b, branch in enumerate(branches):
        Q, valid = evaluate_branch(model, branch, point)
        if not valid.any():
            continue
        values = shape.predicates(Q[valid])
        for part, v in values.items():
            seen = np.sign(v[np.abs(v) > DEGENERATE])
            labels[b].setdefault(part, set()).update(seen.tolist())
    # a part is named by geometry where each branch has one word and the branches have both: the
    # parts are found from the answers, not from which root the family called what (a family that
    # solves the chain from its tool end calls its roots by its own numbering)
    named = {}
    for part in WORDS:
        signs = [labels[b].get(part, set()) for b in range(len(branches))]
        if all(len(s) == 1 for s in signs) and len(set().union(*signs)) == 2:
            named[part] = [WORDS[part][0] if s == {1.0} else WORDS[part][1] for s in signs]
    # the root choices no part explains, kept as few as tell the branches apart (a Stanford arm's slide)
    roots = list(dict.fromkeys(p for c in choices for p, _ in c if p not in named))
    for count in range(len(roots) + 1):
        kept = set(roots[:count])
        new = []
        for b, (branch, choice) in enumerate(zip(branches, choices)):
            spelled = [(part, named[part][b]) for part in named] + [(p, w) for p, w in choice if p in kept]
            spelled.sort(key=lambda item: ORDER.index(item[0]) if item[0] in ORDER else len(ORDER))
            new.append((spelled, branch))
        if len({tuple(spelled) for spelled, _ in new}) == len(new):
            break
    names = ["_".join(f"{p}_{w}" for p, w in spelled) for spelled, _ in new]
    if len(set(names)) != len(names):
        return branches  # the words do not tell the branches apart: keep the root choices

    def rank(item):
        spelled, _ = item
        return [WORDS[p].index(w) if p in WORDS and w in WORDS[p] else ("plus", "minus").index(w)
                if w in ("plus", "minus") else 0 for p, w in spelled]
    out = []
    for spelled, branch in sorted(new, key=rank):
        name = "_".join(f"{p}_{w}" for p, w in spelled)
        meaning = ", ".join(f"{p} {w}" for p, w in spelled if p in named)
        doc = branch.doc + (f"; by geometry (docs/ik.md, Branch names): {meaning}" if meaning else "")
        out.append(branch.renamed(name, doc))
    return out

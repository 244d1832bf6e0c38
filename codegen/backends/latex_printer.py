"""The LaTeX printer of the kinematics: joint variables and trigonometric abbreviations in the papers' notation.

A :class:`KinematicsLatexPrinter` (a SymPy ``LatexPrinter`` subclass) prints the joint variable
``q_i`` as ``\\theta_i`` (revolute) or ``d_i`` (prismatic) and the sine and cosine of a plain sum
of joint angles in the abbreviation of Kumar and the velocity slides: ``cos(q1) -> c_{1}``,
``sin(q1 + q2) -> s_{12}``; rates print with a dot.  What a fragment holds, and in which order, is
:mod:`codegen.backends.latex_backend`'s; fitting it to the page is :mod:`codegen.backends.latex_layout`'s.
"""
from __future__ import annotations

import re

import sympy as sp
from sympy.printing.latex import LatexPrinter

from derivations.chain import REVOLUTE
from derivations.ik import WrapAngle

__all__ = ["KinematicsLatexPrinter", "rate_symbol", "task_rate_symbol"]


class KinematicsLatexPrinter(LatexPrinter):
    """LaTeX in the papers' notation for one robot's symbols.

    ``joints`` are the joint symbols q1..qn and ``joint_types`` their kinds (R/P);
    ``params`` the robot's parameter symbols.  A joint prints as ``\\theta_i`` or
    ``d_i``; when that clashes with a parameter's printed name (a parameter
    ``d3`` beside a prismatic joint 3) the joint keeps ``q_i``.  ``others`` are
    the symbols of a model's other coordinate spaces (the AVR 3000's motor
    angles theta1..theta3, tool T, R, Z, ...): when any joint would print like
    one of them, or like its rate, every joint keeps ``q_i`` (Sotirov writes
    the joints q1, q2, q3 and the motors theta1, theta2, theta3).  Trigonometric
    abbreviations are switched off when a parameter would print like one
    (``c_{1}``, ``s_{2}``).
    """

    def __init__(self, joints=(), joint_types=(), params=(), task_names=(), settings=None, others=()):
        probe = LatexPrinter()
        taken = {probe.doprint(p) for p in params}
        spoken_for = {probe.doprint(s) for s in others if s not in set(joints)}
        plain = [rf"\theta_{{{i}}}" if kind == REVOLUTE else f"d_{{{i}}}"
                 for i, kind in enumerate(joint_types, start=1)]
        keep_q = any(text in spoken_for or _dotted(text) in spoken_for for text in plain)
        names: dict[sp.Symbol, str] = {}
        self.joint_latex: dict[sp.Symbol, str] = {}
        self.revolute: dict[sp.Symbol, int] = {}
        # Rates print with a dot, after the other factors, in joint (or task) order.
        self.rate_order: dict[str, int] = {}
        for i, (qi, kind) in enumerate(zip(joints, joint_types), start=1):
            text = rf"\theta_{{{i}}}" if kind == REVOLUTE else f"d_{{{i}}}"
            if text in taken or keep_q:
                text = f"q_{{{i}}}"
            names[qi] = self.joint_latex[qi] = text
            names[rate_symbol(qi)] = _dotted(text)
            self.rate_order[rate_symbol(qi).name] = i
            if kind == REVOLUTE:
                self.revolute[qi] = i
        for k, name in enumerate(task_names):
            names[task_rate_symbol(name)] = rf"\dot{{{probe.doprint(sp.Symbol(name, real=True))}}}"
            self.rate_order[task_rate_symbol(name).name] = k
        self.abbreviate = not any(re.fullmatch(r"[cs](_\{\d+\})?", t) for t in taken)
        base = {"symbol_names": names, "inv_trig_style": "full"}
        base.update(settings or {})
        super().__init__(base)

    # sin and cos: c_{12} for a plain sum of revolute joint angles, else \cos(...)
    def _angle_label(self, angle: sp.Expr) -> str | None:
        if not self.abbreviate:
            return None
        indices = []
        for term, coefficient in angle.as_coefficients_dict().items():
            if coefficient != 1 or term not in self.revolute:
                return None
            indices.append(self.revolute[term])
        if not indices or any(i > 9 for i in indices):
            return None
        return "".join(str(i) for i in sorted(indices))

    def _trig(self, letter: str, name: str, expr, exp=None) -> str:
        label = self._angle_label(expr.args[0])
        if label is not None:
            text = f"{letter}_{{{label}}}"
            return f"{text}^{{{exp}}}" if exp is not None else text
        head = rf"\{name}" if exp is None else rf"\{name}^{{{exp}}}"
        return f"{head}({self._print(expr.args[0])})"

    def _print_sin(self, expr, exp=None):
        return self._trig("s", "sin", expr, exp)

    def _print_cos(self, expr, exp=None):
        return self._trig("c", "cos", expr, exp)

    def _print(self, expr, **kwargs):
        """Each expression printed once: the line breaking prints a sum, then its terms, then
        the factors of a term too wide for a line, and so on down (an automatic IK step of a
        UR5 whose twists are written 1.5708 printed the same subexpressions 12,519 times, 35 s).
        Printing depends only on the expression and these settings, so a remembered text is the
        text."""
        if kwargs or not isinstance(expr, sp.Basic):
            return super()._print(expr, **kwargs)
        memo = self.__dict__.setdefault("_printed", {})
        text = memo.get(expr)
        if text is None:
            text = memo[expr] = super()._print(expr)
        return text

    def _print_atan2(self, expr, exp=None):
        y, x = (self._print(a) for a in expr.args)
        head = r"\operatorname{atan2}" if exp is None else rf"\operatorname{{atan2}}^{{{exp}}}"
        return rf"{head}\left({y},\, {x}\right)"

    def _as_ordered_terms(self, expr, order=None):
        """Terms in SymPy's order, except that a sum of rates keeps the order of the rates
        (``c_{12} \\dot x + s_{12} \\dot y``, as the papers write)."""
        terms = super()._as_ordered_terms(expr, order=order)

        def rank(term):
            names = [a.name for a in term.atoms(sp.Symbol) if getattr(a, "rate", None) is not None]
            return min((self.rate_order.get(n, 0) for n in names), default=-1)
        if any(rank(t) >= 0 for t in terms):
            terms = sorted(terms, key=rank)
        return terms

    def _print_Symbol(self, expr, style="plain"):
        rate = getattr(expr, "rate", None)
        return super()._print_Symbol(rate if rate is not None else expr, style)

    def _print_WrapAngle(self, expr, exp=None):
        """The kernels' wrap to (-pi, pi] written as mathematics, never as the helper's name:
        ``theta + 2 pi floor((pi - theta) / (2 pi))``."""
        text = self._print(WrapAngle.formula(expr.args[0]))
        return rf"\left({text}\right)^{{{exp}}}" if exp is not None else text

    def _print_Ramp(self, expr, exp=None):
        return self._print(expr.as_min_max()) if exp is None else self._print(expr.as_min_max()**exp)

    def _print_Rational(self, expr):
        """A tolerance such as 1/10^24 as a power of ten, not 25 digits."""
        if expr.p in (1, -1) and expr.q >= 10**4 and 10 ** (len(str(expr.q)) - 1) == expr.q:
            return f"{'-' if expr.p < 0 else ''}10^{{-{len(str(expr.q)) - 1}}}"
        return super()._print_Rational(expr)

    def _print_BooleanTrue(self, expr):
        return r"\text{always}"

    def legend(self) -> str:
        """One sentence saying what the abbreviations stand for (empty when unused)."""
        if not self.abbreviate or not self.revolute:
            return ""
        joints = sorted(self.revolute, key=self.revolute.get)
        first = joints[0]
        i, name = self.revolute[first], self.joint_latex[first]
        text = rf"$c_{{{i}}} = \cos {name}$, $s_{{{i}}} = \sin {name}$"
        if len(joints) > 1:
            j, other = self.revolute[joints[1]], self.joint_latex[joints[1]]
            text += rf", $c_{{{i}{j}}} = \cos({name} + {other})$ and so on"
        return text


def rate_symbol(qi: sp.Symbol) -> sp.Symbol:
    """The symbol of the rate of ``qi`` (printed with a dot)."""
    return sp.Symbol(f"{qi.name}_rate", real=True)


def task_rate_symbol(name: str) -> sp.Symbol:
    """The symbol of the rate of task coordinate ``name`` (printed with a dot)."""
    return sp.Symbol(f"{name}_rate", real=True)


def _dotted(text: str) -> str:
    """``\\theta_{1}`` -> ``\\dot{\\theta}_{1}``."""
    head, sep, sub = text.partition("_")
    return rf"\dot{{{head}}}{sep}{sub}"

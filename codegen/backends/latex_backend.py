"""The LaTeX backend: every derived equation of a robot, in the papers' notation.

A :class:`KinematicsLatexPrinter` (a SymPy ``LatexPrinter`` subclass) prints
the joint variable ``q_i`` as ``\\theta_i`` (revolute) or ``d_i`` (prismatic)
and the sine and cosine of a plain sum of joint angles in the abbreviation of
Kumar and the velocity slides: ``cos(q1) -> c_{1}``, ``sin(q1 + q2) -> s_{12}``.
Any other angle (a difference, a multiple, an offset) keeps the explicit
function, ``\\cos(\\theta_1 + \\theta_2 - \\theta_4)``: one abbreviation style,
used throughout.

The printer lives in :mod:`codegen.backends.latex_printer`, and
:class:`MathLayout`, which breaks what is too wide for a page (a long sum over
several aligned lines, a wide matrix into its entries), in
:mod:`codegen.backends.latex_layout`; this module holds what a fragment says.

:func:`robot_sections` lists what a fragment holds, in order: parameters, DH
table, each link transform A_i, their product T, the task coordinates, the
geometric and task Jacobians, det J and the singular set, the rate maps, each
IK branch, notes, and anything further a model carries (printed generically).
Each equation that reproduces a paper's equation is tagged with it
(``Rehiara Eq. 13``) from :data:`CITATIONS`, or from a model note ``cite_<key>``.
"""
from __future__ import annotations

import dataclasses
import functools
import itertools
import re
from dataclasses import dataclass, field

import sympy as sp
from sympy.core.parameters import distribute
from sympy.printing.latex import LatexPrinter  # noqa: F401  (tests patch latex_backend.LatexPrinter)

from derivations.chain import PRISMATIC, REVOLUTE, simplify_entry
from derivations.ik import ACOS_TOLERANCE, ClampUnit, WrapAngle
from derivations.ik.subproblems import TINY
from derivations.model import RobotModel
from derivations.rates.singular import FACTOR_LIMIT, JacobianDeterminant, inverse_rate_map, jacobian_determinant

from . import TEMPLATES
from .latex_layout import FIT_SLACK, LINE_WIDTH, MathLayout, escape_text, math_width  # noqa: F401  (FIT_SLACK: the names it had here)
from .latex_printer import KinematicsLatexPrinter, _dotted, rate_symbol, task_rate_symbol

__all__ = ["KinematicsLatexPrinter", "MathLayout", "Section", "CITATIONS", "SECTION_KEYS", "math_width",
           "robot_sections", "render", "latex_for", "escape_text", "printer_for", "space_symbols", "pose_name",
           "base_parameter_rows"]


# Which paper equation each derived quantity reproduces, per robot.  Keys are the
# section keys (SECTION_KEYS), "link<i>" for one link transform and "ik:<branch>"
# for one inverse-kinematics branch.  "~" is a LaTeX non-breaking space.
CITATIONS: dict[str, dict[str, str]] = {
    "planar_2r": {
        "position": "Rehiara Eq.~22",
        "jacobian": "slides, 2-link example",
        "task_jacobian": "slides, IVM of a 2R",
        "det": "slides, singularity of a 2R",
        "rates": "slides, DVM of a 2R",
        "inverse_rates": "slides, IVM of a 2R",
        "ik": "Rehiara Eqs.~18, 21, 27, 34",
    },
    "planar_3r": {
        "position": "Kumar Eq.~4",
        "task_jacobian": "Kumar Eq.~11",
        "det": "Kumar Eq.~13",
        "rates": "Kumar Eq.~11",
        "inverse_rates": "Kumar Eq.~12",  # the IK steps carry their own tags, Kumar Eqs. (d)-(j)
    },
    "planar_rp": {
        "position": "Kumar Eq.~5",
        "ik": "Kumar Eqs.~6--8",
    },
    "planar_pp": {
        "position": "Kumar Eq.~10",
        "ik": "Kumar Eq.~10",
    },
    "adept_three": {
        "dh": "Rehiara Table~1",
        "link1": "Rehiara Eq.~9",
        "link2": "Rehiara Eq.~10",
        "link3": "Rehiara Eq.~11",
        "link4": "Rehiara Eq.~12",
        "fk": "Rehiara Eq.~13, corrected (E1)",
        "position": "Rehiara Eq.~14",
        "task_jacobian": "Rehiara Eq.~42, rows 1--3",
        # the IK steps carry their own tags, Rehiara Eqs. 14 and 27-34
    },
    "scorbot_er7": {
        "position": "Predescu--Stroe Fig.~3",  # the IK steps carry their own tags, Eqs. 3.1-3.11
    },
    "puma560": {
        "dh": "Kumar Fig.~1; Paul, Craig",
    },
}

SECTION_KEYS = ("params", "dh", "links", "fk", "position", "jacobian", "task_jacobian", "det", "rates", "ik",
                "notes")

# RobotModel attributes every section above already covers; anything else a model
# carries (added by later derivations) is printed generically as an extra section.
_KNOWN_ATTRIBUTES = {"name", "title", "source", "joint_types", "q", "params", "frames", "jacobian", "task_names",
                     "task", "task_jacobian", "limits", "chain", "ik", "notes"}


# --------------------------------------------------------------------------- sections

@dataclass
class Section:
    """One part of a robot's fragment: ``key`` (for ``--what``), a title, LaTeX body."""

    key: str
    title: str
    body: str


@dataclass
class _Writer:
    model: object
    layout: MathLayout
    citations: dict[str, str] = field(default_factory=dict)

    @property
    def printer(self) -> KinematicsLatexPrinter:
        return self.layout.printer

    def tag(self, key: str) -> str:
        cite = self.citations.get(key)
        return rf" \tag{{{cite}}}" if cite else ""

    def display(self, lhs: str, expr, key: str = "", relation: str = "=") -> str:
        """One equation, broken over lines when long."""
        rows = self.layout.fitted_rows(lhs, expr, relation, tag=self.tag(key))
        return self._align(rows)

    def equations(self, pairs, key: str = "") -> str:
        """Several equations aligned at ``=``, tagged on the first."""
        rows: list[str] = []
        names = itertools.count(1)
        for k, (lhs, expr) in enumerate(pairs):
            rows.extend(self.layout.fitted_rows(lhs, expr, names=names, tag=self.tag(key) if k == 0 else ""))
        return self._align(rows)

    @staticmethod
    def _align(rows: list[str]) -> str:
        return "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}"

    def matrix_equation(self, lhs: str, M: sp.Matrix, key: str = "", entry: str = "",
                        skip_last_row: bool = False, product: str = "") -> str:
        """``lhs = [M]`` when it fits a line, else ``lhs`` entry by entry.

        ``entry`` is the name of an entry with ``{ij}`` for its 1-based indices;
        ``skip_last_row`` leaves out the (0 0 0 1) row of a homogeneous transform.
        ``product`` (e.g. ``A_1 A_2``) is printed between ``lhs`` and the matrix.
        """
        head = f"{lhs} = {product}" if product else lhs
        if self.layout.fits(head, M):
            return ("\\begin{equation*}\n" + f"{head} = {self.layout.matrix(M)}" + self.tag(key)
                    + "\n\\end{equation*}")
        # lhs may hold TeX braces (\mathrm{...}): escape them before using it as a format string
        entry = entry or (lhs.replace("{", "{{").replace("}", "}}") + "_{{{ij}}}")
        rows_shown = M.rows - 1 if skip_last_row else M.rows
        pairs, zeros = [], []
        for r in range(rows_shown):
            for c in range(M.cols):
                name = entry.format(ij=f"{r + 1}{c + 1}")
                (zeros.append(name) if M[r, c] == 0 else pairs.append((name, M[r, c])))
        intro = f"${head}$" if product else f"${lhs}$"
        text = (f"{intro} is ${M.rows} \\times {M.cols}$; its entries are" +
                (" (the last row is $(0\\ 0\\ 0\\ 1)$)" if skip_last_row else "") + ":\n")
        text += self.equations(pairs, key)
        if zeros:
            text += "\nand " + self._zero_list(zeros) + ".\n"
        return text

    @staticmethod
    def _zero_list(names: list[str]) -> str:
        if len(names) == 1:
            return f"${names[0]} = 0$"
        return "$" + " = ".join(names) + " = 0$"


def space_symbols(model) -> dict[str, tuple[sp.Symbol, ...]]:
    """{space name: its position, velocity and acceleration symbols} of a model with coordinate spaces
    (empty for a single chain)."""
    return {name: space.position + space.velocity + space.acceleration
            for name, space in getattr(model, "spaces", {}).items()}


def printer_for(model) -> KinematicsLatexPrinter:
    """The printer of ``model``'s fragment: joints, parameters, task names, and the symbols of its other spaces."""
    others = tuple(s for symbols in space_symbols(model).values() for s in symbols)
    return KinematicsLatexPrinter(model.q, model.joint_types, tuple(model.params), model.task_names, others=others)


def pose_name(model) -> str:
    r"""The tool pose's name: ``T`` (the papers'), or ``{}^{0}H_{\mathrm{tip}}`` where ``T`` is a coordinate
    (the AVR 3000's tool rotation T)."""
    names = {str(s) for symbols in space_symbols(model).values() for s in symbols} | set(model.task_names)
    return r"{}^{0}H_{\mathrm{tip}}" if "T" in names else "T"


def robot_sections(model, citations: dict[str, str] | None = None, width: float = LINE_WIDTH) -> list[Section]:
    """Every derived equation of ``model``, as fragment sections in a fixed order."""
    printer = printer_for(model)
    cites = dict(CITATIONS.get(model.name, {}))
    # A description's cite_* notes are its author's text, not TeX: escaped (\input{...} prints as text).
    cites.update({k[len("cite_"):]: escape_text(v) for k, v in model.notes.items() if k.startswith("cite_")})
    cites.update(citations or {})
    w = _Writer(model, MathLayout(printer, width), cites)
    sections = [_params(w), _dh(w), _links(w), _fk(w), _position(w), _jacobian(w), _task_jacobian(w)]
    determinant = jacobian_determinant(model)
    sections += [_det(w, determinant), _rates(w, determinant), _ik(w), _dynamics(w), _notes(w)]
    sections += _extras(w)
    return [s for s in sections if s is not None]


def _params(w: _Writer) -> Section:
    m = w.model
    kinds = {REVOLUTE: "revolute", PRISMATIC: "prismatic"}
    joints = ", ".join(f"${w.printer.joint_latex[qi]}$ ({kinds[t]})" for qi, t in zip(m.q, m.joint_types))
    text = f"Joint variables: {joints}."
    if m.params:
        values = ", ".join(f"${w.layout.tex(p)} = {_number(v)}$" for p, v in m.params.items())
        text += f" Parameters (SI units, the defaults): {values}."
    legend = w.printer.legend()
    if legend:
        text += f" Abbreviations: {legend}."
    return Section("params", "Symbols", text + "\n")


def _number(value: float) -> str:
    text = f"{value:.6g}"
    return text if "e" not in text else sp.latex(sp.Float(value, 6))


def _dh(w: _Writer) -> Section | None:
    chain = w.model.chain
    if chain is None:
        return None
    tex = w.layout.tex
    if chain.convention == "urdf":
        return _urdf_joints(w, chain)
    rows = []
    for i, (joint, qi) in enumerate(zip(chain.joints, w.model.q), start=1):
        variable = qi + joint.offset
        theta = variable if joint.type == REVOLUTE else joint.theta
        d = variable if joint.type == PRISMATIC else joint.d
        cells = [str(i), tex(theta), tex(d), tex(joint.a), tex(joint.alpha)]
        if chain.convention == "modified":
            cells = [str(i), tex(joint.alpha), tex(joint.a), tex(theta), tex(d)]
        rows.append(" & ".join(c if k == 0 else f"${c}$" for k, c in enumerate(cells)) + r" \\")
    if chain.convention == "standard":
        header = r"$i$ & $\theta_i$ & $d_i$ & $a_i$ & $\alpha_i$ \\"
        convention = "standard Denavit--Hartenberg convention (Rehiara Eqs.~4--6, corrected as erratum E2)"
        rule = (r"A_i = \mathrm{Rot}(z, \theta_i)\,\mathrm{Trans}(z, d_i)\,"
                r"\mathrm{Trans}(x, a_i)\,\mathrm{Rot}(x, \alpha_i)")
    else:
        header = r"$i$ & $\alpha_{i-1}$ & $a_{i-1}$ & $\theta_i$ & $d_i$ \\"
        convention = "modified (Craig) convention"
        rule = (r"A_i = \mathrm{Rot}(x, \alpha_{i-1})\,\mathrm{Trans}(x, a_{i-1})\,"
                r"\mathrm{Rot}(z, \theta_i)\,\mathrm{Trans}(z, d_i)")
    cite = w.citations.get("dh")
    caption = f"Denavit--Hartenberg parameters{f' ({cite})' if cite else ''}, {convention}:"
    body = (caption + "\n\\begin{equation*}\n" + rule + "\n\\end{equation*}\n"
            + "\\begin{center}\n\\begin{tabular}{ccccc}\n\\hline\n" + header + "\n\\hline\n"
            + "\n".join(rows) + "\n\\hline\n\\end{tabular}\n\\end{center}\n")
    return Section("dh", "Denavit--Hartenberg table", body)


def _urdf_joints(w: _Writer, chain) -> Section:
    """A URDF chain's joints: each one's axis (in its own frame) and the translation of its fixed
    transform; the transforms themselves are the link transforms printed next."""
    tex = w.layout.tex
    rows = []
    for i, (joint, qi) in enumerate(zip(chain.joints, w.model.q), start=1):
        kind = "revolute" if joint.type == REVOLUTE else "prismatic"
        axis = tex(sp.Matrix(joint.axis).T)
        origin = tex(sp.Matrix(joint.origin)[:3, 3].T)
        rows.append(f"{i} & {escape_text(joint.name)} & {kind} & ${axis}$ & ${origin}$ \\\\")
    body = ("Joints of the URDF chain (fixed joints folded into the next joint's origin, those after the "
            "last joint into its link):\n\\begin{equation*}\nA_i = O_i\\,M_i(q_i)\n\\end{equation*}\n"
            "where $O_i$ is the fixed transform of the joint's origin, with the fixed joints before it, and "
            "$M_i$ the rotation about or translation along its axis.\n"
            + "\\begin{center}\n\\begin{tabular}{clccc}\n\\hline\n"
            + r"$i$ & joint & type & axis & origin translation \\" + "\n\\hline\n"
            + "\n".join(rows) + "\n\\hline\n\\end{tabular}\n\\end{center}\n")
    return Section("dh", "Joints", body)


def _links(w: _Writer) -> Section | None:
    chain = w.model.chain
    if chain is None:
        return None
    parts = []
    for i, qi in enumerate(w.model.q):
        A = chain.link_transform(i, qi).applyfunc(simplify_entry)
        name = f"A_{{{i + 1}}}"
        parts.append(w.matrix_equation(name, A, key=f"link{i + 1}", entry=f"(A_{{{{{i + 1}}}}})_{{{{{{ij}}}}}}",
                                       skip_last_row=True))
    if chain.tool != sp.eye(4):
        parts.append(w.matrix_equation(r"T_{\mathrm{tool}}", chain.tool, skip_last_row=True))
    return Section("links", "Link transforms", "\n".join(parts) + "\n")


def _fk(w: _Writer) -> Section:
    m = w.model
    if m.chain is not None:
        product = " ".join(f"A_{{{i}}}" for i in range(1, m.n + 1))
        if m.chain.tool != sp.eye(4):
            product += r" T_{\mathrm{tool}}"
    else:
        product = ""
    if m.program:
        base = "T_0 " if m.chain.base != sp.eye(4) else ""
        body = ("\\begin{equation*}\n" + f"{pose_name(m)} = {base}{product}" + w.tag("fk") + "\n\\end{equation*}"
                + _PROGRAM_NOTE.format(steps=len(m.program), reason=_program_reason(m)))
        return Section("fk", "Tool pose", body + "\n")
    body = w.matrix_equation(pose_name(m), m.fk, key="fk", skip_last_row=True, product=product)
    return Section("fk", "Tool pose", body + "\n")


_PROGRAM_NOTE = ("\nThe product is not expanded: {reason}, so nothing cancels in its entries, which written out "
                 "would run to hundreds of terms each. The kernels compute it as the link transforms say, one link "
                 "at a time, with the Jacobians and their rates from the same frames: a straight-line program of "
                 "{steps} steps (\\texttt{{kinegen show --what fk}} prints it).\n")


def _program_reason(m) -> str:
    from derivations.chain_program import EXPLICIT_MAX_JOINTS, has_floats
    if has_floats(m.chain):
        return "its numbers are as the description writes them, not exact values"
    if m.n > EXPLICIT_MAX_JOINTS:
        return f"the arm has {m.n} joints"
    return "its link transforms do not cancel in the product"


_POSE_ROTATION = re.compile(r"r\d\d")


def _task_latex(w: _Writer, name: str) -> str:
    return w.layout.tex(sp.Symbol(name, real=True))


def _position(w: _Writer) -> Section:
    m = w.model
    if m.program:
        return Section("position", "Task coordinates",
                       "The task coordinates are the tool point (the last column of $T$)"
                       + (" and the entries $r_{ij} = T_{ij}$ of its rotation" if "r11" in m.task_names else "")
                       + ".\n")
    pairs = [(_task_latex(w, n), e) for n, e in zip(m.task_names, m.task) if not _POSE_ROTATION.fullmatch(n)]
    body = w.equations(pairs, key="position")
    if any(_POSE_ROTATION.fullmatch(n) for n in m.task_names):
        body += "\nand $r_{ij} = T_{ij}$ for the rotation entries of the task vector.\n"
    return Section("position", "Task coordinates", body + "\n")


def _jacobian(w: _Writer) -> Section:
    m = w.model
    intro = (r"Geometric Jacobian $J = [J_v;\ J_\omega]$ of the tool point $o_n$ in the base frame: the "
             r"column of a revolute joint with axis $z$ through $o$ is $[z \times (o_n - o);\ z]$, that of a "
             r"prismatic joint $[z;\ 0]$ (velocity slides; $z = z_{i-1}$, $o = o_{i-1}$ in standard DH).")
    if m.program:
        return Section("jacobian", "Geometric Jacobian",
                       intro + " Each column is computed from the frames of the product above, as written.\n")
    body = w.matrix_equation("J", m.jacobian, key="jacobian")
    return Section("jacobian", "Geometric Jacobian", intro + "\n" + body + "\n")


def _task_jacobian(w: _Writer) -> Section:
    m = w.model
    rows = [k for k, n in enumerate(m.task_names) if not _POSE_ROTATION.fullmatch(n)]
    J = m.task_jacobian.extract(rows, list(range(m.n)))
    names = ", ".join(_task_latex(w, m.task_names[k]) for k in rows)
    intro = rf"Task Jacobian $J_x = \partial ({names}) / \partial q$"
    if m.program:
        return Section("task_jacobian", "Task Jacobian", intro + (
            r": the rows of the tool point are the rows $J_v$ of the geometric Jacobian, and the rate of its rotation "
            r"is $\partial R / \partial q_j = [z_j]_\times R$ for a revolute joint $j$ with axis $z_j$." "\n"))
    if len(rows) < len(m.task_names):
        intro += r" (the rows of the rotation entries $r_{ij}$ are left out: their rates are $J_\omega$)"
    body = w.matrix_equation("J_x", J, key="task_jacobian", entry="J_{{x,{ij}}}")
    return Section("task_jacobian", "Task Jacobian", intro + ":\n" + body + "\n")


def _det(w: _Writer, determinant: JacobianDeterminant | None) -> Section:
    m = w.model
    if m.program:
        return Section("det", "Singularities", (
            "The determinant is not worked out in closed form for an arm whose product is not expanded. The rate "
            "kernels find singular configurations numerically, by the condition number of the normalised "
            "Jacobian.\n"))
    if determinant is None:
        shape = m.task_jacobian.shape
        text = (f"The task Jacobian is ${shape[0]} \\times {shape[1]}$ and the geometric one "
                f"$6 \\times {m.n}$: neither is square, so there is no determinant to print.\n")
        return Section("det", "Singularities", text)
    name = "J_x" if determinant.which == "task_jacobian" else "J"
    if not determinant.factored:
        text = (f"$\\det {name}$ is not factored: as a polynomial in the sines and cosines of the joints it "
                f"has at least {determinant.size} operations unexpanded, more than the {FACTOR_LIMIT} up to which the "
                "singular families are worked out in closed form. The rate kernels find singular "
                "configurations numerically, by the condition number of the normalised Jacobian.\n")
        return Section("det", "Singularities", text)
    body = w.display(rf"\det {name}", determinant.value, key="det")
    if determinant.which == "jacobian":
        body = ("The determinant of the geometric Jacobian does not depend on the reference point or the frame; "
                "with the wrist-partitioned form $[A\\ 0;\\ C\\ D]$ of the velocity slides it is "
                "$\\det A \\det D$:\n" + body)
    if not determinant.singular:
        body += "\nIt never vanishes for nonzero parameters: the arm has no singular configuration.\n"
        return Section("det", "Singularities", body)
    conditions = []
    for factor, zeros in determinant.singular:
        if zeros:
            conditions.append(r" \text{ or } ".join(
                f"{w.layout.tex(z.lhs)} = {w.layout.tex(z.rhs)}" for z in zeros))
        else:
            conditions.append(f"{w.layout.tex(factor)} = 0")
    constant = [f for f in determinant.factors if not (f.free_symbols & set(m.q)) and not f.is_number]
    letter = "q_i" if any(text.startswith("q_") for text in w.printer.joint_latex.values()) else "\\theta_i"
    lead = f"Singular configurations (one turn, $-\\pi < {letter} \\le \\pi$)"
    if constant:
        lead += " for nonzero " + ", ".join(f"${w.layout.tex(f)}$" for f in constant)
    rows = [rf"&{c}" for c in conditions]
    rows[0] += w.tag("singular")
    body += "\n" + lead + ":\n" + "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}\n"
    return Section("det", "Singularities", body)


# The rows of the forward rate map are written out up to this many operations each (the
# papers' largest, the SCORBOT's: 69; a UR5's: 130); a general 6R's run to 800 and a
# Panda's to 1,555, pages that say no more than J_x, which is printed above them.
RATE_ROW_MAX_OPS = 300


def _rates(w: _Writer, determinant: JacobianDeterminant | None) -> Section:
    m = w.model
    if m.program:
        return Section("rates", "Rate maps", (
            r"Forward rate map $\dot x = J_x \dot q$, with $J_x$ as above; its inverse and the accelerations are "
            "solved at run time, from the same frames.\n"))
    rows = [k for k, n in enumerate(m.task_names) if not _POSE_ROTATION.fullmatch(n)]
    rates = [rate_symbol(qi) for qi in m.q]
    trig = sorted(m.task_jacobian.atoms(sp.sin, sp.cos), key=sp.default_sort_key)
    values = [sp.expand((m.task_jacobian.row(k) * sp.Matrix(rates))[0]) for k in rows]
    longest = max((int(sp.count_ops(v)) for v in values), default=0)
    if longest > RATE_ROW_MAX_OPS:
        body = (r"Forward rate map $\dot x = J_x \dot q$, with $J_x$ as above: its rows written out would run "
                f"to {longest} operations, more than the {RATE_ROW_MAX_OPS} up to which they are printed.\n")
        values = []
    pairs = []
    for k, value in zip(rows, values):
        # Kumar's and the slides' grouping, -l1 s1 th1' - l2 s12 (th1' + th2'), when each sine or
        # cosine then has a constant coefficient; otherwise by joint rate, J_k1 th1' + J_k2 th2' + ...
        by_trig = sp.collect(value, trig, evaluate=False) if trig else {}
        keys = trig if by_trig and not any(c.has(sp.sin, sp.cos) for c in by_trig.values()) else rates
        pairs.append((rf"\dot{{{_task_latex(w, m.task_names[k])}}}", _rates_last(_grouped(value, keys), rates)))
    if pairs:
        body = (r"Forward rate map $\dot x = J_x \dot q$:" + "\n" + w.equations(pairs, key="rates") + "\n")
    inverse = inverse_rate_map(m, determinant)
    if inverse is not None:
        adjugate, det = inverse
        task_rates = [task_rate_symbol(n) for n in m.task_names]
        rows_tex: list[str] = []
        for i, qi in enumerate(m.q):
            numerator = sp.expand((adjugate.row(i) * sp.Matrix(task_rates))[0])
            numerator, denominator = sp.fraction(sp.cancel(numerator / det))
            denominator = sp.factor(denominator)
            if denominator.could_extract_minus_sign():
                numerator, denominator = -numerator, -denominator
            numerator = _rates_last(_grouped(sp.expand(numerator), task_rates), task_rates)
            rows_tex.extend(_fraction_rows(w, _dotted(w.printer.joint_latex[qi]), numerator, denominator))
        rows_tex[0] += w.tag("inverse_rates")
        body += (r"Inverse rate map $\dot q = J_x^{-1} \dot x = \operatorname{adj}(J_x)\, \dot x / \det J_x$, "
                 r"away from the singular set:" + "\n" + _Writer._align(rows_tex) + "\n")
    elif determinant is not None and determinant.which == "task_jacobian":
        body += (f"The inverse rate map is $\\dot q = J_x^{{-1}} \\dot x$ away from the singular set "
                 f"(its closed form is not printed for {m.n} joints).\n")
    return Section("rates", "Rate maps", body)


def _grouped(expr: sp.Expr, keys) -> sp.Expr:
    """``expr`` collected on ``keys``, each coefficient with its common factor and sign taken out."""
    if not keys:
        return expr
    collected = sp.collect(expr, list(keys))
    with distribute(False):
        return sp.Add(*[sp.factor_terms(t) for t in sp.Add.make_args(collected)])


def _rates_last(expr: sp.Expr, rates) -> sp.Expr:
    """Print rates after the other factors (``l_1 s_1 \\dot\\theta_1``, as the papers write).

    SymPy prints a product's commutative factors first and its non-commutative
    ones last, in their given order, so the rates are swapped for
    non-commutative twins printed with the same name.
    """
    with distribute(False):
        return expr.xreplace({r: _NonCommutativeRate(r) for r in rates})


class _NonCommutativeRate(sp.Symbol):
    """A rate symbol that sorts after the other factors of a product when printed."""

    def __new__(cls, rate: sp.Symbol):
        obj = super().__new__(cls, rate.name, commutative=False)
        obj.rate = rate
        return obj

    def __getnewargs_ex__(self):
        return ((self.rate,), {})


def _fraction_rows(w: _Writer, lhs: str, numerator: sp.Expr, denominator: sp.Expr) -> list[str]:
    """``lhs = numerator / denominator``, the numerator broken if too long."""
    if numerator == 0:
        return [f"{lhs} &= 0"]
    if denominator == 1:
        return w.layout.align_rows(lhs, numerator)
    den = w.layout.tex(denominator)
    text = rf"\frac{{{w.layout.tex(numerator)}}}{{{den}}}"
    if math_width(lhs) + 3 + math_width(text) <= w.layout.width:
        return [f"{lhs} &= {text}"]
    head = rf"\frac{{1}}{{{den}}}\bigl("
    parts = w.layout.lines(numerator, w.layout.width - math_width(lhs) - math_width(head) - 4)
    parts[0] = head + parts[0]
    parts[-1] += r"\bigr)"
    return [f"{lhs} &= {parts[0]}"] + [rf"&\quad {p}" for p in parts[1:]]


def _clamped_argument(e):
    """``c`` if ``e`` is ``Min(1, Max(-1, c))`` (``derivations.ik.clamp_unit``), else None."""
    if isinstance(e, sp.Min) and len(e.args) == 2 and sp.S.One in e.args:
        (inner,) = [a for a in e.args if a != 1]
        if isinstance(inner, sp.Max) and len(inner.args) == 2 and sp.S.NegativeOne in inner.args:
            (c,) = [a for a in inner.args if a != -1]
            return c
    return None


@functools.lru_cache(maxsize=4096)
def unclamped(expr):
    """``expr`` as mathematics: an ``acos`` argument clamped for the kernels, ``Min(1, Max(-1, c))``, is ``c``;
    the existence tolerance ``|c| <= 1 + ACOS_TOLERANCE`` reads ``|c| <= 1``.  The IK section says once
    what the kernels do at the edge.  Remembered: the branches of a derived ik share most of their
    steps (Romeo's 8 branches: 328 steps, 0.5 s of its LaTeX)."""
    expr = sp.sympify(expr).replace(lambda e: _clamped_argument(e) is not None, _clamped_argument)
    expr = expr.replace(lambda e: isinstance(e, ClampUnit), lambda e: e.args[0])
    expr = expr.xreplace({TINY: sp.S.Zero})  # the 1e-300 that keeps a generated division finite
    return expr.xreplace({1 + ACOS_TOLERANCE: sp.S.One})


def _joint_value(expr):
    """A revolute joint's value as printed: the kernels' wrap to (-pi, pi] (stated once) left out."""
    return expr.args[0] if isinstance(expr, WrapAngle) else expr


_ACOS_EDGE = (r"An $\arccos$ whose argument lies within $10^{-12}$ beyond $\pm 1$ is taken at $\pm 1$, "
              r"so that a target within rounding of the workspace edge solves.")


def _ik_conventions(w: _Writer) -> str:
    """What the kernels do that the printed solutions leave out, said once: the wrap of angles to (-pi, pi]
    and the clamp of arccos arguments."""
    m = w.model
    if type(m).ik_function is RobotModel.ik_function:  # every revolute joint wrapped (derivations.ik.kernel_form)
        return r"Revolute joint angles are taken in $(-\pi, \pi]$ (modulo $2\pi$). " + _ACOS_EDGE
    wrapped = sorted({i for b in m.ik for i, e in enumerate(b.solution) if isinstance(e, WrapAngle)})
    if not wrapped:
        return _ACOS_EDGE
    names = ", ".join(f"${w.printer.joint_latex[m.q[i]]}$" for i in wrapped)
    return rf"The joint angle{'s' if len(wrapped) > 1 else ''} {names} {'are' if len(wrapped) > 1 else 'is'} " \
           r"taken in $(-\pi, \pi]$ (modulo $2\pi$). " + _ACOS_EDGE


# An IK step whose LaTeX is longer than this many characters is named, not typeset.  The papers'
# longest step is 248 characters and a KUKA KR 210's 401; the Romeo arm held at joint 3 has 328 steps
# of up to 13,393 characters (1.3 MB of LaTeX, 35 s of line breaking, 350 pages of report) that
# nobody reads: the generated ik computes them.
IK_STEP_TEX_LIMIT = 2000


def _ik(w: _Writer) -> Section | None:
    m = w.model
    if not m.ik:
        return None
    parts = [_ik_conventions(w) + "\n"]
    for branch in m.ik:
        header = rf"\paragraph{{Branch \texttt{{{escape_text(branch.name)}}}}}"
        if branch.doc:
            header += " " + escape_text(branch.doc).rstrip(".") + "."
        key = f"ik:{branch.name}" if f"ik:{branch.name}" in w.citations else "ik"
        if branch.steps:
            # The derivation as the paper or textbook writes it, in its order: each step in the ones
            # before (the flat solution of a 6R arm runs to kilobytes per joint), each tagged with
            # the paper's equation where the model names it.
            cites = branch.step_cites or ("",) * len(branch.steps)
            rows: list[str] = []
            names = itertools.count(1)
            for (symbol, expr), cite in zip(branch.steps, cites):
                lhs = w.printer.joint_latex.get(symbol, w.layout.tex(symbol))
                value = unclamped(_joint_value(expr))
                tag = rf" \tag{{{cite}}}" if cite else ""
                size = len(w.layout.tex(value))
                if size > IK_STEP_TEX_LIMIT:  # named, not typeset (see IK_STEP_TEX_LIMIT)
                    rows.append(rf"{lhs} &= \text{{(a closed form of {size:,} characters of \LaTeX: "
                                rf"in the package's \texttt{{ik}})}}{tag}")
                    continue
                rows.extend(w.layout.fitted_rows(lhs, value, names=names, tag=tag))
            if not any(cites) and rows:
                rows[0] += w.tag(key)
            body = header + " In steps, each using the ones before it:\n" + _Writer._align(rows) + "\n"
        else:
            pairs = [(w.printer.joint_latex[qi], unclamped(_joint_value(expr)))
                     for qi, expr in zip(m.q, branch.solution)]
            body = header + "\n" + w.equations(pairs, key=key) + "\n"
        # A decomposed branch's condition in its step symbols: substituted, it runs to kilobytes.
        condition = branch.condition if branch.step_condition is None else branch.step_condition
        if condition is not sp.true and condition != sp.true:
            condition = unclamped(condition)
            args = condition.args if isinstance(condition, sp.And) else (condition,)
            rows = [row for a in args for row in _condition_rows(w, a)]
            if sum(len(r) for r in rows) > (200 if branch.steps else 600):
                body += ("It exists where the square roots and inverse cosines of its steps are real "
                         "(the condition, written out, is in the generated kernels).\n")
            else:
                body += "It exists when\n" + _Writer._align(rows) + "\n"
        parts.append(body)
    return Section("ik", "Inverse kinematics", "\n".join(parts))


# A relation written the other way round: b > a for a < b.
_RELATION_TEX = {sp.Le: (r"\leq", r"\geq"), sp.Ge: (r"\geq", r"\leq"), sp.Lt: ("<", ">"), sp.Gt: (">", "<"),
              sp.Eq: ("=", "="), sp.Ne: (r"\neq", r"\neq")}


def _condition_rows(w: _Writer, condition) -> list[str]:
    """One condition of a branch as rows of its ``align*``: on one row where it fits, else its
    wider side broken over lines (after naming parts, see MathLayout.fitted_rows), the narrower
    side first."""
    text = w.layout.tex(condition)
    # (math_width errs narrow here: the Z1's condition of 0.86 of the width ran 10 pt past the page)
    if math_width(text) <= 0.8 * w.layout.width or type(condition) not in _RELATION_TEX:
        return [rf"&{text}"]
    relation, reverse = _RELATION_TEX[type(condition)]
    lhs, rhs = condition.lhs, condition.rhs
    if math_width(w.layout.tex(lhs)) > math_width(w.layout.tex(rhs)):
        lhs, rhs, relation = rhs, lhs, reverse
    return w.layout.fitted_rows(w.layout.tex(lhs), rhs, relation=relation)


# The mass matrix and gravity vector are printed in closed form for arms of at most this many
# joints whose entries, the program's steps put in and expanded, stay at most DYNAMICS_MAX_OPS
# operations each; a larger arm's equations are programs of hundreds of steps.
DYNAMICS_MAX_JOINTS = 3
DYNAMICS_MAX_OPS = 60


def _dynamics(w: _Writer) -> Section | None:
    """The inertial parameters, gravity, and (for a small arm) M(q) and g(q) in closed form."""
    m = w.model
    if not getattr(m, "inertials", ()):
        return None
    tex = w.layout.tex
    def cell(value) -> str:  # a number to 4 significant digits (the table's say so), a parameter by name
        value = sp.sympify(value)
        if value.is_Number:
            text = f"{float(value):.4g}"
            return text if "e" not in text else sp.latex(sp.Float(float(value), 4))
        return tex(value)

    masses, tensors = [], []
    for k, inertial in enumerate(m.inertials, start=1):
        masses.append(f"{k} & ${cell(inertial.mass)}$ & " + " & ".join(f"${cell(c)}$" for c in inertial.com) + r" \\")
        tensors.append(f"{k} & " + " & ".join(f"${cell(c)}$" for c in inertial.inertia) + r" \\")
    # Two tables, a number a column: one row of both in a table ran 178 pt past the page (KR 210).
    text = (r"Equations of motion $M(q)\,\ddot q + C(q, \dot q)\,\dot q + g(q) = \tau$ by recursive "
            r"Newton--Euler, $M$ by composite rigid bodies, $C$ from the Christoffel symbols (docs/dynamics.md). "
            r"Each link's mass and centre of mass $c$ (frame $k$), and its inertia about $c$, to four "
            r"significant digits (the kernels take the description's numbers):" "\n"
            "\\begin{center}\\small\n\\begin{tabular}{lllll}\n"
            r"link & mass & $c_x$ & $c_y$ & $c_z$ \\ \hline" "\n" + "\n".join(masses)
            + "\n\\end{tabular}\n\n\\medskip\n\\begin{tabular}{lllllll}\n"
            r"link & $I_{xx}$ & $I_{xy}$ & $I_{xz}$ & $I_{yy}$ & $I_{yz}$ & $I_{zz}$ \\ \hline" "\n"
            + "\n".join(tensors) + "\n\\end{tabular}\n\\end{center}\n"
            + f"Gravity in the base frame: $({', '.join(tex(e) for e in m.gravity)})$.\n")
    dynamics = m.dynamics
    if dynamics is None:
        return Section("dynamics", "Dynamics", text + escape_text(m.notes.get("dynamics", "")) + "\n")
    text += _actuators(m, cell)
    if m.n > DYNAMICS_MAX_JOINTS:
        return Section("dynamics", "Dynamics", text + f"The equations are a straight-line program of "
                       f"{len(dynamics.program)} steps (not printed in closed form past {DYNAMICS_MAX_JOINTS} joints).\n"
                       + _base_parameters(m))
    from derivations.program import inline

    def closed(e):
        return sp.factor_terms(sp.trigsimp(sp.expand(inline(dynamics.program, e))))
    M = sp.Matrix(m.n, m.n, lambda i, j: closed(dynamics.mass_matrix[i, j]) if i <= j else 0)
    M = sp.Matrix(m.n, m.n, lambda i, j: M[min(i, j), max(i, j)])
    g = sp.Matrix([closed(e) for e in dynamics.gravity])
    if max(sp.count_ops(e) for e in list(M) + list(g)) > DYNAMICS_MAX_OPS:
        return Section("dynamics", "Dynamics", text + "Their entries in closed form pass "
                       f"{DYNAMICS_MAX_OPS} operations each and are not printed.\n" + _base_parameters(m))
    body = w.matrix_equation("M(q)", M, key="mass_matrix", entry="M_{{{ij}}}") + "\n"
    body += w.matrix_equation("g(q)", g, key="gravity", entry="g_{{{ij}}}") + "\n"
    return Section("dynamics", "Dynamics", text + body + _base_parameters(m))


def _actuators(m, cell) -> str:
    """The actuators' table (armature and friction per joint), or nothing for an arm without."""
    actuators = getattr(m, "actuators", ())
    if not actuators:
        return ""
    from derivations.mechanics.inertia import Actuator
    rows = [f"{k} & " + " & ".join(f"${cell(v)}$" for v in (a.rotor_inertia, a.gear_ratio, a.armature, a.viscous,
                                                             a.coulomb)) + r" \\"
            for k, a in enumerate((a or Actuator() for a in actuators), start=1)]
    return (r"Actuators: each joint's rotor inertia $I_r$ through its gear ratio $G$ adds the armature "
            r"$I_a = I_r G^2$ to $M$'s diagonal; viscous $F_v$ and Coulomb $F_c$ friction add "
            r"$F_v \dot q + F_c \operatorname{sign}(\dot q)$ to $\tau$ ($\operatorname{sign}(0) = 0$):" "\n"
            "\\begin{center}\\small\n\\begin{tabular}{llllll}\n"
            r"joint & $I_r$ & $G$ & $I_a$ & $F_v$ & $F_c$ \\ \hline" "\n" + "\n".join(rows)
            + "\n\\end{tabular}\n\\end{center}\n")


# A standard parameter's name (derivations.dynamics.parameter_names: m1, mx1, ..., izz1, ia1, fv1, fc1)
# in LaTeX: the letters upright, the link or joint as a subscript.
_PARAMETER_NAME = re.compile(r"([a-z]+)(\d+)")


def base_parameter_rows(m) -> list[str]:
    """Each base parameter ``\\beta_k = ...`` as inline LaTeX (a line of its own, breaking at its
    signs), coefficients to four significant digits."""
    from derivations.mechanics.dynamics import base_terms, model_base_parameters
    kept, dropped, K, names = model_base_parameters(m)

    def name(i: int) -> str:
        letters, number = _PARAMETER_NAME.fullmatch(names[i]).groups()
        return rf"\mathrm{{{letters}}}_{{{number}}}"

    def number(c: float) -> str:
        text = f"{c:.4g}"
        if "e" in text:
            mantissa, exponent = text.split("e")
            text = rf"{mantissa} \cdot 10^{{{int(exponent)}}}"
        return text
    rows = []
    for row in range(len(kept)):
        (_, own), *rest = base_terms(kept, dropped, K, row)
        text = name(own)
        for c, d in rest:
            coefficient = "" if f"{abs(c):.4g}" == "1" else number(abs(c)) + r"\,"
            text += f" {'-' if c < 0 else '+'} {coefficient}{name(d)}"
        rows.append(rf"$\beta_{{{row + 1}}} = {text}$")
    return rows


def _base_parameters(m) -> str:
    """The base parameters paragraph of the dynamics section."""
    from derivations.mechanics.dynamics import parameter_names
    rows = base_parameter_rows(m)
    count = len(parameter_names(m.n, actuators=bool(getattr(m, "actuators", ()))))
    return (f"Base parameters: the {len(rows)} combinations of the {count} standard parameters (per link "
            r"$\mathrm{m}$, $\mathrm{mx}, \mathrm{my}, \mathrm{mz}$ = $m c$ and $\mathrm{ixx} \ldots \mathrm{izz}$, "
            r"the inertia about the origin of frame $k$" + (r"; per joint $\mathrm{ia}, \mathrm{fv}, \mathrm{fc}$ = "
                                                           r"$I_a, F_v, F_c$" if getattr(m, "actuators", ()) else "")
            + r") that the torques determine, $\tau = Y_b(q, \dot q, \ddot q)\,\beta$: a numeric QR of the "
            r"regressor at 40 random states (Gautier, 1991), at the parameters' defaults, coefficients to four "
            "significant digits.\n\n" + "\\\\\n".join(rows) + "\n")


def _notes(w: _Writer) -> Section | None:
    notes = {k: v for k, v in w.model.notes.items() if not k.startswith("cite_")}
    if not notes:
        return None
    items = "\n".join(rf"\item \textbf{{{escape_text(k)}}}: {escape_text(v)}" for k, v in sorted(notes.items()))
    return Section("notes", "Notes", "\\begin{itemize}\n" + items + "\n\\end{itemize}\n")


# --------------------------------------------------------------------------- extras

# What a model carries for the verifier, not the reader: never printed.
_NOT_PRINTED = {"sample_ranges", "program",  # a program is printed as its product (see _fk)
                "inertials", "gravity", "actuators"}  # printed by _dynamics


def _extras(w: _Writer) -> list[Section]:
    """Sections for whatever else the model carries (rate maps, singularities, ...)."""
    sections = []
    for name, value in sorted(vars(w.model).items()):
        if name in _KNOWN_ATTRIBUTES | _NOT_PRINTED or name.startswith("_") or not _has_symbols(value):
            continue
        body = _generic(w, name, value, depth=0)
        if body.strip():
            sections.append(Section(name, escape_text(name.replace("_", " ").capitalize()), body))
    return sections


def _has_symbols(value, depth: int = 0) -> bool:
    if depth > 4:
        return False
    if isinstance(value, (sp.Basic, sp.MatrixBase)):
        return True
    if isinstance(value, dict):
        return any(_has_symbols(v, depth + 1) for v in value.values())
    if isinstance(value, (list, tuple)):
        return any(_has_symbols(v, depth + 1) for v in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return any(_has_symbols(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value))
    return False


def _generic(w: _Writer, label: str, value, depth: int) -> str:
    """Print an unknown structure: matrices, expressions, relations, and what holds them."""
    if depth > 4:
        return ""
    name = _label_latex(label)
    if isinstance(value, sp.MatrixBase):
        return w.matrix_equation(name, sp.Matrix(value), key=label) + "\n"
    if isinstance(value, sp.Basic):
        if isinstance(value, (sp.Expr,)):
            return w.display(name, value, key=label) + "\n"
        return f"\\begin{{align*}}\n&{w.layout.tex(value)}{w.tag(label)}\n\\end{{align*}}\n"
    if isinstance(value, dict):
        return "".join(_generic(w, str(k), v, depth + 1) for k, v in value.items() if _has_symbols(v))
    if isinstance(value, (list, tuple)):
        if value and all(isinstance(v, sp.Expr) for v in value):
            return w.equations([(f"{name}_{{{k + 1}}}", v) for k, v in enumerate(value)], key=label) + "\n"
        return "".join(_generic(w, label, v, depth + 1) for v in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        title = getattr(value, "name", None)
        out = rf"\paragraph{{{escape_text(str(title))}}}" + "\n" if isinstance(title, str) else ""
        doc = getattr(value, "doc", None)
        if isinstance(doc, str) and doc:
            out += escape_text(doc) + "\n"
        for f in dataclasses.fields(value):
            if f.name in ("name", "doc"):
                continue
            item = getattr(value, f.name)
            if _has_symbols(item):
                out += _generic(w, f.name, item, depth + 1)
        return out
    return ""


def _label_latex(label: str) -> str:
    """A field name as a math symbol: ``condition -> \\mathrm{condition}``."""
    if re.fullmatch(r"[A-Za-z]", label):
        return label
    return r"\mathrm{" + escape_text(label) + "}"


# --------------------------------------------------------------------------- files

def render(model, origin: str) -> dict[str, str]:
    """``{<name>.tex: fragment}`` for one robot."""
    text = TEMPLATES.get_template("robot.tex.j2").render(
        name=model.name, title=escape_text(model.title), source=escape_text(model.source), origin=origin,
        sections=robot_sections(model))
    return {f"{model.name}.tex": text}


def latex_for(model, what: list[str] | None = None) -> str:
    """The LaTeX of the chosen sections (all when ``what`` is empty), for the terminal."""
    sections = robot_sections(model)
    if what:
        known = [s.key for s in sections]
        unknown = [k for k in what if k not in known]
        if unknown:
            raise ValueError(f"latex: {model.name} has no section {unknown[0]!r} "
                             f"(expected one of {', '.join(known)})")
        sections = [s for s in sections if s.key in what]
    return "\n".join(f"% {s.title}\n{s.body}" for s in sections)

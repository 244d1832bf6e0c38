"""Fitting LaTeX math to the page: an estimate of its printed width and the line breaking.

:func:`math_width` estimates the width of inline math from its LaTeX text (in units of about one
italic letter); :class:`MathLayout` breaks what is too wide for a line: a long sum over several
aligned lines, a wide matrix into its entries, each entry broken the same way, and a part too wide
to break given a name of its own.  The report build checks the estimate against pdflatex's own
overfull-box warnings.  :func:`escape_text` makes plain text safe for pdflatex.
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass

import sympy as sp

from .latex_printer import KinematicsLatexPrinter

__all__ = ["LINE_WIDTH", "FIT_SLACK", "math_width", "MathLayout", "escape_text"]

# Width of a display line in math_width units (about one italic letter at 11 pt):
# the report's text block is 16 cm; the margin leaves room for a tag on the first line.
LINE_WIDTH = 66.0
# A line that cannot be broken is given named parts only past this multiple of the width.
FIT_SLACK = 1.03


# --------------------------------------------------------------------------- widths

_ZERO_WIDTH = {"left", "right", "bigl", "bigr", "Bigl", "Bigr", "biggl", "biggr", "displaystyle", "textstyle",
               "mathrm", "mathbf", "mathit", "operatorname", "text", "dot", "ddot", "bar", "hat", "tilde", "vec",
               "begin", "end", "limits", "nolimits", "tag", "label", "notag", "nonumber"}
_SPACES = {",": 0.3, ";": 0.5, ":": 0.4, "!": -0.2, " ": 0.4, "quad": 1.8, "qquad": 3.6}
_RELATIONS = {"leq", "geq", "neq", "le", "ge", "ne", "wedge", "vee", "iff", "implies", "to", "in", "cdot",
              "times", "pm", "mp", "approx", "equiv", "mapsto", "land", "lor", "neg"}
_OPERATORS = {"sin": 2.4, "cos": 2.6, "tan": 2.4, "arcsin": 5.0, "arccos": 5.2, "arctan": 5.0, "det": 2.4,
              "sqrt": 1.2, "log": 2.2, "exp": 2.4, "min": 2.7, "max": 2.8}


def math_width(tex: str) -> float:
    """Estimated printed width of inline LaTeX math, in units of about one italic letter.

    Deliberately a little pessimistic: a binary operator with its spacing counts
    2.2, a sub- or superscript 0.7 of its content, a fraction the wider of its
    numerator and denominator.
    """
    return _Width(tex).group(until=None)


class _Width:
    def __init__(self, text: str):
        self.text = text
        self.i = 0

    def group(self, until: str | None) -> float:
        width = 0.0
        while self.i < len(self.text):
            ch = self.text[self.i]
            if until is not None and ch == until:
                self.i += 1
                return width
            self.i += 1
            if ch == "\\":
                width += self.command()
            elif ch == "{":
                width += self.group("}")
            elif ch in "_^":
                width += 0.7 * self.argument()
            elif ch in " \n\t&}":
                continue
            elif ch in "+-=<>":
                width += 2.2
            elif ch in "()[],.;|'":
                width += 0.6
            else:
                width += 1.0
        return width

    def argument(self) -> float:
        while self.i < len(self.text) and self.text[self.i] == " ":
            self.i += 1
        if self.i >= len(self.text):
            return 0.0
        ch = self.text[self.i]
        self.i += 1
        if ch == "{":
            return self.group("}")
        if ch == "\\":
            return self.command()
        return 1.0

    def command(self) -> float:
        match = re.match(r"[A-Za-z]+|.", self.text[self.i:])
        if match is None:
            return 0.0
        name = match.group(0)
        self.i += len(name)
        if name in ("frac", "dfrac", "tfrac"):
            return max(self.argument(), self.argument()) + 0.4
        if name in ("left", "right", "bigl", "bigr", "Bigl", "Bigr", "biggl", "biggr"):
            self.i += 1 if self.text[self.i:self.i + 1] != "\\" else 0
            return 0.6
        if name in ("begin", "end", "tag", "label", "text", "operatorname", "mathrm"):
            inner = self.argument()
            return 0.0 if name in ("begin", "end", "tag", "label") else inner
        if name in ("sqrt",):
            return 1.2 + self.argument()
        if name in _SPACES:
            return _SPACES[name]
        if name in _RELATIONS:
            return 2.4
        if name in _OPERATORS:
            return _OPERATORS[name]
        if name in _ZERO_WIDTH:
            return 0.0
        return 1.1  # a Greek letter or another symbol


# --------------------------------------------------------------------------- layout

def escape_text(text: str) -> str:
    """Plain text (a note, a docstring) made safe for pdflatex; a control character (a newline in a
    title, which would end the ``%`` comment it is printed in) becomes a space."""
    text = "".join(" " if ord(ch) < 32 or 127 <= ord(ch) < 160 else ch for ch in str(text))
    replacements = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
                    # OT1 text fonts print < > | as inverted marks and a dash: set them as math
                    "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}"}
    out = "".join(replacements.get(ch, ch) for ch in text)
    unicode = {"θ": r"$\theta$", "φ": r"$\phi$", "π": r"$\pi$", "°": r"$^\circ$", "±": r"$\pm$", "×": r"$\times$",
               "≤": r"$\le$", "≥": r"$\ge$", "−": "-", "–": "--", "—": "---", "’": "'", "“": "``", "”": "''",
               "α": r"$\alpha$", "β": r"$\beta$", "γ": r"$\gamma$", "σ": r"$\sigma$", "·": r"$\cdot$"}
    out = "".join(unicode.get(ch, ch if ord(ch) < 128 else "?") for ch in out)
    return out


@dataclass
class MathLayout:
    """Lays out equations and matrices so that each line fits ``width``."""

    printer: KinematicsLatexPrinter
    width: float = LINE_WIDTH

    def tex(self, expr) -> str:
        return self.printer.doprint(expr)

    # Sums broken over lines ------------------------------------------------
    def pieces(self, expr, limit: float) -> list[tuple[str, str]]:
        """``expr`` as (operator, text) pieces, each of which may start a new line.

        A sum gives one piece per term (operator ``+`` or ``-``; the first piece
        has ``""`` or ``-``); a term still wider than ``limit`` that is a product
        with a sum in it is opened up: ``c_1 \\bigl(a_1 + a_2 c_2 ... \\bigr)``.
        """
        terms = self.printer._as_ordered_terms(expr) if isinstance(expr, sp.Add) else [expr]
        out: list[tuple[str, str]] = []
        for k, term in enumerate(terms):
            sign = "+"
            if isinstance(expr, sp.Add) and term.could_extract_minus_sign():
                sign, term = "-", -term
            if k == 0:
                sign = "-" if sign == "-" else ""
            text = self.tex(term)
            if isinstance(expr, sp.Add) and self.printer._needs_add_brackets(term):
                text = rf"\left({text}\right)"
            opened = self._open_product(term, limit) if math_width(text) > limit else None
            if opened:
                out.append((sign, opened[0][1]))
                out.extend(opened[1:])
            else:
                out.append((sign, text))
        return out

    def _open_product(self, term, limit: float) -> list[tuple[str, str]] | None:
        if not isinstance(term, sp.Mul):
            return None
        sums = [f for f in term.args if isinstance(f, sp.Add)]
        if not sums:
            return None
        widest = max(sums, key=lambda f: math_width(self.tex(f)))
        inner = self.pieces(widest, limit)
        if len(inner) < 2:
            return None
        rest = term / widest
        head = "" if rest == 1 else ("-" if rest == -1 else self.tex(rest) + " ")
        first_op, first_text = inner[0]
        inner[0] = ("", rf"{head}\bigl({first_op}{first_text}")
        inner[-1] = (inner[-1][0], inner[-1][1] + r"\bigr)")
        return inner

    def lines(self, expr, first: float) -> list[str]:
        """``expr`` broken into lines; ``first`` is the width left on the first line.

        A continuation line starts ``{}+ ...`` so that its sign keeps binary spacing.
        """
        text = self.tex(expr)
        if math_width(text) <= first:
            return [text]
        lines: list[str] = []
        current, room = "", first
        for op, piece in self.pieces(expr, self.width - 8):
            if not current:
                current = (f"{{}}{op} {piece}" if op else piece) if lines else f"{op}{piece}"
                continue
            joined = f"{current} {op} {piece}" if op else f"{current} {piece}"
            if math_width(joined) > room:
                lines.append(current)
                room = self.width - 4
                current = f"{{}}{op} {piece}" if op else piece
            else:
                current = joined
        lines.append(current)
        return lines

    def align_rows(self, lhs: str, expr, relation: str = "=") -> list[str]:
        """Rows of an ``align*``: ``lhs &= ...`` then ``&\\quad ...`` continuation lines."""
        first = self.width - math_width(lhs) - 3
        parts = self.lines(expr, first)
        rows = [f"{lhs} &{relation} {parts[0]}"]
        rows.extend(rf"&\quad {part}" for part in parts[1:])
        return rows

    def fits_rows(self, lhs: str, expr) -> bool:
        """Whether align_rows(lhs, expr) keeps every line within the width, give or take
        FIT_SLACK (math_width errs both ways: the AVR 3000 has a line 2.7 % past it that fits,
        the Z1 had one 5 % past it that did not)."""
        first = self.width - math_width(lhs) - 3
        parts = self.lines(expr, first)
        return (math_width(parts[0]) <= first * FIT_SLACK
                and all(math_width(p) <= (self.width - 4) * FIT_SLACK for p in parts[1:]))

    def fitted_rows(self, lhs: str, expr, relation: str = "=", names=None, tag: str = "") -> list[str]:
        """align_rows, except that a part too wide to break across lines (a sum inside an inverse
        cosine, an atan2's argument, a numerator) first gets a name of its own, \\xi_k, on a row
        before the equation: widest first, until every line fits or nothing is left to name.
        ``names`` numbers the \\xi_k (one counter per block of rows, so that no two collide);
        ``tag`` goes on the equation's own first row."""
        names = names if names is not None else itertools.count(1)
        rows: list[str] = []
        for _ in range(8):  # each pass names one part; eight leave any line of a real arm fitting
            if self.fits_rows(lhs, expr):
                break
            parts = {p for p in sp.preorder_traversal(expr)
                     if p is not expr and isinstance(p, sp.Add) and len(p.args) > 1}
            if not parts:
                break
            widest = max(parts, key=lambda p: (math_width(self.tex(p)), sp.default_sort_key(p)))
            if math_width(self.tex(widest)) < 12:  # naming a short part does not help
                break
            name = sp.Symbol(f"xi_{next(names)}")
            rows.extend(self.fitted_rows(self.tex(name), widest, names=names))
            expr = expr.xreplace({widest: name})
        own = self.align_rows(lhs, expr, relation)
        own[0] += tag
        return rows + own

    # Matrices -----------------------------------------------------------------
    def matrix(self, M: sp.Matrix) -> str:
        rows = [" & ".join(self.tex(e) for e in M.row(r)) for r in range(M.rows)]
        return "\\begin{bmatrix}\n" + " \\\\\n".join(rows) + "\n\\end{bmatrix}"

    def matrix_width(self, M: sp.Matrix) -> float:
        widths = [max(math_width(self.tex(M[r, c])) for r in range(M.rows)) for c in range(M.cols)]
        return sum(widths) + 2.0 * (M.cols - 1) + 2.0

    def fits(self, lhs: str, M: sp.Matrix) -> bool:
        return math_width(lhs) + 3 + self.matrix_width(M) <= self.width

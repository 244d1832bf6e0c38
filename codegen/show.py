"""`kinegen show`: a robot's derived equations on the terminal.

The text form of what the LaTeX backend prints for the page: a summary, the parameters, the DH
table (or a URDF chain's joints), fk, the frames, the Jacobians and the task one entry a line, each
wrapped to the terminal, a general arm's straight-line program first, and the inverse kinematics
(each branch's closed form, or the automatic plan, or why there is none).  The sections with no
text form print as LaTeX (:func:`codegen.backends.latex_backend.latex_for`).
"""
from __future__ import annotations

import shutil

import sympy as sp

from derivations.program import needed

from .backends import latex_backend
from .generate import SEED_COUNT, terminal_text

__all__ = ["print_model", "NotShown", "SHOW_TEXT", "WHAT", "LATEX_ALIASES"]

# One vocabulary for `show --what` and `latex --what`: what show prints as text, and the LaTeX
# sections (show prints those that have no text form as LaTeX; `position` and `task` are one).
SHOW_TEXT = ("summary", "params", "dh", "fk", "frames", "jacobian", "task", "task_jacobian", "ik", "base")
WHAT = SHOW_TEXT + tuple(k for k in latex_backend.SECTION_KEYS if k not in SHOW_TEXT)
LATEX_ALIASES = {"task": "position"}


class NotShown(ValueError):
    """A quantity the model does not have (a DH table of a model that is no chain, ...)."""


def print_model(model, what: str, latex: bool = False) -> int:
    """Print ``what`` (one of ``WHAT``) of ``model`` on stdout: as text, wrapped to the terminal, or
    as LaTeX (``latex``, and every section that has no text form); raises :class:`NotShown` for a
    quantity the model does not have."""
    section = LATEX_ALIASES.get(what, what)
    if (latex or what not in SHOW_TEXT) and section in latex_backend.SECTION_KEYS:
        print(latex_backend.latex_for(model, [section]), end="")  # the fragments' notation
        return 0
    width = shutil.get_terminal_size((100, 24)).columns
    render = ((lambda e, indent=0: sp.latex(e)) if latex else
              (lambda e, indent=0: sp.pretty(e, use_unicode=False, num_columns=max(40, width - indent))))
    if what == "summary":
        print(f"{model.title} ({model.name})\nsource: {model.source}")
        print(f"joints: {', '.join(f'{q} ({t})' for q, t in zip(model.q, model.joint_types))}")
        print(f"task: {', '.join(model.task_names)}")
        print("params: " + ", ".join(f"{p} = {v}" for p, v in model.params.items()))
        print(f"ik branches: {', '.join(b.name for b in model.ik) or 'none'}"
              + (f" ({model.ik_plan[0]})" if model.ik_plan else f" ({model.ik_unsupported})" if model.ik_unsupported else ""))
        print(f"kernels: {', '.join(f.name for f in model.functions())}")
        return 0
    if what == "params":
        for p, v in model.params.items():
            print(f"{p} = {v}")
        return 0
    if what == "base":
        return _show_base(model, latex)
    if what == "dh":
        if model.chain is None:
            raise NotShown(f"{model.name} is not a DH chain")
        print(f"convention: {model.chain.convention}")
        if model.chain.convention == "urdf":
            rows = [("joint", "type", "name", "axis", "origin xyz", "after xyz")]
            for i, j in enumerate(model.chain.joints, 1):
                rows.append((str(i), j.type, terminal_text(j.name, 60), _numbers(j.axis),
                             _numbers(j.origin[:3, 3]), "" if j.after is None else _numbers(j.after[:3, 3])))
        else:
            rows = [("joint", "type", "a", "alpha", "d", "theta", "offset")]
            for i, j in enumerate(model.chain.joints, 1):
                d = model.q[i - 1] if j.type == "P" else j.d
                theta = model.q[i - 1] if j.type == "R" else j.theta
                rows.append((str(i), j.type, *(_number(v) for v in (j.a, j.alpha, d, theta, j.offset))))
        print(_table(rows))
        return 0
    if what == "ik":
        if not model.ik:
            if model.chain is None:
                raise NotShown(f"{model.name} has no inverse kinematics (it is not one serial chain)")
            from derivations.ik.general_6r import applies as general_6r
            if general_6r(model):
                print("method: general 6R (every real solution, up to 16: Raghavan and Roth's 14 equations in "
                      "Manocha and Canny's matrix form; in the generated C the real roots of the 12 x 12 determinant, "
                      "a trigonometric polynomial of degree 8 from 17 samples, and a 24 x 24 eigenproblem (balancing, "
                      "Hessenberg reduction and Francis QR steps) only where those leave a doubt; numpy: the eigenproblem "
                      "with LAPACK; each root polished by Newton on the arm's fk; docs/ik.md)")
            else:
                print(f"method: numeric (ik_numeric from {SEED_COUNT} fixed seeds: every answer exact to 1e-12, "
                      "not every answer guaranteed)")
            print(f"no closed form: {model.ik_unsupported}")
            return 0
        if model.ik_plan:  # decomposed (derivations.ik.decompose): the plan, then each branch's root choices
            print("\n".join(model.ik_plan))
            print(f"branches ({len(model.ik)}):")
            for branch in model.ik:
                print(f"  {branch.name}: {branch.doc}")
            return 0
        for branch in model.ik:
            print(f"{branch.name}:")
            for q, expr in zip(model.q, branch.solution):
                print(f"  {q} = {render(expr)}")
        return 0
    value = {"fk": model.fk, "jacobian": model.jacobian, "task": model.task,
             "task_jacobian": model.task_jacobian}.get(what)
    shown = model.frames if what == "frames" else [value]
    steps = needed(model.program, [e for matrix in shown for e in matrix])
    if steps:  # a general arm's kinematics is a program: its steps first, then what reads them
        print(f"# {len(steps)} steps of the straight-line program, in order; the result reads them")
        for symbol, expr in steps:
            print(f"{symbol} = {render(expr)}")
        print()
    if what == "frames":
        for i, frame in enumerate(model.frames):
            print(f"T_{i}:\n{_entries(frame, render)}\n")
        return 0
    print(_entries(value, render))
    return 0


def _show_base(model, latex: bool) -> int:
    """The base parameters, each as its combination of the standard ones (docs/dynamics.md)."""
    from derivations.mechanics.dynamics import base_combinations, model_base_parameters
    if model.dynamics is None:
        raise NotShown(f"{model.name} has no equations of motion, so no base parameters "
                       f"({model.notes.get('dynamics', 'its description gives no inertial parameters')})")
    if latex:
        print("\n".join(latex_backend.base_parameter_rows(model)))
        return 0
    kept, dropped, K, names = model_base_parameters(model)
    print(f"# {len(kept)} base parameters of the {len(names)} standard ones (the regressor's columns, "
          f"docs/dynamics.md): a numeric QR of the regressor at 40 random states, the parameters at their defaults")
    for k, line in enumerate(base_combinations(kept, dropped, K, names), start=1):
        print(f"beta{k} = {line}")
    return 0


def _entries(matrix, render) -> str:
    """A matrix one entry a line (``[i, j] = ...``, each wrapped to the terminal): a 4 x 4 of long
    entries printed as one block ran to lines 656 columns wide."""
    if matrix.cols == 1:
        return "\n".join(f"[{i + 1}] = {render(e, 6)}" for i, e in enumerate(matrix))
    return "\n".join(f"[{i + 1}, {j + 1}] = {render(matrix[i, j], 9)}"
                     for i in range(matrix.rows) for j in range(matrix.cols))


def _number(value) -> str:
    """A DH entry for the terminal: a decimal as the shortest decimal of its double (0.089159, not
    89159/1000000), an exact value where short (pi/2, d1), else its value to 6 digits."""
    value = sp.sympify(value)
    if value.is_Float or (value.is_Rational and not value.is_Integer):
        return repr(float(value))
    text = str(value)
    return text if len(text) <= 24 else f"{float(value):.6g}" if sp.sympify(value).is_number else text[:24] + "..."


def _numbers(values) -> str:
    return "[" + ", ".join(_number(v) for v in values) + "]"


def _table(rows) -> str:
    """Columns padded to their widest cell."""
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows)

"""Rehiara's "tool configuration vector" and its Jacobian (Rehiara section 4, Eqs. 39-42).

Rehiara (after Schilling) builds a Jacobian not from joint axes but by
differentiating a six-vector that encodes the tool pose, Eq. 39:

    w(q) = [p; a exp(q_n / pi)]        (p: tool position, a: approach vector, 3rd column of T)
    J_w(q) = d w / d q                 (Eq. 41)

The scaled approach vector ``a exp(q_n / pi)`` keeps the roll q_n visible (``a``
alone does not change when the tool rolls about it), and ``exp`` makes the map
one-to-one in q_n.  ``J_w`` is *not* a velocity Jacobian: its last three rows are
the rate of that scaled vector, not the angular velocity of the tool, and they
depend on q_n through ``exp``.  The geometric Jacobian's last three rows are the
angular velocity ``w`` (for the AdeptThree ``w_z = q1_dot + q2_dot - q4_dot``).

For the AdeptThree ``a = (0, 0, -1)`` (Eq. 13 and our derivation agree on the
third column), so Eq. 39 gives ``w_6 = -exp(theta4 / pi)``; Eq. 40 prints
``+exp(theta4 / pi)`` (erratum E3 in the README), and Eq. 42 is the derivative
of the printed Eq. 40.
"""
from __future__ import annotations

import sympy as sp

from ...model import Argument, Output, SymbolicFunction

__all__ = ["tool_configuration_vector", "tool_configuration_jacobian", "tool_configuration_functions"]


def tool_configuration_vector(model) -> sp.Matrix:
    """Rehiara Eq. 39: ``[p; a exp(q_n / pi)]`` from the model's tool pose, 6 x 1."""
    fk = model.fk
    return sp.Matrix.vstack(fk[:3, 3], fk[:3, 2] * sp.exp(model.q[-1] / sp.pi))


def tool_configuration_jacobian(model) -> sp.Matrix:
    """Rehiara Eq. 41: ``d w / d q``, 6 x n."""
    return tool_configuration_vector(model).jacobian(sp.Matrix(model.q))


def tool_configuration_functions(model) -> list[SymbolicFunction]:
    """The two kernels: ``tool_configuration(q)`` and ``tool_configuration_jacobian(q)``."""
    n = model.n
    q = Argument("q", model.q, f"joint coordinates, shape (..., {n})")
    return [
        SymbolicFunction("tool_configuration", (q,),
                         (Output("w_tool", tuple(tool_configuration_vector(model)), (6,)),),
                         "Rehiara Eq. 39: tool configuration vector [p; a exp(q_n/pi)], shape (..., 6); "
                         "p in metres, the rest dimensionless."),
        SymbolicFunction("tool_configuration_jacobian", (q,),
                         (Output.from_matrix("Jw", tool_configuration_jacobian(model)),),
                         f"Rehiara Eq. 41: d(tool configuration vector)/dq, shape (..., 6, {n}). "
                         "Not a velocity Jacobian: rows 4-6 are rates of a exp(q_n/pi), not angular velocity."),
    ]

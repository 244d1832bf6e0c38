"""Helpers shared by the robots' inverse-kinematics modules."""
from __future__ import annotations

import sympy as sp


def parameters(model, *names: str) -> list[sp.Symbol]:
    """The parameter symbols of ``model`` named ``names``, in that order."""
    by_name = {str(s): s for s in model.params}
    return [by_name[n] for n in names]

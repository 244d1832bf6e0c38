"""Inverse kinematics: closed-form primitives, structure detection and automatic decomposition.

* :mod:`derivations.ik.primitives`: the small equations every solver is built from
  (``atan2`` of a sine/cosine pair, the law of cosines, ``P cos + Q sin + R = 0``, ...)
  and the numerical conventions of the ``ik`` kernels (clamped ``acos``, wrapped angles).
* :mod:`derivations.ik.structure`: the joint axes of a chain in its zero configuration
  (direction and a point, product-of-exponentials style, for DH and URDF chains alike)
  and what they share: parallel axes, axes meeting in a point, prismatic joints.
* :mod:`derivations.ik.subproblems`: the geometric subproblems on those axes (rotation of
  a vector onto another, to a given height, to a given distance; two rotations about
  meeting axes), each derived once in SymPy with every root and its existence condition.
* :mod:`derivations.ik.decompose`: the families of arms with a closed form and how each
  splits into subproblems; :func:`solve` gives a model's branches or says which structure
  the arm lacks.
* :mod:`derivations.ik.reverse`: an arm read from its tool (``M T^-1 = E_n(-q_n) ... E_1(-q_1)``),
  so that the families solve arms whose special axes are at the base (a spherical shoulder).

The papers' robots (``derivations/robots/<name>.py``) use the primitives to print their
paper's steps; every other arm gets its inverse kinematics from :func:`solve`.

This package may import the core (``derivations.chain``, ``.program``, ``.model``,
``.kinematics``) and ``derivations.support``; never the rates, the assembly or the robots.
"""
from .primitives import *  # noqa: F401,F403
from .primitives import __all__ as _primitives

__all__ = list(_primitives)
__all__ += ["IKSolution", "IKUnsupported", "solve", "attach"]


def __getattr__(name):
    # decompose is loaded on first use: importing it costs every command about 45 ms of its start,
    # and a refusal of bad input must stay well under a second
    if name in ("IKSolution", "IKUnsupported", "solve", "attach", "IK_BUDGET"):
        from . import decompose
        return getattr(decompose, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

"""Dynamics: the inertial parameters of a link (``inertia.py``) and an arm's equations of motion
(``dynamics.py``: Newton-Euler and the composite rigid body, exposed as ``model.dynamics``).

This package may import the core (``derivations.chain``, ``.program``, ``.model``) and
``derivations.support``; the input formats import ``inertia.py`` to read a link's inertials.
It imports neither ik/, rates/, the assembly nor the robots.  (The folder is not called
``dynamics`` so that ``derivations.dynamics`` stays the module it always was.)
"""

"""Rate kinematics of any arm: velocities, accelerations, their inverses and where they break down.

``velocity.py`` derives the forward and inverse rate maps and their kernels
(:func:`~derivations.rates.velocity.rate_kinematics`, exposed as ``model.rates``),
``damping.py`` the closed-form inverses and the damped least squares near a singularity,
``singular.py`` the factored Jacobian determinant and the singular configuration sets, and
``paul.py`` Paul's wrist partition of a 6R arm's Jacobian.  This package may import the core
(``derivations.chain``, ``.program``, ``.model``) and ``derivations.support``; it names no robot
and imports neither ik/, the assembly nor the robots.
"""

"""Input formats: robot description files in, one :class:`~derivations.formats.shared.Description` out.

``description.py`` reads the TOML description (DH, standard or modified, or a URDF named by its
``urdf`` key), ``urdf.py`` reads a URDF file between two links, and ``shared.py`` holds what both
produce (the ``Description``, ``DescriptionError``, the size-capped file read, the task checks).
A new input format is one more module here whose reader returns a ``Description``.  This package
may import the core (``derivations.chain``, ``.expressions``, ``.model``), ``derivations.support``
and the inertial parameters of ``derivations.mechanics.inertia``; never ik/, rates/, the assembly
or the robots.
"""

"""The papers' robots: one description ``<name>.toml`` each (a DH chain), optionally with a module
``<name>.py`` of the paper's own steps (``extend(model)``: its inverse kinematics, its extra
kernels), or a module alone whose ``build()`` returns the model (the AVR 3000, not one chain).

Paper-specific pieces that are not a robot live in ``robots/extras/``.  This is the top layer:
a robot's module may import anything below it (the core, ik/, rates/, motion/, ``robots.extras``),
and nothing below imports a robot's module (``derivations.load`` finds them by name).
"""

"""The papers' pieces that belong to one robot, beside the robots of ``derivations/robots/``.

The AVR 3000's coordinate spaces (``spaces.py``: motor, joint, tool and Cartesian spaces and
the maps between them) and its motor limits (``motor_limits.py``, the Matlab script of Sotirov
2000), the AdeptThree's tool configuration vector (``tool_configuration.py``, Rehiara
Eqs. 39-42) and the 3-RRR platform's forward kinematics (``parallel.py``).  A robot's module
declares the kernels it wants from here (``model.extra_functions`` in its ``extend``).  This
package may import the core, ik/, rates/, motion/ and the robots' modules; nothing generic
imports it.  It holds no robot: the registry (``derivations.ROBOTS``) reads only the files
directly in ``derivations/robots/``.
"""

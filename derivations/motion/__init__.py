"""Motion: the mobility of a mechanism (Gruebler-Kutzbach, ``mobility.py``).

The point-to-point time laws belong here too, but stay in ``derivations/trajectory.py``: the
headers of ``generated/trajectory/`` name that path (docs/architecture.md).  This package may
import the core and ``derivations.support``; it names no robot.
"""

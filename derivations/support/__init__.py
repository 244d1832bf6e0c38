"""Support for slow symbolic work: time and memory budgets (``budget.py``) and the signed disk
cache of derived results (``cache.py``).

Every other layer may import this package; it imports nothing of ``derivations`` but itself.
"""

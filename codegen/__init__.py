"""From SymPy models to files: numpy and C kernels (jinja2 templates), builds and checks.

``codegen`` reads models from ``derivations`` and writes ``generated/``; the
command line is ``python -m codegen`` (also installed as ``kinegen``).
"""

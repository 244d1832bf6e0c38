"""A disk cache for slow symbolic work.

Derived models are pickled under ``.cache/derivations/`` at the top of the
checkout (or ``$KINEGEN_CACHE``).  The key hashes the robot's description, the
source of every module in ``derivations/`` and the SymPy version, so a change to
any of them derives afresh; a cache that cannot be read or written is ignored.
"""
from __future__ import annotations

import hashlib
import os
import pickle
import sys
import tempfile
from pathlib import Path
from typing import Callable, TypeVar

import sympy

T = TypeVar("T")
_PACKAGE = Path(__file__).resolve().parent


def cache_dir() -> Path:
    env = os.environ.get("KINEGEN_CACHE")
    if env:
        return Path(env)
    return _PACKAGE.parent / ".cache" / "derivations"


def source_fingerprint() -> str:
    """Hash of every Python source file of the derivations package."""
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE.rglob("*.py")):
        digest.update(str(path.relative_to(_PACKAGE)).encode())
        digest.update(path.read_bytes())
    digest.update(sympy.__version__.encode())
    digest.update(sys.version.split()[0].encode())
    return digest.hexdigest()


def cached(kind: str, content: bytes, build: Callable[[], T]) -> T:
    """``build()``, memoised on disk by ``kind`` and ``content``."""
    if os.environ.get("KINEGEN_NO_CACHE"):
        return build()
    key = hashlib.sha256(content + source_fingerprint().encode()).hexdigest()[:32]
    path = cache_dir() / f"{kind}-{key}.pickle"
    try:
        with open(path, "rb") as handle:
            return pickle.load(handle)
    except Exception:  # missing, stale or unreadable: derive afresh
        pass
    value = build()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as handle:
            pickle.dump(value, handle, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
    except OSError:
        pass
    return value

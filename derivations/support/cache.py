"""A disk cache for slow symbolic work, which loading cannot turn into running code.

Derived models are pickled under ``.cache/derivations/`` at the top of the
checkout (or ``$KINEGEN_CACHE``).  The key hashes the robot's description, the
source of every module in ``derivations/`` and the SymPy version, so a change to
any of them derives afresh; a cache that cannot be read or written is ignored.

A pickle runs whatever code its bytes name when it is loaded, so no entry is
unpickled unless it carries an HMAC-SHA256, under a secret key kept outside the
cache folder (``$XDG_CONFIG_HOME/kinegen/cache-key``, else ``~/.config/kinegen/
cache-key``, or ``$KINEGEN_CACHE_KEY``; created on first use, mode 0600), of its
file name and its bytes.  A planted or edited entry, or one copied over another's
name (the planar 2R's model under the PUMA's key), fails that check, is reported
once on stderr and derived afresh.  Without a key (a home that cannot be written),
nothing is read from the cache.
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import hmac
import os
import pickle
import secrets
import sys
import tempfile
from pathlib import Path
from typing import Callable, TypeVar

import sympy
from sympy.core.cache import clear_cache

from . import budget, pickling

T = TypeVar("T")
_PACKAGE = Path(__file__).resolve().parents[1]  # derivations/, whose sources key the cache


def cache_dir() -> Path:
    """``$KINEGEN_CACHE``; in a checkout, ``.cache/derivations`` at its top; installed (no
    pyproject.toml beside the package), the user's cache folder (``$XDG_CACHE_HOME/kinegen``, else
    ``~/.cache/kinegen``), never site-packages."""
    env = os.environ.get("KINEGEN_CACHE")
    if env:
        return Path(env)
    if (_PACKAGE.parent / "pyproject.toml").is_file():
        return _PACKAGE.parent / ".cache" / "derivations"
    home = os.environ.get("XDG_CACHE_HOME") or (str(Path.home() / ".cache") if os.environ.get("HOME") else "")
    return Path(home) / "kinegen" / "derivations" if home else _PACKAGE.parent / ".cache" / "derivations"


@functools.lru_cache(maxsize=None)
def source_fingerprint() -> str:
    """Hash of every Python source file of the derivations package, read once per process: a
    process whose code was imported before a source file changed must not store what that old
    code derived under the new sources' key."""
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE.rglob("*.py")):
        digest.update(str(path.relative_to(_PACKAGE)).encode())
        digest.update(path.read_bytes())
    digest.update(sympy.__version__.encode())
    digest.update(sys.version.split()[0].encode())
    return digest.hexdigest()


MAGIC = b"kinegen-cache-1\n"


def key_path() -> Path | None:
    """Where the signing key lives; None where there is no home to keep it in (HOME empty or unset
    and no XDG_CONFIG_HOME: Python would take / for the home, and the key would land in /.config)."""
    env = os.environ.get("KINEGEN_CACHE_KEY")
    if env:
        return Path(env)
    config = os.environ.get("XDG_CONFIG_HOME")
    if not config:
        if not os.environ.get("HOME"):
            return None
        config = str(Path.home() / ".config")
    return Path(config) / "kinegen" / "cache-key"


def _trusted(path: Path) -> bool:
    """The key file is the user's own and nobody else's to read or write: a key planted in a shared
    place (mode 0644, known bytes) would let a planted pickle pass as signed."""
    try:
        info = path.stat()
    except OSError:
        return False
    if info.st_uid == os.getuid() and not info.st_mode & 0o077:
        return True
    if str(path) not in _REPORTED:
        _REPORTED.add(str(path))
        print(f"kinegen: the cache key {path} is not yours alone (owner uid {info.st_uid}, mode "
              f"{info.st_mode & 0o777:o}; expected your own file, mode 600): the cache is not used",
              file=sys.stderr)
    return False


def _secret() -> bytes | None:
    """The signing key, created (32 random bytes, mode 0600) if there is none; None if it cannot be,
    or if the key file is not the user's own with mode 0600 (the cache is then not used)."""
    path = key_path()
    if path is None or not path.is_absolute():
        if "key" not in _REPORTED:
            _REPORTED.add("key")
            print("kinegen: no home folder to keep the cache key in (HOME is empty or unset, and so is "
                  "XDG_CONFIG_HOME): the cache is not used; set HOME, XDG_CONFIG_HOME or KINEGEN_CACHE_KEY",
                  file=sys.stderr)
        return None
    try:
        key = path.read_bytes()
        return key if len(key) >= 32 and _trusted(path) else None
    except FileNotFoundError:
        pass
    except OSError:
        return None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".cache-key-")
        with os.fdopen(fd, "wb") as handle:  # mkstemp: mode 0600
            handle.write(secrets.token_bytes(32))
        try:
            os.link(tmp, path)  # never over another process's key
        except FileExistsError:
            pass
        finally:
            os.unlink(tmp)
        key = path.read_bytes()
        return key if len(key) >= 32 else None
    except OSError:
        return None


def _signature(key: bytes, name: str, payload: bytes) -> bytes:
    return hmac.new(key, name.encode() + b"\0" + payload, hashlib.sha256).hexdigest().encode()


_REPORTED: set[str] = set()


def cached(kind: str, content: bytes, build: Callable[[], T]) -> T:
    """``build()``, memoised on disk by ``kind`` and ``content`` (signed entries only)."""
    if os.environ.get("KINEGEN_NO_CACHE"):
        return build()
    secret = _secret()
    if secret is None:
        return build()
    digest = hashlib.sha256(content + source_fingerprint().encode()).hexdigest()[:32]
    path = cache_dir() / f"{kind}-{digest}.pickle"
    try:
        data = path.read_bytes()
    except OSError:  # missing or unreadable: derive afresh
        data = None
    if data is not None:
        head, _, rest = data.partition(b"\n")
        signature, payload = rest[:64], rest[65:]
        if (head + b"\n" == MAGIC and len(rest) > 65
                and hmac.compare_digest(signature, _signature(secret, path.name, payload))):
            try:
                # Unpickling rebuilds every expression through SymPy's constructors, whose cache
                # holds what this process built before: a second copy of the same model would hit
                # entries of the first and compare the two trees node by node without their
                # sharing (the ROMEO arm's model, loaded a second time in one process: 3 -> 264 s
                # of CPU).  Emptied first, the cache holds only the entry's own, shared, objects.
                clear_cache()
                return pickle.loads(payload)
            except Exception:  # signed by us but unreadable (another Python or SymPy): derive afresh
                pass
        elif path.name not in _REPORTED:
            _REPORTED.add(path.name)
            print(f"kinegen: cache entry {path} is not signed by this machine's key; ignored and derived afresh",
                  file=sys.stderr)
    before = budget.degradations
    value = build()
    if budget.degradations != before:  # a budget cut part of it short: right for now, not for good
        return value
    tmp = None
    try:
        payload = pickling.dumps(value)  # loads without SymPy evaluating every expression again
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as handle:
            handle.write(MAGIC + _signature(secret, path.name, payload) + b"\n" + payload)
        os.replace(tmp, path)
    except OSError:  # a full disk, a read-only cache: the value is right, only not kept
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    return value

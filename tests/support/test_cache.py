"""The derivation cache (derivations/cache.py) loads only entries signed with this machine's key:
a planted pickle runs no code, an entry copied over another's name is not taken for it."""
from __future__ import annotations

import os
import pickle
import stat

import pytest

from derivations import cache


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("KINEGEN_CACHE_KEY", str(tmp_path / "config" / "cache-key"))
    monkeypatch.delenv("KINEGEN_NO_CACHE", raising=False)
    monkeypatch.setattr(cache, "_REPORTED", set())
    return tmp_path


class Counter:
    def __init__(self, value):
        self.value, self.calls = value, 0

    def __call__(self):
        self.calls += 1
        return self.value


class Planted:
    """Unpickling this would create the marker file."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def entries(root):
    return sorted((root / "cache").glob("*.pickle"))


def test_a_signed_entry_is_reused_and_the_key_is_private(private_cache):
    build = Counter({"answer": 42})
    assert cache.cached("thing", b"content", build) == {"answer": 42}
    assert cache.cached("thing", b"content", build) == {"answer": 42}
    assert build.calls == 1
    key = private_cache / "config" / "cache-key"
    assert stat.S_IMODE(os.stat(key).st_mode) == 0o600 and len(key.read_bytes()) == 32


def test_a_planted_pickle_runs_no_code(private_cache, capsys):
    build = Counter([1, 2, 3])
    cache.cached("model-robot", b"description", build)
    (entry,) = entries(private_cache)
    marker = private_cache / "marker"
    evil = pickle.dumps(Planted(marker))
    for planted in (evil, cache.MAGIC + b"0" * 64 + b"\n" + evil):  # bare, and with a forged signature
        entry.write_bytes(planted)
        assert cache.cached("model-robot", b"description", build) == [1, 2, 3]
        assert not marker.exists()
    assert build.calls == 3
    assert capsys.readouterr().err.count("is not signed by this machine's key") == 1  # reported once


def test_an_entry_copied_over_another_name_is_not_taken_for_it(private_cache):
    """The planar 2R's entry copied over the PUMA's: a valid signature, but of another file name."""
    cache.cached("model-planar_2r", b"2r", Counter("planar_2r"))
    cache.cached("model-puma560", b"puma", Counter("puma560"))
    by_name = {p.name.split("-")[1]: p for p in entries(private_cache)}
    by_name["puma560"].write_bytes(by_name["planar_2r"].read_bytes())
    build = Counter("puma560")
    assert cache.cached("model-puma560", b"puma", build) == "puma560" and build.calls == 1


def test_entries_signed_with_another_key_are_derived_afresh(private_cache, monkeypatch):
    cache.cached("thing", b"content", Counter("first"))
    monkeypatch.setenv("KINEGEN_CACHE_KEY", str(private_cache / "other-key"))
    build = Counter("second")
    assert cache.cached("thing", b"content", build) == "second" and build.calls == 1


def test_without_a_key_nothing_is_read(private_cache, monkeypatch):
    blocker = private_cache / "not-a-folder"
    blocker.write_text("")
    monkeypatch.setenv("KINEGEN_CACHE_KEY", str(blocker / "cache-key"))  # its folder cannot be made
    build = Counter("value")
    cache.cached("thing", b"content", build)
    cache.cached("thing", b"content", build)
    assert build.calls == 2


def test_hostile_d6_a_result_a_budget_cut_short_is_not_cached(private_cache):
    """An arm left without ik because the machine was busy past the 10 s budget is right for that
    run only: a later run derives afresh (issue #28, D6)."""
    from derivations import budget

    def cut_short():
        budget.degraded("automatic inverse kinematics: stopped after its time budget of 10 s")
        return "without ik"

    assert cache.cached("model-arm", b"description", cut_short) == "without ik"
    assert entries(private_cache) == []
    whole = Counter("with ik")
    assert cache.cached("model-arm", b"description", whole) == "with ik"
    assert cache.cached("model-arm", b"description", whole) == "with ik" and whole.calls == 1


@pytest.mark.parametrize("mode", [0o644, 0o620, 0o604])
def test_hostile_d7_a_key_others_can_read_or_write_is_not_trusted(private_cache, capsys, mode):
    """A key file planted with known bytes and mode 0644 in a shared config folder would make a
    planted pickle pass as signed: such a key is refused, said once, and nothing is cached or read."""
    key = private_cache / "config" / "cache-key"
    key.parent.mkdir(parents=True)
    key.write_bytes(b"k" * 32)
    os.chmod(key, mode)
    build = Counter("value")
    assert cache.cached("thing", b"content", build) == "value"
    assert cache.cached("thing", b"content", build) == "value"
    assert build.calls == 2 and entries(private_cache) == []
    err = capsys.readouterr().err
    assert err.count("is not yours alone") == 1 and f"mode {mode:o}" in err and "expected your own file, mode 600" in err


def test_hostile_d9_an_empty_home_gets_a_message_not_a_key_at_the_root(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    for variable in ("KINEGEN_CACHE_KEY", "XDG_CONFIG_HOME", "KINEGEN_NO_CACHE"):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("HOME", "")
    monkeypatch.setattr(cache, "_REPORTED", set())
    assert cache.key_path() is None
    assert cache.cached("thing", b"content", Counter(7)) == 7
    assert not (tmp_path / "cache").exists()
    assert "no home folder to keep the cache key in" in capsys.readouterr().err


def test_hostile_d9_a_failed_cache_write_leaves_nothing(private_cache, monkeypatch):
    """A write that fails half-way (a full disk) leaves no temporary file in the cache folder."""
    assert cache.cached("other", b"content", Counter("kept")) == "kept"  # the key and one entry exist
    before = sorted((private_cache / "cache").iterdir())
    real_open = os.fdopen

    class Full:
        def __init__(self, fd, mode):
            self.handle = real_open(fd, mode)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

        def write(self, data):
            self.handle.write(data[:10])
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(cache.os, "fdopen", Full)
    assert cache.cached("thing", b"content", Counter("value")) == "value"
    assert sorted((private_cache / "cache").iterdir()) == before

"""`kinegen fuzz` (codegen/fuzz.py): libFuzzer over every C entry point, here a short pass of one package."""
import re

import pytest

from codegen import fuzz
from codegen.cli import main

# A row of the table: package, entry point, runs, exec/s, result.
ROW = re.compile(r"^(?P<package>\w+)\s+(?P<entry>.+?)\s+(?P<runs>[\d,]+)\s+(?P<rate>[\d,]+)\s+(?P<result>clean|FAILED.*)$")


def test_a_short_fuzz_of_every_entry_point_of_the_planar_2r_is_clean(capsys):
    missing = fuzz.clang_missing()
    if missing:
        pytest.skip(missing)
    status = main(["--quiet", "fuzz", "planar_2r", "--runs", "2000"])
    output = capsys.readouterr().out
    assert status == 0, output
    rows = {m["entry"]: m for m in map(ROW.match, output.splitlines()) if m and m["package"] == "planar_2r"}
    # its 14 kernels, within_limits, and ik's round trip through task
    assert len(rows) == 16 and {"fk", "ik", "joint_acceleration", "within_limits", fuzz.ROUND_TRIP} <= set(rows)
    assert all(row["result"] == "clean" and int(row["runs"].replace(",", "")) >= 2000 for row in rows.values()), output


def test_without_clang_fuzz_says_how_to_install_it_and_exits_2(monkeypatch, capsys):
    monkeypatch.setattr(fuzz, "CLANG", "kinegen-no-such-clang")
    fuzz.clang_missing.cache_clear()
    try:
        assert main(["--quiet", "fuzz", "planar_2r"]) == 2
    finally:
        fuzz.clang_missing.cache_clear()
    error = capsys.readouterr().err
    assert "kinegen-no-such-clang not found" in error and "apt-get install clang" in error

"""`kinegen fuzz` (codegen/fuzz.py): libFuzzer over every C entry point, here a short pass of one package."""
import re

import pytest

from codegen import fuzz
from codegen.cli import main
from codegen.generate import GENERATED

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
    # every single-point entry point the C header declares (the kernels and within_limits), and
    # ik's round trip through task
    header = (GENERATED / "planar_2r" / "planar_2r.h").read_text()
    declared = set(re.findall(r"^\w+ planar_2r_(\w+)\(const", header, re.MULTILINE))  # not the _batch ones
    assert len(declared) >= 16 and {"fk", "ik", "jacobian_tool", "within_limits"} <= declared
    assert set(rows) == declared | {fuzz.ROUND_TRIP}, output
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


def test_the_fuzz_reaches_the_streaming_stores_of_the_simd_layout(tmp_path, models, monkeypatch):
    """The harness builds the SIMD layout with streaming stores from fuzz.FUZZ_STREAM_BYTES on: a
    bug planted in them alone (the two lanes of each streamed pair swapped) is found, as single
    and batched results that differ, within a short run; and only where outputs stream.  Two
    targets are fuzzed, fk (whose outputs stream) and ik (whose never do): the short fuzz above
    runs every one."""
    import platform
    import re
    import shutil

    from codegen import generate
    missing = fuzz.clang_missing()
    if missing:
        pytest.skip(missing)
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("the streaming stores are SSE2's (x86-64 only)")
    package = tmp_path / "planar_2r"
    shutil.copytree(generate.GENERATED / "planar_2r", package)
    source = package / "planar_2r.c"
    text = source.read_text()
    planted = re.sub(r"_mm_set_pd\((\w+)\[k \+ 1\]\[i\], (\w+)\[k\]\[i\]\)", r"_mm_set_pd(\2[k][i], \1[k + 1][i])", text)
    assert planted != text  # the streaming stores are there to plant it in (x86-64)
    source.write_text(planted)
    context = generate.robot_context(models["planar_2r"], "")
    fuzzed = fuzz.package_from_context(package, context)
    every_target = fuzz.targets
    monkeypatch.setattr(fuzz, "targets", lambda package: [t for t in every_target(package) if t.entry in ("fk", "ik")])
    results = {r.target.entry: r for r in fuzz.fuzz([fuzzed], runs=3000, seconds=None, jobs=2)}
    assert set(results) == {"fk", "ik"}
    assert results["fk"].failure is not None and "differ" in results["fk"].reason, results["fk"]
    # ik's outputs never stream (a kernel with a valid flag writes its branches as it checks them)
    assert results["ik"].failure is None, results["ik"].reason

"""Hostile use of the output and the terminal (issue #28, round two): the package folder is taken
before any work and never lost, echoed text cannot forge lines or flood the terminal, and the
machine's own failures (a read-only folder, a closed pipe) end with a message and exit status 2,
not an internal error.  Each test is named after its class in the issue (D8, D10, D12, D13)."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from codegen import generate
from codegen.cli import main

ROOT = Path(__file__).resolve().parents[2]
ARM = 'name = "{name}"\ntitle = "{title}"\n[[joint]]\ntype = "R"\na = 0.5\n[[joint]]\ntype = "R"\na = 0.4\n'


def arm(tmp_path, name="arm", title="An arm") -> Path:
    path = tmp_path / "arm.toml"
    path.write_text(ARM.format(name=name, title=title))
    return path


def test_hostile_d8_out_is_claimed_before_any_work(tmp_path, capsys):
    """An --out that exists is refused at once (before the derivation), and a run that stops leaves
    no folder it made."""
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "mine.txt").write_text("a user's file")
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    assert time.process_time() - start < 1.0
    assert "output folder exists (use --force to replace it)" in capsys.readouterr().err
    assert (tmp_path / "pkg" / "mine.txt").read_text() == "a user's file"
    broken = tmp_path / "broken.toml"
    broken.write_text('name = "arm"\n[[joint]]\ntype = "X"\n')
    assert main(["--quiet", "generate", str(broken), "--out", str(tmp_path / "fresh"), "--no-build"]) == 2
    assert not (tmp_path / "fresh").exists()


def test_hostile_d8_a_folder_that_appears_at_out_during_the_run_is_never_deleted(tmp_path, monkeypatch, capsys):
    """Files written into --out while the run works are left as they are; the run refuses to put its
    package there (exit 2), and leaves no scratch folder."""
    real_render = generate.render_robot

    def render_then_intrude(*args, **kwargs):
        files = real_render(*args, **kwargs)
        (tmp_path / "pkg" / "theirs.txt").write_text("written by someone else meanwhile")
        return files

    monkeypatch.setattr(generate, "render_robot", render_then_intrude)
    assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    err = capsys.readouterr().err
    assert "files appeared in the output folder while this run worked" in err and err.count("\n") == 1
    assert sorted(p.name for p in (tmp_path / "pkg").iterdir()) == ["theirs.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.toml", "pkg"]


def test_hostile_d8_a_dangling_link_at_out_is_refused_before_work(tmp_path, capsys):
    (tmp_path / "pkg").symlink_to(tmp_path / "nowhere")
    assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    assert "a symbolic link to nothing" in capsys.readouterr().err
    assert not (tmp_path / "nowhere").exists()


def test_hostile_d8_a_read_only_output_folder_is_exit_2_naming_the_path(tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root writes into a read-only folder")
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o555)
    try:
        assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(parent / "pkg"), "--no-build"]) == 2
    finally:
        parent.chmod(0o755)
    err = capsys.readouterr().err
    assert f"{parent / 'pkg'}: Permission denied" in err and "internal error" not in err


def test_hostile_d8_the_package_folder_follows_the_umask(tmp_path):
    previous = os.umask(0o022)
    try:
        assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / "pkg"), "--no-build"]) == 0
    finally:
        os.umask(previous)
    assert (tmp_path / "pkg").stat().st_mode & 0o777 == 0o755


@pytest.mark.parametrize("out", ["class", "json", "typing", "1arm", "my-arm"])
def test_hostile_d13_out_names_that_cannot_be_imported_as_their_own_package(tmp_path, capsys, out):
    assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / out), "--no-build"]) == 2
    err = capsys.readouterr().err
    assert f"kinegen: error: {tmp_path / out}" in err
    assert not (tmp_path / out).exists()


def test_hostile_d10_a_newline_in_a_title_stays_inside_the_tex_comment(tmp_path):
    """The title is printed in a ``%`` comment of the .tex: a newline in it would make the rest live
    document text (``\\input`` of anything)."""
    path = arm(tmp_path, title="An arm\\n\\\\input{/etc/passwd}")
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), "--no-build"]) == 0
    tex = (tmp_path / "pkg" / "arm.tex").read_text()
    for line in tex.splitlines():
        assert "passwd" not in line or line.startswith("%") or line.startswith("\\kinegenrobot"), line
    assert "\\input{" not in tex


def test_hostile_d12_a_huge_name_is_echoed_in_a_few_hundred_characters(tmp_path, capsys):
    """A 512 KiB joint name in an error: one line of at most 1,000 characters."""
    text = 'name = "arm"\n[[joint]]\ntype = "R"\nname = "' + "j" * 2**19 + '"\na = "nowhere"\n'
    path = tmp_path / "arm.toml"
    path.write_text(text)
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err) < 1100 and "more characters)" in err


def test_hostile_d12_a_newline_in_a_file_name_cannot_forge_a_line(tmp_path):
    """``kinegen: wrote ...`` and the printed path stay one line each whatever the folder is called."""
    folder = tmp_path / "a\nkinegen: wrote elsewhere"
    folder.mkdir()
    path = arm(folder)
    result = subprocess.run([sys.executable, "-m", "codegen", "generate", str(path), "--out", str(tmp_path / "pkg"),
                             "--no-build"], cwd=ROOT, capture_output=True, text=True,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert result.returncode == 0, result.stderr
    assert not any(line.startswith("kinegen: wrote elsewhere") for line in result.stderr.splitlines())
    assert result.stdout.count("\n") == 1


def test_hostile_d12_control_and_bidirectional_characters_are_escaped_on_the_terminal():
    shown = generate.terminal_text("joint\u202e1\x1b[2J\nnext")
    assert "\u202e" not in shown and "\x1b" not in shown and "\n" not in shown
    assert "\\u202e" in shown and "\\x1b" in shown and "\\n" in shown


def test_a_closed_pipe_ends_quietly():
    """`kinegen list | head -1`: no 'internal error', no traceback."""
    process = subprocess.Popen([sys.executable, "-m", "codegen", "list"], cwd=ROOT, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    process.stdout.readline()
    process.stdout.close()
    _, err = process.communicate(timeout=60)
    assert process.returncode == 0 and err == b"", err


def test_two_runs_racing_for_one_out_leave_one_package(tmp_path):
    """Two generates of the same --out at once: one takes the folder, the other is refused (exit 2)."""
    path = arm(tmp_path)
    codes = []

    def run():
        result = subprocess.run([sys.executable, "-m", "codegen", "--quiet", "generate", str(path), "--out",
                                 str(tmp_path / "pkg"), "--no-build"], cwd=ROOT, capture_output=True,
                                env=dict(os.environ, PYTHONPATH=str(ROOT)))
        codes.append(result.returncode)

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(codes) == [0, 2]
    assert (tmp_path / "pkg" / "__init__.py").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.toml", "pkg"]


def test_hostile_d8_an_out_inside_a_file_is_exit_2_naming_the_file(tmp_path, capsys):
    (tmp_path / "afile").write_text("")
    assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / "afile" / "pkg"),
                 "--no-build"]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'afile'}: not a folder" in err and "internal error" not in err


def urdf_revolute_line(count: int) -> str:
    links = "".join(f'<link name="l{i}"/>' for i in range(count + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0.1 0 0" rpy="0.3 0 0"/><axis xyz="0 0 1"/></joint>' for i in range(count))
    return f'<robot name="arm">{links}{joints}</robot>'


def test_hostile_d4_a_urdf_chain_of_200_joints_is_refused_at_once(tmp_path, capsys):
    """The same joint limit as a TOML description (was: refused only at the 120 s budget)."""
    path = tmp_path / "long.urdf"
    path.write_text(urdf_revolute_line(200))
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    assert time.process_time() - start < 5.0
    err = capsys.readouterr().err
    assert "200 moving joints between 'l0' and 'l200'; a chain has 1 to 8" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.urdf"]


@pytest.mark.parametrize("target, message", [
    ("fifo", "not a regular file"), ("/dev/zero", "not a regular file"), (".", "not a regular file"),
    ("missing.urdf", "cannot read: No such file or directory")])
def test_hostile_d4_a_toml_urdf_path_is_read_only_from_a_regular_file(tmp_path, capsys, target, message):
    """``urdf =`` opens a regular file only, with a size cap: a FIFO blocked for ever, /dev/zero
    was read to the 8 GiB cap, a folder was an internal error."""
    if target == "fifo":
        os.mkfifo(tmp_path / "fifo")
    (tmp_path / "arm.toml").write_text(f'name = "arm"\nurdf = "{target}"\n')
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    assert main(["--quiet", "generate", str(tmp_path / "arm.toml"), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    assert time.process_time() - start < 5.0
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not (tmp_path / "pkg").exists()


def test_hostile_d5_the_cache_keys_the_bytes_the_model_was_derived_from(tmp_path, monkeypatch):
    """A file replaced between two reads (an editor saving, a checkout) kept the old robot's model
    under the new bytes' key: now the description is read once, and its key is those bytes."""
    import derivations
    from derivations import cache
    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("KINEGEN_CACHE_KEY", str(tmp_path / "key"))
    path = arm(tmp_path)
    keys = []
    real = cache.cached

    def spy(kind, content, build):
        keys.append(content)
        return real(kind, content, build)

    monkeypatch.setattr(derivations, "cached", spy)
    model = derivations.load(path)
    assert path.read_bytes() in keys[0] and path.name.encode() in keys[0]
    path.write_text(ARM.format(name="arm", title="An arm").replace("a = 0.4", "a = 0.7"))
    assert derivations.load(path).fk != model.fk


def test_hostile_d13_identical_bytes_under_another_name_are_another_cache_entry(tmp_path, monkeypatch):
    """A URDF package's Source: names its file: two files of the same bytes share no cache entry,
    so the second one's source names the second file."""
    import derivations
    monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("KINEGEN_CACHE_KEY", str(tmp_path / "key"))
    first, second = tmp_path / "one.urdf", tmp_path / "two.urdf"
    for path in (first, second):
        path.write_text(urdf_revolute_line(2))
    assert derivations.load(first).source.startswith("URDF one.urdf")
    assert derivations.load(second).source.startswith("URDF two.urdf")


@pytest.mark.parametrize("command", [["show", "--what", "fk"], ["latex"], ["verify", "--out", "pkg"]])
def test_hostile_d4_every_command_that_derives_has_a_time_budget(tmp_path, capsys, command):
    """show, latex and verify derive too: they stop at --time-limit like generate (exit 2, the stage
    named), where before they had neither a budget nor a memory cap."""
    text = 'name = "slow"\n' + "".join(f'[[joint]]\ntype = "R"\na = 0.{i + 1}\nalpha = 0.{i + 3}\nd = 0.0{i}\n'
                                        for i in range(6))
    (tmp_path / "slow.toml").write_text(text)
    args = [command[0], str(tmp_path / "slow.toml"), *command[1:], "--time-limit", "0.05"]
    if command[0] == "verify":
        args[args.index("pkg")] = str(tmp_path / "pkg")
    start = time.process_time()  # CPU time: bounds the work, whatever the load
    assert main(["--quiet", *args]) == 2
    assert time.process_time() - start < 5.0
    err = capsys.readouterr().err
    assert "stopped after its time budget of 0.05 s" in err and err.count("\n") == 1


def test_hostile_d11_kernels_that_overflow_a_double_at_the_defaults_are_refused(tmp_path, capsys):
    """sqrt(p**2 + 1) - p + 0.5 is 0.5 exactly (every field passes its own check at 30 digits), but
    with p = 1e200 the kernels compute inf - inf: the package is refused (exit 2), nothing written."""
    path = tmp_path / "arm.toml"
    path.write_text('name = "arm"\n[params]\np = 1e200\n[[joint]]\ntype = "R"\na = "sqrt(p**2 + 1) - p + 0.5"\n')
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    err = capsys.readouterr().err
    assert "arm: fk is inf at the parameters' defaults when computed in double precision" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.toml"]
    path.write_text('name = "arm"\n[params]\np = 1e100\n[[joint]]\ntype = "R"\na = "sqrt(p**2 + 1) - p + 0.5"\n')
    assert main(["--quiet", "generate", str(path), "--out", str(tmp_path / "pkg"), "--no-build"]) == 0


def test_hostile_d9_a_rerun_clears_what_a_killed_run_left_beside_out(tmp_path, capsys):
    """``kill -9`` leaves the run's scratch folder (its build objects inside it): the next run writing
    the same --out removes it and says so; a folder of a run still going is left alone."""
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    left = tmp_path / f".pkg-kinegen-{dead}-abc123"
    (left / ".kinegen-build-x").mkdir(parents=True)
    (left / ".kinegen-build-x" / "arm.o").write_bytes(b"\0" * 64)
    running = tmp_path / f".pkg-kinegen-{os.getpid()}-def456"
    running.mkdir()
    assert main(["generate", str(arm(tmp_path)), "--out", str(tmp_path / "pkg"), "--no-build"]) == 0
    err = capsys.readouterr().err
    assert f"removed {left}: a scratch folder left by a run that was killed" in err
    assert not left.exists() and running.exists()


def test_hostile_d9_a_build_keeps_its_objects_inside_the_package(tmp_path, monkeypatch):
    """The compiler's objects and temporary files are made inside the package being built, never in
    the system's temporary folder, where a killed build would leave them for good."""
    monkeypatch.setenv("TMPDIR", str(tmp_path / "system-tmp"))
    (tmp_path / "system-tmp").mkdir()
    import tempfile
    monkeypatch.setattr(tempfile, "tempdir", None)
    assert main(["--quiet", "generate", str(arm(tmp_path)), "--out", str(tmp_path / "pkg")]) == 0
    assert list((tmp_path / "system-tmp").iterdir()) == []
    assert not list((tmp_path / "pkg").glob(".kinegen-build-*"))


D1_URDF = """<robot name="extremes"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><origin xyz="1e-320 0 0.3" rpy="0 0 0"/>
 <axis xyz="0.123456789012345 0.2 0.972222222222222"/><limit lower="-3" upper="3"/></joint>
<joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.4 0 0" rpy="1.5707963267 0 0"/>
 <axis xyz="0.000000000123456 1 0"/></joint>
<joint name="j3" type="prismatic"><parent link="c"/><child link="d"/><origin xyz="0.1 0.2 0.3" rpy="0.1 0.2 0.3"/>
 <axis xyz="1 1 1"/><limit lower="0" upper="0.5"/></joint></robot>"""
D1_TOML = ('name = "tan_arm"\n[[joint]]\ntype = "R"\na = "tan(pi/2 - 1/10**15)"\nalpha = "pi/2"\n'
           '[[joint]]\ntype = "R"\na = 0.5\n')


@pytest.mark.parametrize("name, text", [("extremes.urdf", D1_URDF), ("tan_arm.toml", D1_TOML)])
def test_hostile_d1_extreme_numbers_generate_compile_strictly_and_verify(tmp_path, name, text):
    """A length of 1e-320, axes of 15 digits and one of 1e-10 off a coordinate axis, and a link
    of tan(pi/2 - 1e-15) = 6e14 m: exit 0 and a package that compiles with the strict flags (the
    extension build is the strict compile), verifies against SymPy at 30 digits in both backends,
    and holds no integer literal past 2^53 (issue #28, D1)."""
    import re

    import derivations
    from codegen.verify import verify_model
    path = tmp_path / name
    path.write_text(text)
    out = tmp_path / "pkg"
    assert main(["--quiet", "generate", str(path), "--out", str(out)]) == 0
    for source in out.glob("*.c"):
        body = re.sub(r"/\*.*?\*/", "", source.read_text(), flags=re.S)
        assert [int(m) for m in re.findall(r"(?<![\w.])(\d+)(?![\w.])", body) if int(m) > 2**53] == []
    sys.path.insert(0, str(tmp_path))
    try:
        import importlib
        package = importlib.import_module("pkg")
        checks = verify_model(derivations.load(path), {"numpy": package.load("numpy"), "c": package.load("c")},
                              samples=3)
    finally:
        sys.path.remove(str(tmp_path))
        for module in [m for m in sys.modules if m == "pkg" or m.startswith("pkg.")]:
            del sys.modules[module]
    assert checks and all(c.ok for c in checks), [c for c in checks if not c.ok]


MIMIC_1E308 = """<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j1" multiplier="1e308"/></joint></robot>
"""


@pytest.mark.parametrize("filename, text, message", [
    ("mimic.urdf", MIMIC_1E308, "joint 'j2': mimic multiplier '1e308' is more than 1e+300 in size"),
    ("nul.toml", 'name = "arm"\nurdf = "a\\u0000b.urdf"\n', "field 'urdf': a path with a NUL byte"),
])
def test_hostile_d2_the_input_at_fault_is_exit_2_naming_the_field(tmp_path, capsys, filename, text, message):
    """A mimic multiplier of 1e308 (an OverflowError) and a URDF path holding a NUL byte (a
    ValueError from the operating system's interface) were internal errors with exit 1."""
    (tmp_path / filename).write_text(text)
    assert main(["--quiet", "generate", str(tmp_path / filename), "--out", str(tmp_path / "pkg"), "--no-build"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [filename]


def test_hostile_d2_verify_of_a_kernel_with_no_reference_is_a_failed_check(models, monkeypatch):
    """A system whose entries overflow a double made the reference raise (LinAlgError from the
    SVD of a run-time solve, OverflowError from a value past any float), and `verify` ended in an
    internal error: now that kernel's check fails (error inf), and every other kernel is checked."""
    import numpy as np

    import generated
    from codegen import verify
    exact = verify.reference
    def overflowing(function, values, *args, **kwargs):
        if function.name == "jacobian":
            raise np.linalg.LinAlgError("SVD did not converge")
        return exact(function, values, *args, **kwargs)
    monkeypatch.setattr(verify, "reference", overflowing)
    model = models["planar_2r"]
    checks = verify.verify_model(model, {"numpy": generated.load("planar_2r", backend="numpy")}, samples=2)
    against_sympy = [c for c in checks if c.method.startswith("sympy")]  # not the finite differences
    assert {c.kernel for c in against_sympy} == {f.name for f in model.functions()}
    assert all((c.error == float("inf")) == (not c.ok) == (c.kernel == "jacobian") for c in against_sympy)

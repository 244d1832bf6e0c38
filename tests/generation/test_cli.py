"""The command line, as a user meets it: their own robot, from an empty folder."""
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from codegen.cli import main

# The README's example description, so the walkthrough there is exactly what this test runs.
README = (Path(__file__).resolve().parents[2] / "README.md").read_text()
CYLINDRICAL = re.search(r"```toml\n(.*?)```", README, re.S).group(1)


def cylindrical_by_hand(q, d1=0.5, tool=0.1):
    """The arm extends (q3 + tool) along the heading q1 at height d1 + q2."""
    q1, q2, q3 = q
    return np.array([(q3 + tool) * np.cos(q1), (q3 + tool) * np.sin(q1), d1 + q2])


def run(args, cwd):
    env = dict(os.environ, PYTHONPATH=str(cwd))
    return subprocess.run([sys.executable, "-m", "codegen", *args], cwd=cwd, capture_output=True, text=True, env=env)


def test_a_new_user_generates_imports_and_verifies_their_robot(tmp_path):
    (tmp_path / "cyl.toml").write_text(CYLINDRICAL)
    result = run(["generate", "cyl.toml"], tmp_path)
    assert result.returncode == 0, result.stderr
    package = tmp_path / "cylindrical_rpp"
    assert {"__init__.py", "numpy_kernels.py", "c_kernels.py", "cylindrical_rpp.c", "cylindrical_rpp.h",
            "build_c.py"} <= {p.name for p in package.iterdir()}
    assert "compiling" in result.stderr  # progress on stderr
    q = [0.7, 0.2, 0.35]
    script = ("import json, cylindrical_rpp as r; q = %r; "
              "print(json.dumps([r.task(q).tolist(), r.load('c').task(q).tolist(), r.fk(q)[:3, 3].tolist()]))" % q)
    out = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, check=True)
    numpy_task, c_task, position = np.array(eval(out.stdout))
    expected = cylindrical_by_hand(q)
    np.testing.assert_allclose(numpy_task, expected, atol=1e-15)
    np.testing.assert_allclose(c_task, expected, atol=1e-15)
    np.testing.assert_allclose(position, expected, atol=1e-15)
    verified = run(["--quiet", "verify", "cyl.toml"], tmp_path)
    assert verified.returncode == 0, verified.stdout + verified.stderr
    import derivations
    names = {f.name for f in derivations.load(tmp_path / "cyl.toml").functions()}
    expected = 2 * len(names) + 2 * (1 + 2 * ("jacobian_dot" in names))  # kernels x backends + finite differences
    assert f"{expected} passed, 0 failed" in verified.stdout
    assert verified.stderr == ""  # --quiet


BAD = [
    ("malformed TOML", 'name = "x"\n[[joint]\ntype = "R"\n', r"robot.toml: malformed TOML"),
    ("missing field", '[[joint]]\ntype = "R"\n', r"robot.toml: top level: missing field 'name'"),
    ("unknown joint type", 'name = "arm"\n[[joint]]\ntype = "S"\n', r"robot.toml: joint 1: field 'type': unknown joint type 'S'"),
    ("unknown name", 'name = "arm"\n[[joint]]\ntype = "R"\na = "l7"\n', r"robot.toml: joint 1: field 'a': in 'l7': unknown name 'l7'"),
    ("disallowed construct", 'name = "arm"\n[[joint]]\ntype = "R"\na = "__import__(\'os\').getcwd()"\n', r"robot.toml: joint 1: field 'a': .*only the functions"),
    ("invalid identifier", 'name = "my-arm"\n[[joint]]\ntype = "R"\n', r"robot.toml: field 'name': 'my-arm' is not a valid identifier"),
    ("reserved parameter", 'name = "arm"\n[params]\nreturn = 1.0\n[[joint]]\ntype = "R"\n', r"robot.toml: params: 'return'"),
]


@pytest.mark.parametrize("case, text, message", BAD, ids=[b[0] for b in BAD])
def test_bad_descriptions_exit_2_name_the_place_and_write_nothing(tmp_path, capsys, case, text, message):
    (tmp_path / "robot.toml").write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    status = main(["--quiet", "generate", str(tmp_path / "robot.toml"), "--out", str(tmp_path / "pkg")])
    assert status == 2
    assert re.search(message, capsys.readouterr().err), case
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_an_existing_output_folder_is_refused_unless_forced(tmp_path, capsys):
    (tmp_path / "cyl.toml").write_text(CYLINDRICAL)
    out = tmp_path / "pkg"
    out.mkdir()
    (out / "mine.txt").write_text("keep me")
    assert main(["--quiet", "generate", str(tmp_path / "cyl.toml"), "--out", str(out)]) == 2
    assert "output folder exists (use --force to replace it)" in capsys.readouterr().err
    assert (out / "mine.txt").read_text() == "keep me"
    assert main(["--quiet", "generate", str(tmp_path / "cyl.toml"), "--out", str(out), "--force",
                 "--backend", "numpy"]) == 0
    assert not (out / "mine.txt").exists() and (out / "numpy_kernels.py").is_file()
    assert not (out / "c_kernels.py").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no scratch left behind


def test_a_failed_c_build_leaves_no_package(tmp_path, monkeypatch, capsys):
    from codegen import build

    def broken(folder, name):
        raise build.CompileError("cc failed: simulated")
    monkeypatch.setattr(build, "build_package", broken)
    (tmp_path / "cyl.toml").write_text(CYLINDRICAL)
    assert main(["--quiet", "generate", str(tmp_path / "cyl.toml"), "--out", str(tmp_path / "pkg")]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cyl.toml"]


def test_unknown_robot_and_backend(capsys):
    assert main(["--quiet", "show", "puma561"]) == 2
    assert "unknown robot 'puma561'; known robots:" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["generate", "puma560", "--backend", "fortran"])
    assert exit_info.value.code == 2


def test_list_and_show(capsys):
    assert main(["list"]) == 0
    listed = capsys.readouterr().out
    assert "puma560" in listed and "planar_3r" in listed
    assert main(["--quiet", "show", "planar_3r", "--what", "task"]) == 0
    text = capsys.readouterr().out
    assert "l3*cos(q1 + q2 + q3)" in text
    assert main(["show", "planar_3r", "--what", "task_jacobian", "--latex", "--quiet"]) == 0
    assert r"s_{12}" in capsys.readouterr().out  # the fragments' notation (Kumar's abbreviations)
    assert main(["--quiet", "show", "adept_three", "--what", "dh"]) == 0
    lines = capsys.readouterr().out.splitlines()[1:]
    assert ["2", "R", "l2", "pi", "0", "q2", "0"] in [line.split() for line in lines]
    header = lines[0]
    for line in lines[1:]:  # every column starts where its header does
        assert line[header.index("alpha")] != " " and line[header.index("alpha") - 1] == " "


def test_cli_conventions(capsys, monkeypatch):
    """--version; every robot listed with a title; show and latex take the same --what names;
    show's text fits the terminal (issue #27)."""
    import tomllib
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    version = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())["project"]["version"]
    assert capsys.readouterr().out.strip() == f"kinegen {version}"
    assert main(["list"]) == 0
    rows = [line.split(None, 1) for line in capsys.readouterr().out.splitlines()]
    assert all(len(row) == 2 and row[1].strip() for row in rows), rows
    from codegen.cli import WHAT
    from codegen.backends.latex_backend import SECTION_KEYS
    assert set(SECTION_KEYS) <= set(WHAT)
    for what in ("task", "det", "links"):
        assert main(["--quiet", "show", "planar_2r", "--what", what]) == 0
        assert main(["--quiet", "latex", "planar_2r", "--what", what]) == 0
    capsys.readouterr()
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["--quiet", "show", "puma560", "--what", "fk"]) == 0
    assert max(len(line) for line in capsys.readouterr().out.splitlines()) <= 80


def test_free_text_cannot_break_the_generated_code(tmp_path):
    """A title holding comment and docstring terminators still gives valid C and Python."""
    title = "*/ int oops; /* \"\"\" \\ end"
    hostile = CYLINDRICAL.replace('title = "Cylindrical RPP robot"', f"title = '''{title}'''")
    assert hostile != CYLINDRICAL
    (tmp_path / "cyl.toml").write_text(hostile)
    assert main(["--quiet", "generate", str(tmp_path / "cyl.toml"), "--out", str(tmp_path / "pkg")]) == 0
    script = "import pkg; print(pkg.load('c').task([0.0, 0.0, 0.0]), pkg.__doc__.splitlines()[0])"
    result = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, check=True, capture_output=True, text=True)
    assert "int oops" in result.stdout  # the title survives, defanged

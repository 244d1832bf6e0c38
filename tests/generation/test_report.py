"""The report compiles cleanly (when TeX Live is installed) and its log check can fail."""
import pytest

from codegen import generate, report

NEEDS_PDFLATEX = pytest.mark.skipif(
    report.pdflatex() is None,
    reason="pdflatex is not installed; `make report` installs TeX Live (texlive-latex-base, "
           "texlive-latex-recommended) and builds the report")


@NEEDS_PDFLATEX
def test_report_compiles_without_errors_or_overfull_boxes(tmp_path):
    result = report.build_report(build=tmp_path)
    assert result.pdf.is_file() and result.pdf.stat().st_size > 50_000
    assert result.warnings == ()
    assert result.pages >= 20
    # every generated fragment of a registered robot went into the report
    for path in sorted(generate.GENERATED.glob("*/*.tex")):
        assert f"../generated/{path.parent.name}/{path.name}" in result.log


@NEEDS_PDFLATEX
def test_a_broken_document_is_reported(tmp_path):
    main = tmp_path / "broken.tex"
    main.write_text("\\documentclass{article}\\begin{document}\\undefinedmacro\\end{document}\n")
    with pytest.raises(report.ReportError, match="Undefined control sequence"):
        report.build_report(main=main, build=tmp_path / "build", runs=1)


def test_log_check_finds_overfull_boxes_and_undefined_references():
    log = ("Overfull \\hbox (12.3pt too wide) in paragraph at lines 40--41\n"
           "[]\\OT1/cmr/m/n/10.95 some text\n"
           "Underfull \\hbox (badness 1000) in paragraph at lines 3--4\n"
           "LaTeX Warning: Reference `robot:avr3000' on page 5 undefined on input line 12.\n")
    warnings = report.log_warnings(log)
    assert len(warnings) == 2
    assert warnings[0].startswith("Overfull \\hbox (12.3pt too wide)") and "some text" in warnings[0]
    assert "robot:avr3000" in warnings[1]
    assert report.log_warnings("Underfull \\hbox (badness 1000)\n") == []


# --------------------------------------------------------------------------- one arm: kinegen report FILE

ARMS = generate.REPO / "tests" / "data" / "arms"
URDF_ZOO = generate.REPO / "tests" / "data" / "urdf" / "zoo"


@NEEDS_PDFLATEX
@pytest.mark.parametrize("argv", [
    [str(ARMS / "ur5.toml")],  # closed-form ik in steps: an inverse cosine of a long sum had no line break
    [str(URDF_ZOO / "kr210l150.urdf"), "--base", "base_link", "--tip", "tool0"],  # 15-digit decimals
], ids=["ur5", "kr210"])
def test_report_of_one_arm_is_a_pdf_whose_lines_fit_the_page(tmp_path, capsys, argv):
    from codegen.cli import main
    out = tmp_path / "arm.pdf"
    assert main(["--quiet", "report", *argv, "--out", str(out)]) == 0
    printed = capsys.readouterr()
    assert out.read_bytes().startswith(b"%PDF") and "0 warning(s)" in printed.out, printed.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.pdf"]  # the scratch folder went with the run


def test_report_of_one_arm_refuses_before_any_work(tmp_path, capsys, monkeypatch):
    """Exit 2 with the reason: an existing --out (without --force), a name not ending in .pdf, and
    a machine without pdflatex (naming TeX Live); nothing is derived or written."""
    from codegen import cli
    derive = []
    monkeypatch.setattr(cli, "_load", lambda *a, **k: derive.append(a) or (_ for _ in ()).throw(AssertionError))
    monkeypatch.setattr(report, "pdflatex", lambda: "/usr/bin/pdflatex")
    (tmp_path / "arm.pdf").write_bytes(b"mine")
    assert cli.main(["--quiet", "report", str(ARMS / "ur5.toml"), "--out", str(tmp_path / "arm.pdf")]) == 2
    assert "exists (--force replaces it)" in capsys.readouterr().err
    assert cli.main(["--quiet", "report", str(ARMS / "ur5.toml"), "--out", str(tmp_path / "arm.txt")]) == 2
    assert "expected a file name ending in .pdf" in capsys.readouterr().err
    monkeypatch.setattr(report, "pdflatex", lambda: None)
    assert cli.main(["--quiet", "report", str(ARMS / "ur5.toml"), "--out", str(tmp_path / "new.pdf")]) == 2
    assert "pdflatex not found: install TeX Live" in capsys.readouterr().err
    assert derive == [] and (tmp_path / "arm.pdf").read_bytes() == b"mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.pdf"]

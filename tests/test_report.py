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

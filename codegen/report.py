"""Building the report: ``report/main.tex`` (chapters per paper + generated fragments) -> PDF.

The report inputs the committed fragments ``generated/<name>/<name>.tex``, so it
shows exactly what ``make generate`` wrote.  pdflatex runs in ``report/`` with
its output in ``report/build/``, twice (for the table of contents and the
references), and its log is read for what would make the report untrustworthy:
an error, an overfull box (a line or an equation wider than the page), an
undefined reference.
"""
from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from .generate import REPO

__all__ = ["REPORT", "MAIN", "BUILD", "ReportError", "ReportResult", "build_report", "log_warnings", "pdflatex"]

REPORT = REPO / "report"
MAIN = REPORT / "main.tex"
BUILD = REPORT / "build"
JOB = "kinegen-report"


class ReportError(RuntimeError):
    """pdflatex is missing or failed; the message says which and quotes the log."""


@dataclass(frozen=True)
class ReportResult:
    pdf: Path
    pages: int
    warnings: tuple[str, ...]  # overfull boxes, undefined references: each makes the build fail
    log: str


def pdflatex() -> str | None:
    """The pdflatex executable, or ``None`` when TeX Live is not installed."""
    return shutil.which("pdflatex")


def build_report(main: Path = MAIN, build: Path = BUILD, runs: int = 2) -> ReportResult:
    """Compile ``main`` into ``build/kinegen-report.pdf``; raise :class:`ReportError` on failure."""
    exe = pdflatex()
    if exe is None:
        raise ReportError("pdflatex not found: install TeX Live (`make report` does: "
                          "apt-get install texlive-latex-base texlive-latex-recommended)")
    build.mkdir(parents=True, exist_ok=True)
    command = [exe, "-interaction=nonstopmode", "-halt-on-error", "-file-line-error",
               f"-output-directory={build}", f"-jobname={JOB}", main.name]
    log = ""
    for _ in range(runs):
        done = subprocess.run(command, cwd=main.parent, capture_output=True, text=True, errors="replace")
        log_path = build / f"{JOB}.log"
        log = log_path.read_text(errors="replace") if log_path.is_file() else done.stdout
        if done.returncode != 0:
            raise ReportError(f"pdflatex failed (exit {done.returncode}):\n{_error_excerpt(log)}")
    pdf = build / f"{JOB}.pdf"
    pages = re.search(r"Output written on .*?\((\d+) pages?", log.replace("\n", ""))
    return ReportResult(pdf, int(pages.group(1)) if pages else 0, tuple(log_warnings(log)), log)


def log_warnings(log: str) -> list[str]:
    """Overfull boxes and undefined references or citations in a pdflatex log."""
    warnings = []
    lines = log.splitlines()
    for k, line in enumerate(lines):
        if line.startswith("Overfull \\hbox") or line.startswith("Overfull \\vbox"):
            context = lines[k + 1].strip() if k + 1 < len(lines) else ""
            warnings.append(f"{line.strip()} {context[:80]}")
        elif re.search(r"LaTeX Warning: (Reference|Citation) .* undefined", line):
            warnings.append(line.strip())
        elif "There were undefined references" in line:
            warnings.append(line.strip())
    return warnings


def _error_excerpt(log: str) -> str:
    lines = log.splitlines()
    for k, line in enumerate(lines):
        if line.startswith("!") or re.match(r"^[^:\s]+\.tex:\d+:", line):
            return "\n".join(lines[k:k + 12])
    return "\n".join(lines[-20:])

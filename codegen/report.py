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

__all__ = ["REPORT", "MAIN", "BUILD", "ReportError", "ReportResult", "build_report", "build_robot_report",
           "log_warnings", "pdflatex"]

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


def build_report(main: Path = MAIN, build: Path = BUILD, runs: int = 2, job: str = JOB) -> ReportResult:
    """Compile ``main`` into ``build/<job>.pdf``; raise :class:`ReportError` on failure."""
    exe = pdflatex()
    if exe is None:
        raise ReportError("pdflatex not found: install TeX Live (`make report` does: "
                          "apt-get install texlive-latex-base texlive-latex-recommended)")
    build.mkdir(parents=True, exist_ok=True)
    command = [exe, "-interaction=nonstopmode", "-halt-on-error", "-file-line-error",
               f"-output-directory={build}", f"-jobname={job}", main.name]
    log = ""
    for _ in range(runs):
        done = subprocess.run(command, cwd=main.parent, capture_output=True, text=True, errors="replace")
        log_path = build / f"{job}.log"
        log = log_path.read_text(errors="replace") if log_path.is_file() else done.stdout
        if done.returncode != 0:
            raise ReportError(f"pdflatex failed (exit {done.returncode}):\n{_error_excerpt(log)}")
    pdf = build / f"{job}.pdf"
    pages = re.search(r"Output written on .*?\((\d+) pages?", log.replace("\n", ""))
    return ReportResult(pdf, int(pages.group(1)) if pages else 0, tuple(log_warnings(log)), log)


# One arm's report: its fragment (the package's <name>.tex) in a document of its own, with the
# preamble of report/main.tex (the same text width, so that what fits one fits the other).
ROBOT_DOCUMENT = r"""% kinegen report of one robot; the fragment beside it is generated.
\documentclass[11pt,a4paper]{article}
\usepackage[margin=2.5cm]{geometry}
\usepackage{amsmath,amssymb}
\usepackage{array,booktabs,tabularx}
\usepackage{microtype}
\usepackage[hidelinks]{hyperref}
\allowdisplaybreaks
\setlength{\emergencystretch}{3em}
\setlength{\parindent}{0pt}
\setlength{\parskip}{0.5\baselineskip}
\renewcommand{\arraystretch}{1.25}
\newcommand{\kinegenrobot}[2]{\section*{#1}\label{robot:#2}}
\newcommand{\kinegenpart}[1]{\subsection*{#1}}
\begin{document}
\input{FRAGMENT}
\end{document}
"""


def build_robot_report(fragments: dict[str, str], out: Path) -> ReportResult:
    """One robot's PDF at ``out`` from its LaTeX fragment (``{<name>.tex: text}``, as
    latex_backend.render gives it), built in a scratch folder beside ``out`` and moved into place
    only when pdflatex succeeded; the result's ``pdf`` is ``out``."""
    import os
    import tempfile
    (name, fragment), = fragments.items()
    out = Path(out)
    with tempfile.TemporaryDirectory(prefix=f".{out.name}-kinegen-", dir=out.parent) as scratch:
        scratch = Path(scratch)
        (scratch / name).write_text(fragment)
        main = scratch / "main.tex"
        main.write_text(ROBOT_DOCUMENT.replace("FRAGMENT", Path(name).stem))
        result = build_report(main, scratch / "build", job="robot")
        os.replace(result.pdf, out)
    return ReportResult(out, result.pages, result.warnings, result.log)


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

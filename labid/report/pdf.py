"""Print the HTML certificate to PDF in a headless browser (Debian's ``chromium``).

``browser() -> path | None`` finds it; ``html_to_pdf(html_path, pdf_path)`` prints one file
(A4, the page margins and "Page n of N" of the certificate's ``@page`` rules, no browser
header or footer). The flags are those a root process on a closed network needs: no
sandbox, no GPU, no background networking. Used by the certificate's rendering test and
the screenshot script; a ``UserError`` when no browser is installed.
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from ..base.errors import UserError

NAMES = ("chromium", "chromium-browser", "google-chrome")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--no-pdf-header-footer")


def browser() -> str | None:
    """The path of a Chromium-family browser, or None."""
    return next((p for p in map(shutil.which, NAMES) if p), None)


def html_to_pdf(html_path: str | Path, pdf_path: str | Path, timeout_s: float = 900.0) -> Path:
    """Print ``html_path`` to ``pdf_path`` with headless Chromium; returns the PDF's path. The
    timeout is a hang guard (15 min), not a speed budget: a print takes ~1 s CPU."""
    exe = browser()
    if exe is None:
        raise UserError("no chromium on PATH: install it (apt-get install chromium) to print the report to PDF")
    pdf = Path(pdf_path).resolve()
    with tempfile.TemporaryDirectory(prefix="labid-chromium-") as profile:
        p = subprocess.run([exe, *FLAGS, f"--user-data-dir={profile}", f"--print-to-pdf={pdf}",
                            Path(html_path).resolve().as_uri()], capture_output=True, text=True, timeout=timeout_s)
    if p.returncode != 0 or not pdf.exists():
        tail = (p.stderr.strip().splitlines() or ["no message"])[-1]
        raise UserError(f"chromium could not print the report (exit {p.returncode}: {tail})", file=str(html_path))
    return pdf

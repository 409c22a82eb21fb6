"""The report as PDF: the HTML printed by headless Chromium (Debian's chromium package), a
well-kept engine that draws the page margin boxes (page numbers, the campaign id) of the
report's print CSS. Nothing else renders it: without Chromium there is no PDF, and it is said."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from campaign.errors import InputError

BROWSERS = ("chromium", "chromium-browser", "google-chrome")
"""The executables tried, in order (Debian names its package chromium)."""
TIMEOUT_S = 120.0
"""The longest a print may take; a report prints in a few seconds."""


def browser() -> str:
    """The path of the first of BROWSERS found; InputError saying how to install one."""
    for name in BROWSERS:
        if found := shutil.which(name):
            return found
    raise InputError("--pdf: no PDF engine: headless Chromium is not installed (Debian: apt-get install chromium)")


def print_pdf(html: Path, pdf: Path) -> Path:
    """Print the report `html` to `pdf` (A4, the report's own page footer, no browser header)."""
    flags = ["--headless", "--disable-gpu", "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--no-pdf-header-footer",
             "--run-all-compositor-stages-before-draw", "--virtual-time-budget=5000"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        flags.append("--no-sandbox")  # Chromium's sandbox refuses to run as root
    try:
        pdf.parent.mkdir(parents=True, exist_ok=True)
        pdf.unlink(missing_ok=True)
    except OSError as exc:
        raise InputError(f"--pdf: {pdf}: cannot write ({exc.strerror})") from None
    with tempfile.TemporaryDirectory(prefix="axiscal-pdf-") as profile:
        try:
            proc = subprocess.run([browser(), *flags, f"--user-data-dir={profile}",
                                   f"--print-to-pdf={pdf.resolve()}", html.resolve().as_uri()],
                                  capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired:
            raise InputError(f"--pdf: Chromium did not print {html} within {TIMEOUT_S:g} s") from None
    if proc.returncode != 0 or not pdf.is_file() or pdf.stat().st_size == 0:
        last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
        raise InputError(f"--pdf: Chromium could not print {html} (exit {proc.returncode}: {last})")
    return pdf

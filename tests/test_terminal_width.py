"""The command line says the same at any terminal width (fast tier): a narrow terminal may wrap a
line or split a table in two, never cut or drop what is said. Each command runs in-process at
COLUMNS=60 and COLUMNS=200, from a working directory of its own with short file names; what is
said, without the spaces, line breaks and table rules between the words, must be the same (a word
folded over two lines joins up again; a cut one does not). `analyze` is not among them: at 60
columns it splits its per-target table in two on purpose, repeating the target column."""

from __future__ import annotations

import re
import shutil

import pytest
from rich.cells import cell_len

from tests.conftest import PAPER, ROOT

COMMANDS = [
    ("plan", "demo.toml"),
    ("convert", "v.csv", "-o", "v.rtl"),
    ("compensate", "h.csv", "--format", "linuxcnc", "-o", "comp.txt"),
]


def said(text: str) -> str:
    """`text` without whitespace and rich's box-drawing characters (they scale with the width)."""
    return "".join(re.sub("[\u2500-\u257f]", " ", text).split())


@pytest.mark.parametrize("command", COMMANDS, ids=[c[0] for c in COMMANDS])
def test_a_command_says_the_same_at_60_and_200_columns(cli, monkeypatch, tmp_path, command):
    out = {}
    for width in (60, 200):
        here = tmp_path / str(width)
        here.mkdir()
        shutil.copy(PAPER / "horizontal_before.csv", here / "h.csv")
        shutil.copy(PAPER / "vertical_before.csv", here / "v.csv")
        shutil.copy(ROOT / "campaign" / "demo.toml", here / "demo.toml")
        monkeypatch.chdir(here)
        monkeypatch.setenv("COLUMNS", str(width))
        result = cli(*command)
        assert result.code == 0, result.err
        out[width] = result.out
    assert max(cell_len(line) for line in out[60].splitlines()) <= 60  # the width was used (x̄ is one cell)
    assert said(out[60]) == said(out[200])


def test_into_a_file_or_pipe_a_line_of_text_stays_one_line_however_long_its_path(cli, tmp_path):
    """Without a terminal and without COLUMNS (a pipe, a log file, pytest's capture), a sentence
    with a long path is one line: it used to be wrapped at 120 columns, so a test's assertion
    passed or failed with the length of pytest's temporary directory."""
    deep = tmp_path / ("a-directory-with-a-long-name-" * 4)
    deep.mkdir()
    shutil.copy(PAPER / "vertical_before.csv", deep / "v.csv")
    result = cli("convert", deep / "v.csv", "-o", deep / "v.rtl")
    assert result.code == 0, result.err
    summary = [line for line in result.out.splitlines() if "points" in line]
    assert len(summary) == 1 and len(summary[0]) > 120 and "ISO 230-2: A" in summary[0], result.out

"""People read µm, never the files' ASCII "um", in every command that prints deviations."""

import re

import pytest

from tests.conftest import PAPER

TABLE = PAPER / "horizontal_before.csv"


@pytest.mark.parametrize("command", [
    ("analyze", TABLE),
    ("analyze", TABLE, "--wide"),
    ("discover", TABLE),
    ("refine", TABLE),
    ("compensate", TABLE, "--format", "linuxcnc", "-o", "{tmp}/c.txt"),
    ("compensate", TABLE, "--format", "csv", "-o", "{tmp}/c.csv", "--mode", "bi"),
])
def test_no_ascii_um_and_every_deviation_in_micrometres(cli, tmp_path, command):
    result = cli(*[str(a).format(tmp=tmp_path) for a in command])
    assert result.code == 0, result.err
    assert "µm" in result.out
    assert not re.search(r"\bum\b", result.out + result.err), result.out

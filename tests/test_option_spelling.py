"""One spelling across commands: -o/--output for a file, --out for a campaign directory."""

import argparse

import pytest

from campaign.cli import build_parser
from campaign.commands import SUMMARY


def options(command: str) -> list[argparse.Action]:
    parser = build_parser([command])
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]._actions


@pytest.mark.parametrize("command", list(SUMMARY))
def test_output_options_are_spelled_one_way(command):
    for action in options(command):
        strings = set(action.option_strings)
        if "-o" in strings:
            assert strings == {"-o", "--output"}, (command, strings)
        if "--output" in strings:
            assert "-o" in strings, (command, strings)
        if "--out" in strings:
            assert strings == {"--out"} and action.metavar == "DIR", (command, strings, action.metavar)


@pytest.mark.parametrize("command", list(SUMMARY))
def test_rates_are_in_micrometres_per_second(command):
    for action in options(command):
        if "rate" in " ".join(action.option_strings):
            assert action.metavar == "UM_PER_S" and "µm/s" in action.help, (command, action.option_strings)

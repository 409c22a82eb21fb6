"""The interferometer's ASCII line protocol: default format, configured formats, garbage."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from campaign.errors import BAD_INPUT
from protocols.hardware import Reading
from protocols.serial_line import LineError, LineFormat, checksum_hex, format_line, parse_line

DEFAULT = LineFormat()
EXAMPLE = "POS,12.5,100.00125,87.5,20.31,1013.25,45.2,20.07*77\r\n"


def test_the_documented_example_line():
    reading = parse_line(EXAMPLE, DEFAULT)
    assert reading == Reading(
        time_s=12.5,
        position=100.00125,
        signal_ok=True,
        signal_pct=87.5,
        air_temp_c=20.31,
        air_pressure_hpa=1013.25,
        humidity_pct=45.2,
        material_temp_c=20.07,
    )
    assert format_line(reading, DEFAULT) == EXAMPLE


def test_lf_only_and_no_line_end_are_accepted_and_lowercase_hex():
    body = EXAMPLE.rstrip("\r\n")
    assert parse_line(body + "\n", DEFAULT) == parse_line(EXAMPLE, DEFAULT)
    assert parse_line(body, DEFAULT) == parse_line(EXAMPLE, DEFAULT)
    line = "POS,1,2,50,,,,*" + checksum_hex("POS,1,2,50,,,,").lower()
    assert parse_line(line, DEFAULT).position == 2.0


def test_empty_fields_are_absent():
    line = "POS,1.0,-3.5,50,,,,"
    reading = parse_line(f"{line}*{checksum_hex(line)}", DEFAULT)
    assert reading == Reading(time_s=1.0, position=-3.5, signal_ok=True, signal_pct=50.0)


def test_low_signal_means_beam_not_ok():
    line = "POS,1.0,2.0,5,,,,"
    reading = parse_line(f"{line}*{checksum_hex(line)}", DEFAULT)
    assert reading.signal_ok is False and reading.signal_pct == 5.0


def _with_checksum(body: str) -> str:
    return f"{body}*{checksum_hex(body)}\r\n"


@pytest.mark.parametrize(
    "text",
    [
        "",
        "\r\n",
        "POS,12.5,100.00125,87.5,20.31,1013.25,45.2,20.07*78\r\n",  # wrong checksum
        "POS,12.5,100.00125,87.5,20.31,1013.25,45.2,20.07\r\n",  # no checksum
        "POS,12.5,100.00125,87.5,20.31,10",  # partial line
        "13.25,45.2,20.07*77\r\n",  # the rest of a partial line
        _with_checksum("POS,12.5,100.0,87.5,,,"),  # a field missing
        _with_checksum("POS,12.5,100.0,87.5,,,,,"),  # a field too many
        _with_checksum("STA,12.5,100.0,87.5,,,,"),  # another tag
        _with_checksum("POS,,100.0,87.5,,,,"),  # no time
        _with_checksum("POS,1,,87.5,,,,"),  # no position
        _with_checksum("POS,1,2,,,,,"),  # no signal
        _with_checksum("POS,1,nan,87.5,,,,"),
        _with_checksum("POS,1,inf,87.5,,,,"),
        _with_checksum("POS,1,1e999,87.5,,,,"),
        _with_checksum("POS,1,1_000,87.5,,,,"),
        _with_checksum("POS,1,0x10,87.5,,,,"),
        _with_checksum("POS,1,2,87.5,twenty,,,"),
        _with_checksum("POS,1,\u0663,87.5,,,,"),  # an Arabic-Indic digit
    ],
)
def test_bad_lines_raise_line_error(text):
    with pytest.raises(LineError):
        parse_line(text, DEFAULT)


def _readings(fmt: LineFormat):
    finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6)
    optional = st.none() | finite

    def reading(time_s, position, signal_pct, *env):
        return Reading(time_s, position, signal_pct >= fmt.signal_threshold_pct, signal_pct, *env)

    return st.builds(reading, finite, finite, st.floats(0, 100), *[optional] * 4)


@given(_readings(DEFAULT))
def test_round_trip_default_format(reading):
    assert parse_line(format_line(reading, DEFAULT), DEFAULT) == reading


MICRON_SEMICOLON = LineFormat.from_dict(
    {
        "tag": "",
        "separator": ";",
        "decimal_mark": ",",
        "fields": ["time_s", "position", "beam_ok", "skip", "air_temp_c"],
        "position_scale": 0.001,
        "checksum": False,
        "line_end": "\r",
        "beam_ok_text": "OK",
        "beam_lost_text": "LOST",
    },
    "test",
)


def test_semicolon_decimal_comma_micron_format_from_config():
    reading = parse_line("12,5;100001,25;OK;whatever;20,5\r", MICRON_SEMICOLON)
    assert reading.time_s == 12.5
    assert reading.position == pytest.approx(100.00125, abs=1e-12)
    assert reading.signal_ok is True and reading.signal_pct is None
    assert reading.air_temp_c == 20.5 and reading.air_pressure_hpa is None
    assert parse_line("12,5;100001,25;LOST;;\r", MICRON_SEMICOLON).signal_ok is False
    for bad in ("12,5;100001,25;MAYBE;;", "12.5;100001,25;OK;;", "12,5;100001,25;OK;;*00"):
        with pytest.raises(LineError):
            parse_line(bad, MICRON_SEMICOLON)


def test_space_separated_inch_format_with_unit_word():
    fmt = LineFormat.from_dict(
        {
            "tag": "",
            "separator": " ",
            "fields": ["time_s", "position", "skip", "signal_pct"],
            "position_scale": 25.4,
            "checksum": False,
            "signal_threshold_pct": 30,
        },
        "test",
    )
    reading = parse_line("3.25 1.5000 in 42\r\n", fmt)
    assert reading.position == pytest.approx(38.1)
    assert reading.signal_ok is True
    assert parse_line("3.25 1.5000 in 29.9\r\n", fmt).signal_ok is False


@given(_readings(MICRON_SEMICOLON))
def test_round_trip_configured_format(reading):
    reading = Reading(reading.time_s, reading.position, reading.signal_ok, air_temp_c=reading.air_temp_c)
    back = parse_line(format_line(reading, MICRON_SEMICOLON), MICRON_SEMICOLON)
    assert back.position == pytest.approx(reading.position, rel=1e-15, abs=1e-300)
    assert back == Reading(reading.time_s, back.position, reading.signal_ok, air_temp_c=reading.air_temp_c)


@settings(max_examples=500)
@given(st.binary(max_size=200))
def test_arbitrary_bytes_raise_only_line_error(data):
    _parse_or_line_error(data.decode("latin-1"), DEFAULT)
    _parse_or_line_error(data.decode("latin-1"), MICRON_SEMICOLON)


@settings(max_examples=500)
@given(st.text(alphabet=st.sampled_from("POS,*0123456789.-+eE;\r\n abcdefINF"), max_size=80))
def test_arbitrary_near_miss_text_raises_only_line_error(text):
    _parse_or_line_error(text, DEFAULT)
    _parse_or_line_error(_with_checksum(text.rstrip("\r\n")), DEFAULT)
    _parse_or_line_error(text, MICRON_SEMICOLON)


def _parse_or_line_error(text: str, fmt: LineFormat) -> None:
    try:
        reading = parse_line(text, fmt)
    except LineError:
        return
    assert math.isfinite(reading.time_s) and math.isfinite(reading.position)


@pytest.mark.parametrize(
    "table, key",
    [
        ({"colour": "red"}, "colour"),
        ({"fields": ["time_s", "position", "speed"]}, "fields"),
        ({"fields": ["position", "signal_pct"]}, "fields"),
        ({"fields": ["time_s", "position"]}, "fields"),
        ({"fields": ["time_s", "position", "position", "signal_pct"]}, "fields"),
        ({"fields": "time_s,position"}, "fields"),
        ({"separator": ""}, "separator"),
        ({"separator": "."}, "separator"),
        ({"decimal_mark": ";"}, "decimal_mark"),
        ({"position_scale": 0}, "position_scale"),
        ({"position_scale": "1000"}, "position_scale"),
        ({"position_scale": float("nan")}, "position_scale"),
        ({"signal_threshold_pct": True}, "signal_threshold_pct"),
        ({"checksum": 1}, "checksum"),
        ({"tag": "P,S"}, "tag"),
        ({"tag": 7}, "tag"),
        ({"line_end": "x"}, "line_end"),
        ({"request": ""}, "request"),
        ({"beam_ok_text": "0"}, "beam_lost_text"),
    ],
)
def test_bad_config_raises_input_error_naming_the_key(table, key):
    with pytest.raises(BAD_INPUT) as caught:
        LineFormat.from_dict(table, "cfg.toml [instrument.line]")
    message = str(caught.value)
    assert message.startswith("cfg.toml [instrument.line]: ")
    assert f"'{key}'" in message and "\n" not in message


def test_empty_config_gives_the_default_format():
    assert LineFormat.from_dict({}, "cfg") == DEFAULT
    assert DEFAULT.request == "?\r\n" and DEFAULT.terminator == "\n"

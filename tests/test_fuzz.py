"""Hostile input: whatever the bytes, the parsers and loaders end in a one-line `error:` with exit
status 2 (or a valid result), never a traceback and never a hang (hypothesis deadlines)."""

import string

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from campaign.config import parse_config
from campaign.errors import BAD_INPUT
from campaign.faults import parse_faults, parse_inject
from campaign.model import model_from_dict
from campaign.pointtable import parse_points
from protocols.serial_line import LineError, LineFormat, parse_line
from tests.conftest import assert_one_line_error
from tests.test_plan import BASE

FUZZ = settings(max_examples=200, deadline=2000, suppress_health_check=[HealthCheck.function_scoped_fixture])
CSV_ALPHABET = string.printable + "\u2212\ufeff\x00é"
HEADER = "run,direction,target_mm,deviation_um\n"


@FUZZ
@given(st.text(alphabet=CSV_ALPHABET, max_size=400))
def test_point_table_text(text):
    try:
        parse_points(text, "fuzz.csv")
    except BAD_INPUT as exc:
        assert "\n" not in str(exc) and str(exc).startswith("fuzz.csv")


@FUZZ
@given(st.lists(st.tuples(st.text(max_size=6), st.sampled_from(["+", "-", "x", "\u2212", ""]),
                          st.text(max_size=8), st.text(max_size=8)), min_size=1, max_size=20))
def test_point_table_rows(rows):
    text = HEADER + "".join(",".join(r) + "\n" for r in rows)
    try:
        table = parse_points(text, "rows.csv")
        assert len(table) == len(rows)
    except BAD_INPUT as exc:
        assert "\n" not in str(exc)


def test_a_run_number_too_large_for_an_integer_is_bad_input(cli, tmp_path):
    """Found by test_point_table_rows on a fresh clone: a run of 1E100 is a finite number, whole, and
    at least 1, but no integer array holds it: it was an internal error, not one `error:` line."""
    path = tmp_path / "p.csv"
    for run in ("1E100", "1000001"):
        path.write_text(HEADER + f"{run},+,0,0\n", encoding="utf-8")
        result = cli("analyze", path)
        assert result.code == 2
        assert_one_line_error(result, str(path))


def test_point_table_binary_through_cli(cli, tmp_path):
    @settings(max_examples=60, deadline=4000, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(st.binary(min_size=1, max_size=300))
    def check(data):
        path = tmp_path / "b.csv"
        path.write_bytes(data)
        result = cli("analyze", path, "--json")
        if result.code != 0:
            assert_one_line_error(result, str(path))

    check()


@FUZZ
@given(st.text(max_size=400))
def test_config_text(text):
    try:
        parse_config(text, "fuzz.toml")
    except BAD_INPUT as exc:
        assert "\n" not in str(exc)


SCALARS = st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=True, allow_infinity=True),
                    st.booleans(), st.text(max_size=10), st.lists(st.integers(), max_size=3))


@FUZZ
@given(st.sampled_from(["axis", "plan", "capture", "environment", "instrument", "campaign", "sim", "axis_driver"]),
       st.text(alphabet=string.ascii_lowercase + "_", min_size=1, max_size=20), SCALARS)
def test_config_values(section, key, value):
    import tomllib

    from campaign.config import config_from_dict

    data = tomllib.loads(BASE)
    data.setdefault(section, {})[key] = value
    try:
        config_from_dict(data, "fuzz.toml")
    except BAD_INPUT as exc:
        assert "\n" not in str(exc)


@FUZZ
@given(st.dictionaries(st.text(max_size=12), SCALARS, max_size=6))
def test_line_format_tables(table):
    try:
        fmt = LineFormat.from_dict(table, "fuzz.toml")
    except BAD_INPUT as exc:
        assert "\n" not in str(exc)
        return
    try:
        parse_line("POS,1,2,3,,,,*00", fmt)
    except LineError:
        pass


@FUZZ
@given(st.dictionaries(st.text(max_size=30), st.dictionaries(st.text(max_size=12), SCALARS, max_size=4),
                       max_size=4))
def test_model_and_fault_tables(table):
    for load in (lambda: model_from_dict({"effects": table}, "m.toml"), lambda: parse_faults(table, "f.toml")):
        try:
            load()
        except BAD_INPUT as exc:
            assert "\n" not in str(exc)


@FUZZ
@given(st.text(max_size=60))
def test_inject_option(text):
    try:
        parse_inject(text)
    except BAD_INPUT as exc:
        assert "\n" not in str(exc)

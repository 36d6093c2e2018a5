"""The one strict number reader (clockwork/numbers.py)."""

import math

import pytest

from clockwork.numbers import CSV_SPECIAL, XSD_SPECIAL, parse_int, parse_json, parse_real, shorten


@pytest.mark.parametrize("text, value", [
    ("0", 0.0), ("-1.5", -1.5), ("+2", 2.0), (".5", 0.5), ("5.", 5.0), ("1e3", 1000.0),
    ("1.25E-2", 0.0125), ("-0", -0.0), ("0.1745", 0.1745),
])
def test_decimal_numbers_read_as_float_reads_them(text, value):
    assert parse_real(text) == value


@pytest.mark.parametrize("text", [
    "1_0", "0.17_45", " 1", "1 ", "", "+", ".", "e3", "1e", "1.2.3", "0x10", "１", "1,5",
    "inf", "nan", "INF", "NaN", "infinity", "1e3_0", "--1", "1d0",
])
def test_what_float_accepts_and_files_do_not_is_refused(text):
    with pytest.raises(ValueError):
        parse_real(text)


def test_special_values_only_in_their_own_spelling():
    assert parse_real("INF", XSD_SPECIAL) == math.inf
    assert parse_real("-INF", XSD_SPECIAL) == -math.inf
    assert math.isnan(parse_real("NaN", XSD_SPECIAL))
    for text in ("inf", "nan", "Infinity"):
        with pytest.raises(ValueError):
            parse_real(text, XSD_SPECIAL)
    assert parse_real("-Infinity", CSV_SPECIAL, special_case_insensitive=True) == -math.inf
    assert math.isnan(parse_real("NAN", CSV_SPECIAL, special_case_insensitive=True))


def test_integers():
    assert parse_int("-12") == -12
    for text in ("1_0", "1.0", " 1", "1e3", ""):
        with pytest.raises(ValueError):
            parse_int(text)


def test_not_text_is_refused():
    with pytest.raises(ValueError):
        parse_real(1.0)


def test_shorten_bounds_an_echoed_value():
    assert shorten("abc") == "abc"
    long = "x" * (4 << 20)
    s = shorten(long)
    assert len(s) <= 200 and str(len(long)) in s



# --- JSON ------------------------------------------------------------------------------

@pytest.mark.parametrize("text", ['{"a": NaN}', '[Infinity]', '[-Infinity]', '[1e400]', '[-1e309]',
                                  '{"a": 1, "a": 2}', '{"x": {"b": [], "b": {}}}'])
def test_json_that_python_reads_and_rfc_8259_does_not_is_refused(text):
    import json

    json.loads(text)  # Python reads it
    with pytest.raises(ValueError):
        parse_json(text)


def test_strict_json_reads_json():
    assert parse_json(b'{"a": [1, 2.5e-3, -0.0, null, true, "x"], "b": {"c": 1e308}}') == \
        {"a": [1, 0.0025, -0.0, None, True, "x"], "b": {"c": 1e308}}


def test_clockwork_reads_json_only_through_the_strict_reader():
    """Every JSON file clockwork reads (case files, the cache, points, the
    commit journal, summaries, quick.json, FMU manifests) goes through
    numbers.parse_json: no json.load(s) anywhere else in the package."""
    import re
    from pathlib import Path

    import clockwork

    root = Path(clockwork.__file__).parent
    found = [f"{p.relative_to(root)}:{i}" for p in root.rglob("*.py") if p.name != "numbers.py"
             for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"\bjson\.loads?\(", line)]
    assert not found, found

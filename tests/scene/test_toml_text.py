"""TOML text of the values envcap writes into scene files reads back exactly (``envcap.scene.toml_text``)."""

from __future__ import annotations

import math
import tomllib

import pytest

from envcap.scene.toml_text import toml_key, toml_string, toml_table, toml_value

NASTY = ['a "quoted" name', "C:\\Users\\x\\city.ply", "line\nbreak\r\n", "tab\tand\x00nul\x1f\x7f", "é 東京 😀", "", "'"]


@pytest.mark.parametrize("text", NASTY)
def test_any_string_reads_back_and_stays_on_one_line(text: str) -> None:
    written = toml_string(text)
    assert "\n" not in written and "\x7f" not in written
    assert tomllib.loads(f"k = {written}")["k"] == text
    assert tomllib.loads(f"{toml_key(text)} = 1") == {text: 1} if text else True


def test_numbers_lists_and_inline_tables_read_back() -> None:
    values = {"f": [0.1, -0.0, 1e-300, 5e22, 150276.432778], "i": [0, -3, 2**40], "b": [True, False],
              "crop": {"min": [0.0, -1.5, 2.0], "my key": "x"}, "inf": [math.inf, -math.inf]}
    back = tomllib.loads(toml_table("[t]", values))["t"]
    assert back == values
    assert math.isnan(tomllib.loads(f"x = {toml_value(math.nan)}")["x"])


def test_what_cannot_be_written_is_refused() -> None:
    with pytest.raises(ValueError, match="not valid Unicode"):
        toml_string("bad\udcffname")         # a file name that was not UTF-8 (surrogate escape)
    with pytest.raises(TypeError, match="cannot write a set"):
        toml_value({1, 2})

"""TOML text of values that envcap writes into scene files (``envcap streets``' ``scene.toml``).

Python reads TOML (:mod:`tomllib`) but does not write it; these few functions write the values a
scene file holds, so that :func:`tomllib.loads` reads back exactly what was written:

* strings as basic strings: ``"`` and ``\\`` escaped, every control character (U+0000-U+001F,
  U+007F) as ``\\uXXXX`` or its short escape, everything else as UTF-8 (a path with a quote,
  a backslash or a newline stays one valid line);
* finite floats by :func:`repr` (the shortest text that reads back to the same float), ``inf`` /
  ``nan`` as TOML spells them; integers; booleans;
* lists (arrays) and dicts (inline tables) of those, keys bare when they can be, else quoted.

A string that cannot be UTF-8 (a lone surrogate: a file name that was not valid UTF-8) is a
``ValueError`` naming it.
"""

from __future__ import annotations

import math
import re
from typing import Any

_SHORT = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def toml_string(text: str) -> str:
    """``text`` as a TOML basic string, quotes included (``'a"b'`` -> ``"a\\"b"``)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise ValueError(f"{text!r} is not valid Unicode text (a file name that is not UTF-8?): "
                         "it cannot be written into a TOML file") from None
    out = []
    for ch in text:
        if ch in _SHORT:
            out.append(_SHORT[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_key(key: str) -> str:
    """A key: bare (``offset``) when it may be, else quoted (``"my key"``)."""
    return key if _BARE_KEY.fullmatch(key) else toml_string(key)


def toml_value(value: Any) -> str:
    """A TOML value of a string, bool, int, float, list or dict (inline table).  ``TypeError``
    for anything else (dates are not part of a scene file)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_key(str(k))} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"cannot write a {type(value).__name__} as a TOML value: {value!r}")


def toml_table(header: str, values: dict[str, Any]) -> str:
    """``[header]`` (or ``[[header]]`` when given so) and one ``key = value`` line per entry,
    sub-tables as inline tables; ends with a newline."""
    lines = [header] + [f"{toml_key(k)} = {toml_value(v)}" for k, v in values.items()]
    return "\n".join(lines) + "\n"

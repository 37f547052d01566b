"""Typed dataclasses <-> strict JSON, driven by the type hints; errors name the field path.

The manifest types (:mod:`envcap.probeset.manifest`, :mod:`envcap.probeset.planes`) are plain
frozen dataclasses whose field order is the JSON key order.  :func:`from_json` checks a parsed
JSON value against a dataclass and builds it; :func:`to_json` turns one back into plain JSON
types (numpy scalars become Python numbers).  Supported field types: ``int``, ``float`` (finite;
an integer is accepted), ``str``, ``bool``, ``X | None``, ``tuple[X, ...]``, fixed-length
``tuple[X, Y, Z]``, nested dataclasses, ``dict[str, float]`` and ``dict[str, Any]`` (a free-form
JSON object, kept as it is).

Field ``metadata`` adjusts the JSON form of a field:

* ``{"json": "omit_none"}``: the key is absent when the value is ``None`` (and may be absent on read);
* ``{"json": "empty_object_none"}``: ``None`` is written as ``{}`` (and ``{}`` reads as ``None``);
* ``{"json": "rest", "pattern": REGEX}``: a ``dict`` field that collects the object's other keys
  matching ``REGEX`` (its one group is the dict key; without a group the whole key is used),
  written at the field's place as ``key_format.format(dict key)`` (default ``"{}"``).

Every other key must be present (a default only serves Python callers).  Unknown keys are errors.  Checks beyond types
(ranges, cross-field rules) belong to the caller.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import types
import typing
from typing import Any, TypeVar

import numpy as np

from envcap.core.input_path import require_file

T = TypeVar("T")


class ManifestError(ValueError):
    """A JSON value that does not match its dataclass; the message starts with the field path."""


def _err(path: str, msg: str) -> ManifestError:
    return ManifestError(f"{path}: {msg}" if path else msg)


def _key(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _kind(x: Any) -> str:
    return {dict: "an object", list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(x), "a number" if _is_number(x) else type(x).__name__)


def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _optional_inner(tp: Any) -> Any | None:
    """``X`` for ``X | None``, else ``None``."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0]
    return None


def _decode(tp: Any, v: Any, path: str) -> Any:
    inner = _optional_inner(tp)
    if inner is not None:
        return None if v is None else _decode(inner, v, path)
    if tp is Any:
        return v
    if tp is float:
        if not (_is_number(v) and math.isfinite(v)):
            raise _err(path, f"must be a finite number, got {v!r}")
        return float(v)
    if tp is int:
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool):
            raise _err(path, f"must be an integer, got {v!r}")
        return int(v)
    if tp is str or tp is bool:
        if not isinstance(v, tp):
            raise _err(path, f"must be {'a string' if tp is str else 'true or false'}, got {v!r}")
        return v
    if dataclasses.is_dataclass(tp):
        return from_json(tp, v, path)
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is tuple:
        if not isinstance(v, (list, tuple)):
            raise _err(path, f"must be an array, got {_kind(v)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_decode(args[0], x, f"{path}[{i}]") for i, x in enumerate(v))
        if len(v) != len(args):
            raise _err(path, f"must be an array of {len(args)} entries, got {len(v)}: {v!r}")
        return tuple(_decode(a, x, f"{path}[{i}]") for i, (a, x) in enumerate(zip(args, v)))
    if origin is dict:
        if not isinstance(v, dict) or not all(isinstance(k, str) for k in v):
            raise _err(path, f"must be an object, got {_kind(v)}")
        return {k: _decode(args[1], x, _key(path, k)) for k, x in v.items()}
    raise TypeError(f"{path}: field type {tp!r} is not supported by the JSON codec")


def _rest_key(f: dataclasses.Field, key: str) -> str | None:
    """The dict key a ``rest`` field stores JSON ``key`` under, or ``None`` if it does not match."""
    m = re.fullmatch(f.metadata.get("pattern", ".+"), key)
    if m is None:
        return None
    return m.group(1) if m.re.groups else key


def from_json(cls: type[T], obj: Any, path: str = "") -> T:
    """Build dataclass ``cls`` from the parsed JSON ``obj``; raise :class:`ManifestError` naming
    the first field (``key[i].key...``, relative to ``path``) that is missing, unknown or of the
    wrong type."""
    if not isinstance(obj, dict):
        raise _err(path, f"must be an object, got {_kind(obj)}")
    hints = _hints(cls)
    fields = dataclasses.fields(cls)
    named = [f for f in fields if f.metadata.get("json") != "rest"]
    rest = [f for f in fields if f.metadata.get("json") == "rest"]
    values: dict[str, Any] = {}
    for f in named:
        mode = f.metadata.get("json")
        if f.name not in obj:
            if mode != "omit_none":
                raise _err(path, f"missing key {f.name!r}")
            values[f.name] = None
            continue
        v = obj[f.name]
        if mode == "empty_object_none" and v == {}:
            values[f.name] = None
            continue
        values[f.name] = _decode(hints[f.name], v, _key(path, f.name))
    names = {f.name for f in named}
    for key in obj:
        if key in names:
            continue
        for f in rest:
            k = _rest_key(f, key)
            if k is not None:
                value_type = typing.get_args(hints[f.name])[1]
                values.setdefault(f.name, {})[k] = _decode(value_type, obj[key], _key(path, key))
                break
        else:
            raise _err(path, f"unknown key {key!r} (expected {sorted(names)})")
    return cls(**values)


def _encode(v: Any) -> Any:
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return to_json(v)
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_encode(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _encode(x) for k, x in v.items()}
    return v


def to_json(obj: Any) -> dict[str, Any]:
    """Dataclass ``obj`` as a dict of plain JSON types, keys in field order (see the module doc)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        mode = f.metadata.get("json")
        if mode == "rest":
            for k, x in v.items():
                key = f.metadata.get("key_format", "{}").format(k)
                if key in out or key in {g.name for g in dataclasses.fields(obj)}:
                    raise ManifestError(f"{type(obj).__name__}.{f.name}: key {key!r} collides with another entry")
                out[key] = _encode(x)
        elif v is None and mode == "omit_none":
            continue
        elif v is None and mode == "empty_object_none":
            out[f.name] = {}
        else:
            out[f.name] = _encode(v)
    return out


def read_json_file(path: str | os.PathLike[str], what: str) -> Any:
    """The JSON document in the file ``path``: ``FileNotFoundError`` ("``what`` not found: PATH")
    or :class:`ManifestError` (not valid JSON, naming the file)."""
    p = require_file(path, what)
    try:
        return json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ManifestError(f"{p}: not valid JSON ({e})") from e
    except RecursionError:   # arrays or objects nested thousands deep
        raise ManifestError(f"{p}: not valid JSON for envcap (nested too deep)") from None
    except ValueError as e:  # an integer literal past Python's digit limit (sys.get_int_max_str_digits)
        raise ManifestError(f"{p}: not valid JSON for envcap ({str(e).split(';')[0]})") from None


def json_text(obj: Any) -> str:
    """A document as envcap writes its JSON files: 2-space indented strict JSON, a final newline."""
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"

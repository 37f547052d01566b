"""Strict reading of nested TOML tables: every key is consumed or reported, numbers are checked.

A :class:`Table` wraps a dict with its dotted location (``file: streets[1].side_min.random``) so
every error names the file and the key.  Unknown keys are an error (typos must not pass).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""Largest finite float32 (3.4028235e38): every number of a scene file is at most this in size."""

_MISSING = object()


class Table:
    """A TOML table being read; ``close()`` raises on keys nobody asked for."""

    def __init__(self, data: Any, where: str) -> None:
        if not isinstance(data, dict):
            raise ValueError(f"{where}: expected a table, got {type(data).__name__}")
        self.data = data
        self.where = where
        self._used: set[str] = set()

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        self._used.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise ValueError(f"{self.where or 'top level'}: missing required key '{key}'")
            return default
        return self.data[key]

    def sub(self, key: str) -> "Table | None":
        v = self.raw(key, None)
        return None if v is None else Table(v, f"{self.where}.{key}" if self.where else key)

    def string(self, key: str, default: Any = _MISSING, choices: tuple[str, ...] | None = None) -> str:
        v = self.raw(key, default)
        if not isinstance(v, str):
            raise ValueError(f"{self._loc(key)}: expected a string, got {v!r}")
        if choices is not None and v not in choices:
            raise ValueError(f"{self._loc(key)}: {v!r} is not one of {list(choices)}")
        return v

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        v = self.raw(key, default)
        if not isinstance(v, bool):
            raise ValueError(f"{self._loc(key)}: expected true or false, got {v!r}")
        return v

    def number(
        self,
        key: str,
        default: Any = _MISSING,
        *,
        min: float | None = None,
        max: float | None = None,
        positive: bool = False,
    ) -> float:
        v = self.raw(key, default)
        return check_number(v, self._loc(key), min=min, max=max, positive=positive)

    def integer(self, key: str, default: Any = _MISSING, *, min: int | None = None, max: int | None = None) -> int:
        v = self.raw(key, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise ValueError(f"{self._loc(key)}: expected an integer, got {v!r}")
        if min is not None and v < min:
            raise ValueError(f"{self._loc(key)}: must be >= {min}, got {_shown(v)}")
        if max is not None and v > max:
            raise ValueError(f"{self._loc(key)}: must be <= {max}, got {_shown(v)}")
        return v

    def vector(self, key: str, n: int, default: Any = _MISSING, *, min: float | None = None,
               max: float | None = None, gray: bool = False) -> tuple[float, ...]:
        """A list of ``n`` numbers, each in [``min``, ``max``]; with ``gray`` a single number ``x``
        means ``[x, x, x]``."""
        v = self.raw(key, default)
        if gray and isinstance(v, (int, float)) and not isinstance(v, bool) and n == 3:
            v = [v, v, v]  # a gray value for a color
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise ValueError(f"{self._loc(key)}: expected a list of {n} numbers, got {v!r}")
        return tuple(check_number(x, self._loc(key), min=min, max=max) for x in v)

    def range(self, key: str, default: Any = _MISSING, *, min: float | None = None, max: float | None = None,
              positive: bool = False) -> tuple[float, float]:
        """A ``[lo, hi]`` pair with lo <= hi, both in [``min``, ``max``] (a single number means ``[x, x]``)."""
        v = self.raw(key, default)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v, v]
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise ValueError(f"{self._loc(key)}: expected [min, max], got {v!r}")
        lo, hi = (check_number(x, self._loc(key), min=min, max=max, positive=positive) for x in v)
        if lo > hi:
            raise ValueError(f"{self._loc(key)}: min {lo} is larger than max {hi}")
        return lo, hi

    def tables(self, key: str) -> list["Table"]:
        v = self.raw(key, [])
        if not isinstance(v, list):
            raise ValueError(f"{self._loc(key)}: expected an array of tables ([[{key}]])")
        return [Table(x, f"{self._loc(key)}[{i}]") for i, x in enumerate(v)]

    def close(self) -> None:
        unknown = sorted(set(self.data) - self._used)
        if unknown:
            raise ValueError(f"{self.where or 'top level'}: unknown key(s) {unknown}")

    def _loc(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key


def check_number(v: Any, where: str, *, min: float | None = None, max: float | None = None,
                 positive: bool = False) -> float:
    """``v`` (an int or a float, not a bool) as a float in [``min``, ``max``] (and > 0 with
    ``positive``); always finite and within float32 range.  ``ValueError`` naming ``where``."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"{where}: expected a number, got {v!r}")
    try:
        x = float(v)
    except OverflowError:  # an integer past float range (10**400)
        x = math.inf
    if not math.isfinite(x):
        raise ValueError(f"{where}: must be finite and within float32 range (|x| <= {FLOAT32_MAX:.4g}), got {_shown(v)}")
    if positive and not x > 0:
        raise ValueError(f"{where}: must be positive, got {x:g}")
    if min is not None and x < min:
        raise ValueError(f"{where}: must be >= {min:g}, got {x:g}")
    if max is not None and x > max:
        raise ValueError(f"{where}: must be <= {max:g}, got {x:g}")
    if abs(x) > FLOAT32_MAX:
        raise ValueError(f"{where}: must be within float32 range (|x| <= {FLOAT32_MAX:.4g}), got {x:g}")
    return x


def _shown(v: int | float) -> str:
    """``v`` for a message: an integer too long to print is given by its size."""
    if isinstance(v, int) and v.bit_length() > 64:
        return f"an integer of {v.bit_length()} bits"
    return repr(v)

"""Shared validation: numbers, sizes, directions and table keys.

Every checker returns the cleaned value or raises ``ValueError`` with a message that starts with
the name it was given (``name`` / ``where``), so an error points at the offending argument or
scene-file key.  The stage packages validate their own concepts (a cube, a manifest, a sky) and
build on these.
"""

from __future__ import annotations

import math
from typing import Any, Collection

import numpy as np
from numpy.typing import ArrayLike, NDArray


def format_number(value: Any) -> str:
    """A number for a message as Python writes a plain number (``5``, ``2.5``, ``3.0``, ``1e+30``,
    ``nan``), numpy scalars included (never ``np.float64(2.5)``); anything else as its ``repr``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return repr(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def format_numbers(values: Any) -> str:
    """A sequence of numbers for a message: ``[1.0, 2.5, -3.0]`` (see :func:`format_number`)."""
    return "[" + ", ".join(format_number(v) for v in np.asarray(values).ravel().tolist()) + "]"


def finite_float(value: Any, name: str) -> float:
    """``value`` (a Python or numpy number, not a bool) as a finite float."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except OverflowError:  # an integer past float range, e.g. 10**400 written in a TOML file
        raise ValueError(f"{name} must be finite, got an integer of {int(value).bit_length()} bits") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def float_in_range(value: Any, name: str, lo: float, hi: float, unit: str = "") -> float:
    """``value`` (as :func:`finite_float` takes it) as a float in the closed range [``lo``, ``hi``];
    the error names the range and ``unit`` (e.g. ``"degrees"``): ``"NAME must be in [lo, hi] unit,
    got x"``."""
    v = finite_float(value, name)
    if not lo <= v <= hi:
        raise ValueError(f"{name} must be in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}, got {v:g}")
    return v


def positive_int(value: Any, name: str) -> int:
    """``value`` (a Python or numpy integer, not a bool) >= 1, as an int: a size or a count."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def finite_directions(d: ArrayLike, name: str = "directions") -> NDArray[np.float64]:
    """Directions ``(..., 3)`` as float64, unchanged (any length): finite and none all-zero."""
    a = np.asarray(d, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise ValueError(f"{name} must have shape (..., 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contain NaN or Inf")
    if np.any(np.all(a == 0, axis=-1)):
        raise ValueError(f"{name}: zero-length direction")
    return a


def unit_directions(d: ArrayLike, name: str = "directions") -> NDArray[np.float64]:
    """:func:`finite_directions` divided by their Euclidean length: unit vectors ``(..., 3)`` float64.

    A direction whose length is not a positive finite float64 (components below ~1e-154 or above
    ~1e154) cannot be normalized and raises like a zero one."""
    a = finite_directions(d, name)
    with np.errstate(over="ignore"):
        norm = np.linalg.norm(a, axis=-1, keepdims=True)
    if np.any(norm == 0) or not np.all(np.isfinite(norm)):
        raise ValueError(f"{name}: zero-length direction (or a length outside float64 range)")
    return a / norm


def check_table_keys(table: Any, required: Collection[str], optional: Collection[str], where: str) -> None:
    """``table`` is a dict holding every ``required`` key and no key outside ``required | optional``."""
    if not isinstance(table, dict):
        raise ValueError(f"{where} must be a table, got {type(table).__name__}")
    req, allowed = set(required), set(required) | set(optional)
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    missing = sorted(req - set(table))
    if missing:
        raise ValueError(f"{where}: missing key(s) {missing}")

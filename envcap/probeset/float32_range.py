"""Every number of a probe-set manifest must survive the trip to the GPU: float32 and int32 range.

The runtime uploads probe positions, planes, street extents, lobe powers and the sun as float32
uniforms and indexes layers with 32-bit integers; a value that is finite as a JSON (float64)
number but past float32's range (``1e300``) becomes ``inf`` there.  :func:`check_number_ranges`
walks a manifest (any tree of dataclasses, tuples, lists and dicts) and raises
:class:`envcap.probeset.json_codec.ManifestError` at the first number outside the range, naming
its field path (``streets[0].probes[1].position[0]``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from envcap.probeset.json_codec import ManifestError

__all__ = ["FLOAT32_MAX", "INT32_MAX", "check_number_ranges", "positive_in_float32"]

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""Largest finite float32 (3.4028235e38): a real number must satisfy ``|x| <= FLOAT32_MAX``."""

INT32_MAX = int(np.iinfo(np.int32).max)
"""Largest int32 (2147483647): an integer must satisfy ``|i| <= INT32_MAX``."""


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def check_number_ranges(obj: Any, where: str = "") -> None:
    """Raise :class:`ManifestError` (``"WHERE: PATH: ..."``) at the first number in ``obj``
    outside float32 (reals) or int32 (integers) range; booleans and strings are skipped.

    ``obj``: a dataclass instance, tuple, list, dict (its values) or number; ``where``: what
    ``obj`` is (a file name), put before the field path.  Free-form objects (a sky spec) are
    walked too.
    """
    prefix = f"{where}: " if where else ""
    stack: list[tuple[str, Any]] = [("", obj)]
    while stack:
        path, v = stack.pop()
        where = f"{prefix}{path or 'value'}"
        if isinstance(v, (bool, np.bool_, str, bytes)) or v is None:
            continue
        if isinstance(v, (int, np.integer)):
            if abs(int(v)) > INT32_MAX:
                raise ManifestError(f"{where}: {int(v)} is outside the int32 range (|i| <= {INT32_MAX})")
            continue
        if isinstance(v, (float, np.floating)):
            x = float(v)
            if not (math.isfinite(x) and abs(x) <= FLOAT32_MAX):
                raise ManifestError(f"{where}: {x!r} is outside the float32 range (|x| <= {FLOAT32_MAX:.8g}); "
                                    "the GPU holds this number as float32")
            continue
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            stack += [(_join(path, f.name), getattr(v, f.name)) for f in reversed(dataclasses.fields(v))]
        elif isinstance(v, dict):
            stack += [(_join(path, str(k)), x) for k, x in reversed(list(v.items()))]
        elif isinstance(v, (list, tuple)):
            stack += [(f"{path}[{i}]", x) for i, x in reversed(list(enumerate(v)))]


def positive_in_float32(x: float) -> bool:
    """Whether ``x`` is positive and stays positive as float32 (``1e-300`` does not: it becomes 0)."""
    return bool(x > 0 and np.float32(x) > 0)

"""Strict uniform setting for moderngl programs: a name the program does not have is an error.

moderngl, like OpenGL, silently ignores writes to a uniform that is not there, so a typo or a
uniform renamed in GLSL leaves the old value (usually 0) and the program quietly computes
something else.  :func:`set_uniforms` refuses such names.  One exception is explicit: a uniform
that the GLSL source declares but does not use is removed by the compiler (it is not *active*,
and writing it would have no effect); pass the source as ``sources`` to allow those names.

Values are converted to the uniform's own type (``float`` -> float32, ``int``/samplers -> int32,
``uint`` -> uint32, ``double`` -> float64; an integer uniform refuses non-integral values) and
written in C order: scalars and vectors as they are, arrays of vectors as ``(count, dim)``, and
matrices **column-major** as GLSL stores them, i.e. pass ``m.T`` for a row-major numpy ``m``.
An array uniform may receive fewer elements than it holds (the rest is set to 0); any other
size mismatch is an error.
"""

from __future__ import annotations

import re
from typing import Any, Iterable, Mapping

import moderngl
import numpy as np

_COMMENTS = re.compile(r"/\*.*?\*/|//[^\n]*", re.DOTALL)
# `uniform [precision] TYPE name[, name2][[N]];` after layout qualifiers; uniform blocks (`{`) excluded.
_DECLARATION = re.compile(r"\buniform\s+(?:(?:lowp|mediump|highp)\s+)?\w+\s+([^;{}()]+);")
_NAME = re.compile(r"^\s*(\w+)\s*(?:\[[^\]]*\])?\s*$")

_DTYPES = {"f": np.float32, "i": np.int32, "I": np.uint32, "d": np.float64}


def declared_uniforms(*sources: str) -> frozenset[str]:
    """Names of the uniforms declared in GLSL ``sources`` (comments ignored).

    Every declaration in the text counts, including those in preprocessor branches that a
    compilation leaves out.  Uniform blocks are not included.
    """
    names: set[str] = set()
    for src in sources:
        for decl in _DECLARATION.finditer(_COMMENTS.sub(" ", src)):
            for part in decl.group(1).split(","):
                m = _NAME.match(part)
                if m:
                    names.add(m.group(1))
    return frozenset(names)


def set_uniforms(prog: moderngl.Program | moderngl.ComputeShader, values: Mapping[str, Any], *,
                 sources: Iterable[str] = ()) -> None:
    """Set the uniforms ``values`` (name -> value) of ``prog``; see the module docstring.

    Raises ``KeyError`` for a name that is not an active uniform of ``prog`` (unless the GLSL
    ``sources`` declare it: then the compiler removed it as unused and it is skipped), and
    ``ValueError`` for a value of the wrong size or a non-integral value for an integer uniform.
    Struct members are named as GLSL does (``"street.count"``).
    """
    declared: frozenset[str] | None = None
    for name, value in values.items():
        if name not in prog:
            if declared is None:
                declared = declared_uniforms(*sources)
            if name.split(".")[0].split("[")[0] in declared:
                continue
            active = sorted(k for k in prog if isinstance(prog[k], moderngl.Uniform))
            raise KeyError(f"uniform '{name}' is not in the program (active uniforms: {active})")
        u = prog[name]
        if not isinstance(u, moderngl.Uniform):
            raise KeyError(f"'{name}' is a {type(u).__name__} of the program, not a uniform")
        _write(name, u, value)


def _write(name: str, u: moderngl.Uniform, value: Any) -> None:
    dtype = _DTYPES.get(u.fmt[-1])
    if dtype is None:
        raise ValueError(f"uniform '{name}': unsupported GLSL type (moderngl format {u.fmt!r})")
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"uniform '{name}': expected numbers, got {arr.dtype} {value!r}")
    if dtype is not np.float32 and dtype is not np.float64 and arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)) or not np.array_equal(arr, np.round(arr)):
            raise ValueError(f"uniform '{name}' is an integer uniform, got non-integral {value!r}")
    flat = arr.astype(dtype).ravel()
    dim, length = int(u.dimension), int(u.array_length)
    if length == 1 and flat.size != dim:
        raise ValueError(f"uniform '{name}' holds {dim} value(s), got {flat.size}")
    if length > 1 and (flat.size % dim or flat.size > dim * length):
        raise ValueError(f"uniform '{name}' is an array of {length} x {dim} values, got {flat.size}")
    if flat.size < dim * length:
        buf = np.zeros(dim * length, dtype=dtype)
        buf[: flat.size] = flat
        flat = buf
    u.write(flat.tobytes())

"""glTF 2.0 accessors <-> numpy arrays (on a :class:`pygltflib.GLTF2` whose buffers are one binary
blob, as a ``.glb`` loads or after ``convert_buffers(BufferFormat.BINARYBLOB)``).

:func:`read_accessor` decodes an accessor to ``(count, components)`` (``SCALAR``: ``(count,)``;
``MAT4``: ``(count, 4, 4)`` in the usual row/column order, i.e. transposed from glTF's column-major
storage) honouring ``byteOffset``, ``byteStride`` and ``normalized``; sparse accessors and
accessors without a buffer view are refused with a clear error.  :func:`append_accessor` appends an
array as a new tightly packed, 4-byte aligned buffer view + accessor (``min``/``max`` written for
``POSITION``-like float data when asked) and returns its index.  pygltflib is the glTF library
(trimesh's glTF importer reads neither ``skins`` nor ``animations``).
"""

from __future__ import annotations

import numpy as np
import pygltflib
from numpy.typing import NDArray

COMPONENT_DTYPES = {
    pygltflib.BYTE: np.dtype("<i1"), pygltflib.UNSIGNED_BYTE: np.dtype("<u1"),
    pygltflib.SHORT: np.dtype("<i2"), pygltflib.UNSIGNED_SHORT: np.dtype("<u2"),
    pygltflib.UNSIGNED_INT: np.dtype("<u4"), pygltflib.FLOAT: np.dtype("<f4"),
}
"""glTF componentType -> numpy little-endian dtype."""
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
"""glTF accessor type -> number of components."""


class GltfError(ValueError):
    """A glTF file that envcap cannot read (the message names the file part at fault)."""


def blob(gltf: pygltflib.GLTF2) -> bytes:
    """The one binary buffer of ``gltf`` (``b""`` when it has none)."""
    data = gltf.binary_blob()
    return bytes(data) if data is not None else b""


def read_accessor(gltf: pygltflib.GLTF2, index: int) -> NDArray:
    """Accessor ``index`` as a numpy array: float64 for float or normalized data, else int64."""
    if not isinstance(index, int) or not 0 <= index < len(gltf.accessors):
        raise GltfError(f"accessor {index!r} does not exist (the file has {len(gltf.accessors)})")
    acc = gltf.accessors[index]
    if acc.sparse is not None:
        raise GltfError(f"accessor {index} is sparse; sparse accessors are not supported")
    if acc.bufferView is None or not 0 <= acc.bufferView < len(gltf.bufferViews):
        raise GltfError(f"accessor {index} has no valid bufferView")
    if acc.componentType not in COMPONENT_DTYPES or acc.type not in TYPE_SIZES:
        raise GltfError(f"accessor {index}: unknown componentType {acc.componentType} or type {acc.type!r}")
    view = gltf.bufferViews[acc.bufferView]
    data = blob(gltf)
    dtype = COMPONENT_DTYPES[acc.componentType]
    ncomp = TYPE_SIZES[acc.type]
    elem = dtype.itemsize * ncomp
    if acc.type in ("MAT2", "MAT3") and dtype.itemsize < 4:
        raise GltfError(f"accessor {index}: padded small-component matrices are not supported")
    stride = view.byteStride or elem
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    count = int(acc.count)
    end = start + (stride * (count - 1) + elem if count else 0)
    if count < 0 or stride < elem or end > (view.byteOffset or 0) + view.byteLength or end > len(data):
        raise GltfError(f"accessor {index} reads past its bufferView or the binary buffer "
                        f"(bytes {start}..{end}, buffer {len(data)})")
    raw = np.frombuffer(data, dtype=np.uint8, count=end - start, offset=start) if count else np.zeros(0, np.uint8)
    rows = np.lib.stride_tricks.as_strided(raw, shape=(count, elem), strides=(stride, 1)) if count else raw.reshape(0, elem)
    values = np.ascontiguousarray(rows).view(dtype).reshape(count, ncomp)
    if dtype.kind == "f":
        out = values.astype(np.float64)
        if not np.all(np.isfinite(out)):
            raise GltfError(f"accessor {index} holds NaN or infinite values")
    elif acc.normalized:
        info = np.iinfo(dtype)
        out = np.maximum(values.astype(np.float64) / info.max, -1.0)
    else:
        out = values.astype(np.int64)
    if acc.type == "SCALAR":
        return out[:, 0]
    if acc.type.startswith("MAT"):
        n = int(round(ncomp ** 0.5))
        return out.reshape(count, n, n).transpose(0, 2, 1)  # column-major storage
    return out


def append_accessor(gltf: pygltflib.GLTF2, array: NDArray, component_type: int, *, target: int | None = None,
                    with_bounds: bool = False, normalized: bool = False) -> int:
    """Append ``array`` (``(count,)`` SCALAR, ``(count, 2..4)`` VEC, ``(count, 4, 4)`` MAT4) to the
    binary blob as a new buffer view + accessor of ``component_type``; returns the accessor index.
    Creates the single buffer when the file has none."""
    a = np.asarray(array)
    if a.ndim == 1:
        kind, flat = "SCALAR", a[:, None]
    elif a.ndim == 2 and a.shape[1] in (2, 3, 4):
        kind, flat = f"VEC{a.shape[1]}", a
    elif a.ndim == 3 and a.shape[1:] == (4, 4):
        kind, flat = "MAT4", a.transpose(0, 2, 1).reshape(len(a), 16)
    else:
        raise ValueError(f"cannot store an array of shape {a.shape} as a glTF accessor")
    dtype = COMPONENT_DTYPES[component_type]
    if dtype.kind == "f" and not np.all(np.isfinite(flat)):
        raise ValueError("refusing to write NaN or infinite values to a glTF accessor")
    payload = np.ascontiguousarray(flat.astype(dtype)).tobytes()
    data = blob(gltf)
    data += b"\0" * (-len(data) % 4)
    if not gltf.buffers:
        gltf.buffers.append(pygltflib.Buffer(byteLength=0))
    gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(data), byteLength=len(payload), target=target))
    data += payload + b"\0" * (-len(payload) % 4)
    gltf.set_binary_blob(data)
    gltf.buffers[0].byteLength = len(data)
    acc = pygltflib.Accessor(bufferView=len(gltf.bufferViews) - 1, componentType=component_type, count=len(a),
                             type=kind, normalized=True if normalized else None)
    if with_bounds and len(a):
        acc.min = [float(v) for v in flat.astype(dtype).min(axis=0)]
        acc.max = [float(v) for v in flat.astype(dtype).max(axis=0)]
    gltf.accessors.append(acc)
    return len(gltf.accessors) - 1

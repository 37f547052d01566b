"""Hypothesis strategies that mutate valid inputs: parsed trees (TOML scenes, JSON manifests),
bytes (any file), KTX2 header and level-index fields, OpenEXR header attributes.

Each strategy returns ``(mutated, log)`` where ``log`` is a short list of what was changed
(shown in failure reports and the catalog).
"""

from __future__ import annotations

import copy
import json
import math
import re
import struct
from typing import Any

from hypothesis import strategies as st

# --------------------------------------------------------------------------------------------
# Values

EDGE_NUMBERS: list[Any] = [
    0, -1, 1, 2, 7, 2**31, 2**63 - 1, -(2**63), 10**30, 10**400,
    0.0, -0.0, 5e-324, 1e-300, 1e-12, 1e-9, 1e-6, 0.5, 1e6, 1e7, 1e9, 1e12, 1e30, 1e300,
    1.7976931348623157e308, -1e30, -1e-9, math.nan, math.inf, -math.inf,
]
"""Numbers at the edges: zero and signed zero, denormals, float32/float64 overflow, NaN, Inf, big ints."""

SCALES = [0.0, -1.0, 1e-9, 1e-3, 10.0, 1e6, 1e30, 1e300]
"""Factors that move a valid number out of its sane range."""

text = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=12)


def numbers() -> st.SearchStrategy[Any]:
    return st.one_of(
        st.sampled_from(EDGE_NUMBERS),
        st.integers(-(2**70), 2**70),
        st.floats(allow_nan=True, allow_infinity=True),
    )


def leaf_values() -> st.SearchStrategy[Any]:
    """A replacement for any leaf: a number, a string, a bool, a short list or a small table."""
    small = st.one_of(numbers(), text, st.booleans())
    return st.one_of(
        numbers(),
        numbers(),
        st.sampled_from(["", "x", "canyon", "latlong", "uniform", "preetham", "z", "y", "../nope.toml", "sky.exr",
                         "imported_block/", "é", "\x00"]),
        text,
        st.booleans(),
        st.lists(small, max_size=4),
        st.dictionaries(st.sampled_from(["a", "type", "width", "file"]), small, max_size=2),
    )


# --------------------------------------------------------------------------------------------
# Trees (parsed TOML / JSON)


def _paths(tree: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(tree, dict):
        for k, v in tree.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            out += _paths(v, prefix + (i,))
    return out


def _get(tree: Any, path: tuple) -> Any:
    for k in path:
        tree = tree[k]
    return tree


@st.composite
def mutated_tree(draw: st.DrawFn, tree: Any, max_ops: int = 3, unknown_key: str = "zzz_unknown") -> tuple[Any, list[str]]:
    """``tree`` with 1..max_ops edits: set a node to an edge value, scale a number, delete a key
    or item, add an unknown key, duplicate a list item, replace a table by a scalar."""
    tree = copy.deepcopy(tree)
    log: list[str] = []
    for _ in range(draw(st.integers(1, max_ops))):
        paths = [p for p in _paths(tree) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent, key = _get(tree, path[:-1]), path[-1]
        node = parent[key]
        ops = ["set", "delete", "add"]
        if isinstance(node, (int, float)) and not isinstance(node, bool):
            ops += ["scale", "scale"]
        if isinstance(parent, list):
            ops += ["duplicate"]
        op = draw(st.sampled_from(ops))
        where = ".".join(str(k) for k in path)
        if op == "set":
            v = draw(leaf_values())
            parent[key] = v
            log.append(f"{where} = {v!r}")
        elif op == "scale":
            f = draw(st.sampled_from(SCALES))
            try:
                parent[key] = node * f
            except OverflowError:  # an int past float range
                parent[key] = -node
            log.append(f"{where} *= {f!r} -> {parent[key]!r}")
        elif op == "delete":
            del parent[key]
            log.append(f"del {where}")
        elif op == "duplicate":
            parent.insert(key, copy.deepcopy(node))
            log.append(f"dup {where}")
        else:  # add a key beside the node (or into it)
            host = node if isinstance(node, dict) else parent if isinstance(parent, dict) else None
            if host is None:
                parent[key] = draw(leaf_values())
                log.append(f"{where} = <leaf>")
            else:
                v = draw(leaf_values())
                host[unknown_key] = v
                log.append(f"add {unknown_key} = {v!r} near {where}")
    return tree, log


# --------------------------------------------------------------------------------------------
# TOML writing (inline tables and arrays: enough for any tree of tomllib's types)

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: Any) -> str:
    k = str(k)
    return k if _BARE.match(k) else json.dumps(k)


def _toml_value(v: Any) -> str | None:
    if v is None:
        return None
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        r = repr(v)
        return r if any(c in r for c in ".en") else r + ".0"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        items = [x for x in (_toml_value(i) for i in v) if x is not None]
        return "[" + ", ".join(items) + "]"
    if isinstance(v, dict):
        items = [f"{_toml_key(k)} = {x}" for k, x in ((k, _toml_value(i)) for k, i in v.items()) if x is not None]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def to_toml(tree: dict) -> str:
    """A TOML document that ``tomllib`` parses back to ``tree`` (``None`` values are dropped)."""
    lines = []
    for k, v in tree.items():
        s = _toml_value(v)
        if s is not None:
            lines.append(f"{_toml_key(k)} = {s}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Bytes


@st.composite
def mutated_bytes(draw: st.DrawFn, data: bytes, hot: int = 256, max_ops: int = 3) -> tuple[bytes, list[str]]:
    """``data`` with 1..max_ops byte edits (flip bits, set a byte, insert, delete, truncate, append);
    positions favour the first ``hot`` bytes (the header)."""
    b = bytearray(data)
    log: list[str] = []
    for _ in range(draw(st.integers(1, max_ops))):
        if not b:
            break
        n = len(b)
        pos = draw(st.one_of(st.integers(0, min(hot, n) - 1), st.integers(0, n - 1)))
        op = draw(st.sampled_from(["flip", "flip", "set", "insert", "delete", "truncate", "append"]))
        if op == "flip":
            bit = draw(st.integers(0, 7))
            b[pos] ^= 1 << bit
            log.append(f"flip byte {pos} bit {bit}")
        elif op == "set":
            v = draw(st.sampled_from([0, 1, 0x7F, 0x80, 0xFF]))
            b[pos] = v
            log.append(f"byte {pos} = 0x{v:02x}")
        elif op == "insert":
            ins = draw(st.binary(min_size=1, max_size=16))
            b[pos:pos] = ins
            log.append(f"insert {len(ins)} bytes at {pos}")
        elif op == "delete":
            k = draw(st.integers(1, 16))
            del b[pos:pos + k]
            log.append(f"delete {k} bytes at {pos}")
        elif op == "truncate":
            del b[pos:]
            log.append(f"truncate to {pos} bytes")
        else:
            extra = draw(st.binary(min_size=1, max_size=64))
            b += extra
            log.append(f"append {len(extra)} bytes")
    return bytes(b), log


# --------------------------------------------------------------------------------------------
# KTX2 fields

KTX2_HEADER = struct.Struct("<12s9I4I2Q")
KTX2_FIELDS = ["vkFormat", "typeSize", "pixelWidth", "pixelHeight", "pixelDepth", "layerCount", "faceCount",
               "levelCount", "supercompressionScheme", "dfdByteOffset", "dfdByteLength", "kvdByteOffset",
               "kvdByteLength", "sgdByteOffset", "sgdByteLength"]
KTX2_LEVEL = struct.Struct("<3Q")


@st.composite
def mutated_ktx2_field(draw: st.DrawFn, data: bytes) -> tuple[bytes, list[str]]:
    """Set one KTX2 header field or level-index entry to an edge value (in range of its width)."""
    hdr = list(KTX2_HEADER.unpack_from(data, 0))
    levels = hdr[8]
    choices = [("header", i) for i in range(len(KTX2_FIELDS))] + [("level", (k, j)) for k in range(levels) for j in range(3)]
    kind, idx = draw(st.sampled_from(choices))
    if kind == "header":
        old = hdr[1 + idx]
        wide = idx >= 13
    else:
        k, j = idx
        old = KTX2_LEVEL.unpack_from(data, KTX2_HEADER.size + KTX2_LEVEL.size * k)[j]
        wide = True
    top = 2**64 - 1 if wide else 2**32 - 1
    cand = [0, 1, 2, 3, 6, 7, 97, 109, old + 1, max(old - 1, 0), old * 2, old // 2, len(data), len(data) + 1,
            2**31, 2**32 - 1, top]
    v = min(draw(st.one_of(st.sampled_from(cand), st.integers(0, top))), top)
    b = bytearray(data)
    if kind == "header":
        hdr[1 + idx] = v
        KTX2_HEADER.pack_into(b, 0, *hdr)
        name = KTX2_FIELDS[idx]
    else:
        k, j = idx
        ent = list(KTX2_LEVEL.unpack_from(data, KTX2_HEADER.size + KTX2_LEVEL.size * k))
        ent[j] = v
        KTX2_LEVEL.pack_into(b, KTX2_HEADER.size + KTX2_LEVEL.size * k, *ent)
        name = f"level[{k}].{['byteOffset', 'byteLength', 'uncompressedByteLength'][j]}"
    return bytes(b), [f"{name}: {old} -> {v}"]


def ktx2_level0(data: bytes) -> tuple[int, int, int]:
    """``(offset, length, component size)`` of level 0's texels in a valid KTX2 file."""
    hdr = KTX2_HEADER.unpack_from(data, 0)
    off, length, _ = KTX2_LEVEL.unpack_from(data, KTX2_HEADER.size)
    return off, length, hdr[2]


@st.composite
def ktx2_with_texel(draw: st.DrawFn, data: bytes) -> tuple[bytes, list[str]]:
    """A valid KTX2 file with texel components of level 0 set to NaN, Inf, negative or huge values."""
    off, length, size = ktx2_level0(data)
    b = bytearray(data)
    log = []
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, length // size - 1))
        if size == 2:
            name, bits = draw(st.sampled_from([("NaN", 0x7E00), ("+Inf", 0x7C00), ("-Inf", 0xFC00), ("-1", 0xBC00),
                                               ("65504", 0x7BFF), ("-0", 0x8000)]))
            struct.pack_into("<H", b, off + 2 * i, bits)
        else:
            name, val = draw(st.sampled_from([("NaN", math.nan), ("+Inf", math.inf), ("-Inf", -math.inf),
                                              ("-1", -1.0), ("3e38", 3e38), ("-0", -0.0)]))
            struct.pack_into("<f", b, off + 4 * i, val)
        log.append(f"level 0 component {i} = {name}")
    return bytes(b), log


# --------------------------------------------------------------------------------------------
# OpenEXR header attributes


def exr_attributes(data: bytes) -> list[tuple[str, str, int, int]]:
    """``(name, type, value offset, value size)`` of each header attribute of a single-part EXR."""
    out = []
    pos = 8
    while pos < len(data) and data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        vpos = type_end + 5
        out.append((data[pos:name_end].decode("latin-1"), data[name_end + 1:type_end].decode("latin-1"), vpos, size))
        pos = vpos + size
    return out


@st.composite
def mutated_exr_attribute(draw: st.DrawFn, data: bytes) -> tuple[bytes, list[str]]:
    """One OpenEXR header attribute changed: a 32-bit word of its value set to an edge value,
    its type name or its size field changed, or the first chunk offset moved."""
    attrs = exr_attributes(data)
    name, typ, vpos, size = draw(st.sampled_from(attrs))
    b = bytearray(data)
    op = draw(st.sampled_from(["word", "word", "byte", "size", "type", "offsets"]))
    if op == "word" and size >= 4:
        w = draw(st.integers(0, size // 4 - 1))
        old = struct.unpack_from("<i", data, vpos + 4 * w)[0]
        v = draw(st.sampled_from([0, -1, 1, 2**31 - 1, -(2**31), old + 1, old - 1, old * 6, 1 << 20]))
        v = max(-(2**31), min(2**31 - 1, v))
        struct.pack_into("<i", b, vpos + 4 * w, v)
        return bytes(b), [f"{name} ({typ}) word {w}: {old} -> {v}"]
    if op in ("word", "byte") and size >= 1:
        i = draw(st.integers(0, size - 1))
        v = draw(st.integers(0, 255))
        b[vpos + i] = v
        return bytes(b), [f"{name} ({typ}) byte {i} = {v}"]
    if op == "size":
        v = draw(st.sampled_from([0, -1, size + 1, size - 1, 1 << 30]))
        struct.pack_into("<i", b, vpos - 4, v)
        return bytes(b), [f"{name} size {size} -> {v}"]
    if op == "type":
        new = draw(st.sampled_from(["int", "float", "box2i", "chlist", "string", "envmap", "zzzz"]))
        tpos = vpos - 5 - len(typ)
        b[tpos:tpos + len(typ)] = new.encode()
        return bytes(b), [f"{name} type {typ} -> {new}"]
    # first entry of the chunk offset table (right after the header's terminating NUL)
    end = attrs[-1][2] + attrs[-1][3] + 1
    old = struct.unpack_from("<Q", data, end)[0]
    v = draw(st.sampled_from([0, 1, old + 1, old - 1, len(data), 2**63, 2**64 - 1]))
    struct.pack_into("<Q", b, end, v)
    return bytes(b), [f"chunk offset 0: {old} -> {v}"]

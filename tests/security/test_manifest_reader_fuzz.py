"""``read_manifest`` on hostile manifests: random mutations of a real ``manifest.json`` (a node
replaced by a random JSON value, a key removed or added, a file entry pointing outside the set,
deep nesting, an integer literal of thousands of digits, ``NaN``, truncation, bytes that are not
UTF-8).  The reader either returns a :class:`Manifest` whose files all lie inside the set, or
raises :class:`ManifestError` (one line naming the file); never another exception."""

from __future__ import annotations

import json
import math
from pathlib import PurePosixPath, PureWindowsPath

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from envcap.probeset.manifest import Manifest, ManifestError, read_manifest

JSON_LEAVES = (st.none() | st.booleans() | st.integers(-(2 ** 70), 2 ** 70) | st.sampled_from([2 ** 31, -1, 0, 10 ** 40])
               | st.floats(allow_nan=False, allow_infinity=False) | st.sampled_from([1e308, -1e-320, 3.5e38])
               | st.text(max_size=12) | st.sampled_from(["../x", "/etc/passwd", "", "a/../../b", "x\x00y"]))
JSON_VALUES = st.recursive(JSON_LEAVES, lambda inner: st.lists(inner, max_size=4)
                           | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=12)
HOSTILE_NAMES = ["/etc/passwd", "../secret", "a/../../secret", "./../secret", "..", "", "C:\\x", "\\\\host\\share\\x",
                 "x\x00", "ok/../../../x", "/", "."]


def nodes(doc, path=()):
    """Every path of keys and indices to a node of ``doc`` (the root excluded)."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        out.append((*path, k))
        out.extend(nodes(v, (*path, k)))
    return out


def parent_of(doc, path):
    for k in path[:-1]:
        doc = doc[k]
    return doc


@st.composite
def mutated(draw, text: str) -> bytes:
    """The bytes of a mutated manifest (the strategies of the module docstring)."""
    doc = json.loads(text)
    how = draw(st.sampled_from(["replace", "replace", "delete", "add", "file_name", "file_name", "nest", "huge_int",
                                "nan", "truncate", "bytes"]))
    if how in ("replace", "delete", "add"):
        path = draw(st.sampled_from(nodes(doc)))
        parent = parent_of(doc, path)
        if how == "replace":
            parent[path[-1]] = draw(JSON_VALUES)
        elif how == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(st.text(max_size=8))] = draw(JSON_VALUES)
        else:
            parent.append(draw(JSON_VALUES))
    elif how == "file_name":
        key = draw(st.sampled_from(["probes", "sky", "probes_atlas", "exr", "previews", "contact_sheet", "notes"]))
        name = draw(st.sampled_from(HOSTILE_NAMES) | st.text(max_size=10))
        doc["files"][key] = [name] if key in ("exr", "previews") or draw(st.booleans()) else name
    if how in ("replace", "delete", "add", "file_name"):
        return json.dumps(doc).encode()
    if how == "nest":
        depth = draw(st.sampled_from([50, 5000, 100_000]))
        key = draw(st.sampled_from(["resolution", "streets", "scene", "files"]))
        doc[key] = "@@"
        return json.dumps(doc).replace('"@@"', "[" * depth + "]" * depth).encode()
    if how == "huge_int":
        digits = draw(st.sampled_from([400, 4301, 20_000]))
        doc["resolution"] = "@@"
        return json.dumps(doc).replace('"@@"', "9" * digits).encode()
    if how == "nan":
        doc[draw(st.sampled_from(["probe_height", "probe_spacing", "resolution"]))] = "@@"
        return json.dumps(doc).replace('"@@"', draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e999"]))).encode()
    raw = json.dumps(doc).encode()
    if how == "truncate":
        return raw[:draw(st.integers(0, len(raw) - 1))]
    at = draw(st.integers(0, len(raw)))
    return raw[:at] + draw(st.binary(min_size=1, max_size=4)) + raw[at:]


def inside(name: str) -> bool:
    """An independent reading of "a relative path inside the set": POSIX and Windows forms."""
    p, w = PurePosixPath(name), PureWindowsPath(name)
    return (bool(name) and "\x00" not in name and not p.is_absolute() and not w.is_absolute() and not w.drive
            and ".." not in p.parts and ".." not in w.parts and p.parts not in ((), (".",)))


def file_names(m: Manifest) -> list[str]:
    f = m.files
    names = [f.probes, f.sky, f.sky_preview, f.contact_sheet, *(f.exr or ()), *(f.previews or ())]
    for v in f.extra.values():
        names.extend(v if isinstance(v, (list, tuple)) else [v])
    return [n for n in names if n is not None]


@pytest.fixture(scope="module")
def manifest_text(web_probe_dir):
    return (web_probe_dir / "manifest.json").read_text()


def test_mutated_manifests_parse_or_raise_manifest_error(manifest_text, tmp_path_factory):
    path = tmp_path_factory.mktemp("manifest_fuzz") / "manifest.json"
    outcomes = {"parsed": 0, "error": 0}
    base = json.loads(manifest_text)

    def nested(depth: int) -> bytes:
        return json.dumps({**base, "streets": "@@"}).replace('"@@"', "[" * depth + "]" * depth).encode()

    @settings(max_examples=300, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
    @given(data=mutated(manifest_text))
    @example(data=nested(100_000))
    @example(data=json.dumps({**base, "resolution": "@@"}).replace('"@@"', "9" * 5000).encode())
    @example(data=json.dumps({**base, "files": {**base["files"], "notes": "/etc/passwd"}}).encode())
    def check(data: bytes) -> None:
        path.write_bytes(data)
        try:
            m = read_manifest(path)
        except ManifestError as e:
            assert "\n" not in str(e) and len(str(e)) < 2000, str(e)[:300]
            outcomes["error"] += 1
            return
        assert isinstance(m, Manifest)
        assert all(inside(n) for n in file_names(m)), file_names(m)
        assert all(math.isfinite(v) for v in (m.probe_height, m.probe_spacing))
        outcomes["parsed"] += 1

    check()
    assert outcomes["parsed"] >= 10 and outcomes["error"] >= 50, outcomes

"""Probe-set directories: manifest, KTX2 textures, OpenEXR probes and PNG previews.

Layout of a probe-set directory (schema in ``docs/formats.md``)::

    manifest.json           format "envcap-probeset", version 1 (validated on read)
    probes.ktx2             cube-map array RGBA16F, one layer per probe, premultiplied, all levels
    sky.ktx2                plain cube RGBA32F (the sun exceeds the half-float range), all levels
    exr/probe_NNN.exr       level 0 of layer NNN: R, G, B, A (half) and Z = distance (float32, m)
    previews/probe_NNN.png  inside-view cross of level 0
    previews/sky.png, previews/contact_sheet.png

Layers are global over streets: ``streets[i].probes[j].layer`` indexes the one texture array.
"""

from __future__ import annotations

import copy
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from envcap import __version__
from envcap.core.atomic import atomic_output_dir
from envcap.formats.exr_cube import read_exr_cube, write_exr_cube
from envcap.formats.ktx2 import read_ktx2, write_ktx2

FORMAT = "envcap-probeset"
VERSION = 1
CUBE_CONVENTION = (
    "OpenGL cube map: faces +X,-X,+Y,-Y,+Z,-Z; arrays [layer, face, row=t, column=s, RGBA]; "
    "texel centers at s=(i+0.5)/N; see envcap/core/cube.py"
)
FIXED_FIELDS: dict[str, Any] = {
    "format": FORMAT,
    "version": VERSION,
    "units": "meters",
    "up_axis": "+Y",
    "handedness": "right",
    "cube_convention": CUBE_CONVENTION,
    "color": {"space": "linear Rec.709", "scale": "cd/m^2", "alpha": "premultiplied"},
}
PLANE_KEYS = ("facade_min", "facade_max", "ground")


@dataclass
class ProbeSet:
    """A probe set in memory.

    ``levels[k]``: probe-array mip level ``k``, float32 ``(L, 6, N_k, N_k, 4)``, premultiplied
    RGBA, ``N_k = max(1, N >> k)``.  ``distance``: ``(L, 6, N, N)`` float32 radial distance in
    meters from the probe center, 0 where alpha = 0 (level 0 only), or ``None``.
    ``sky_levels[k]``: sky mip level ``k``, float32 ``(6, M_k, M_k, 4)`` with alpha = 1.
    ``manifest``: the JSON manifest (schema in ``docs/formats.md``).
    """

    manifest: dict
    levels: list[NDArray]
    distance: NDArray | None
    sky_levels: list[NDArray]

    @property
    def layer_count(self) -> int:
        return int(self.levels[0].shape[0])

    @property
    def resolution(self) -> int:
        return int(self.levels[0].shape[2])


def new_manifest(resolution: int, level_count: int, **fields: Any) -> dict:
    """A manifest with the fixed fields, ``resolution`` and a ``levels`` table (``lobe_power``
    null), defaults for the other required fields, updated with ``fields``."""
    m: dict[str, Any] = copy.deepcopy(FIXED_FIELDS)
    m.update({
        "envcap_version": __version__,
        "resolution": int(resolution),
        "levels": [{"level": k, "size": max(1, int(resolution) >> k), "lobe_power": None} for k in range(level_count)],
        "lobes": {},
        "probe_height": 1.7,
        "probe_spacing": 1.0,
        "streets": [],
        "effects": [],
        "passes_run": [],
        "sky": {"spec": {}, "format": "RGBA32F", "sun": None},
        "files": {},
        "timings": {},
        "scene": {},
    })
    m.update(copy.deepcopy(fields))
    return m


def _err(where: str, msg: str) -> ValueError:
    return ValueError(f"{where}: {msg}")


def _num(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _check_planes(p: Any, where: str, *, allow_none: bool = False) -> None:
    if p is None and allow_none:
        return
    if not isinstance(p, dict) or not all(_num(p.get(k)) for k in PLANE_KEYS):
        raise _err(where, f"must be an object with finite numbers {list(PLANE_KEYS)}, got {p!r}")
    if not p["facade_max"] > p["facade_min"]:
        raise _err(where, f"facade_max {p['facade_max']} must exceed facade_min {p['facade_min']}")


def validate_manifest(m: Any, where: str = "manifest") -> int:
    """Check a manifest against the version-1 schema; return the number of probe layers.

    Raises ``ValueError`` naming the first problem found.
    """
    if not isinstance(m, dict):
        raise _err(where, "must be a JSON object")
    if m.get("format") != FORMAT:
        raise _err(where, f"format is {m.get('format')!r}, expected {FORMAT!r}")
    if m.get("version") != VERSION:
        raise _err(where, f"version {m.get('version')!r} not supported (this envcap reads version {VERSION})")
    for k, v in FIXED_FIELDS.items():
        if k in ("format", "version", "cube_convention"):
            continue
        if m.get(k) != v:
            raise _err(where, f"{k} is {m.get(k)!r}, expected {v!r}")
    if not isinstance(m.get("cube_convention"), str):
        raise _err(where, "cube_convention must be a string")
    n = m.get("resolution")
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise _err(where, f"resolution must be a positive integer, got {n!r}")
    levels = m.get("levels")
    if not isinstance(levels, list) or not 1 <= len(levels) <= int(math.log2(n)) + 1:
        raise _err(where, f"levels must be a list of 1..{int(math.log2(n)) + 1} entries")
    for k, lev in enumerate(levels):
        if not isinstance(lev, dict) or lev.get("level") != k or lev.get("size") != max(1, n >> k):
            raise _err(where, f"levels[{k}] must be {{'level': {k}, 'size': {max(1, n >> k)}, ...}}, got {lev!r}")
        w = lev.get("lobe_power")
        if w is not None and not (_num(w) and w > 0):
            raise _err(where, f"levels[{k}].lobe_power must be a positive number or null, got {w!r}")
    for k in ("probe_height", "probe_spacing"):
        if not (_num(m.get(k)) and m[k] > 0):
            raise _err(where, f"{k} must be a positive number (meters), got {m.get(k)!r}")
    for k, typ in (("lobes", dict), ("streets", list), ("effects", list), ("passes_run", list),
                   ("sky", dict), ("files", dict), ("timings", dict), ("scene", dict)):
        if not isinstance(m.get(k), typ):
            raise _err(where, f"{k} must be a JSON {'object' if typ is dict else 'array'}")
    if m["sky"].get("format") != "RGBA32F" or not isinstance(m["sky"].get("spec"), dict):
        raise _err(where, "sky must have format 'RGBA32F' and a spec object")
    layers: list[int] = []
    for i, st in enumerate(m["streets"]):
        sw = f"{where}: streets[{i}]"
        if not isinstance(st, dict) or not isinstance(st.get("name"), str):
            raise ValueError(f"{sw}: must be an object with a name")
        if st.get("axis") not in ("x", "z"):
            raise ValueError(f"{sw} ({st['name']}): axis must be 'x' or 'z', got {st.get('axis')!r}")
        if not all(_num(st.get(k)) for k in ("start", "end", "center")) or not st["end"] > st["start"]:
            raise ValueError(f"{sw} ({st['name']}): start < end and center must be finite numbers")
        _check_planes(st.get("planes"), f"{sw}.planes")
        if not isinstance(st.get("probes"), list):
            raise ValueError(f"{sw}: probes must be a list")
        for j, pr in enumerate(st["probes"]):
            pw = f"{sw}.probes[{j}]"
            if not isinstance(pr, dict):
                raise ValueError(f"{pw}: must be an object")
            lay = pr.get("layer")
            if not isinstance(lay, int) or isinstance(lay, bool) or lay < 0:
                raise ValueError(f"{pw}: layer must be a non-negative integer, got {lay!r}")
            pos = pr.get("position")
            if not isinstance(pos, list) or len(pos) != 3 or not all(_num(x) for x in pos):
                raise ValueError(f"{pw}: position must be 3 finite numbers [x, y, z] (m), got {pos!r}")
            _check_planes(pr.get("planes"), f"{pw}.planes")
            fp = pr.get("fitted_planes")
            if fp is not None and not isinstance(fp, dict):
                raise ValueError(f"{pw}: fitted_planes must be an object or null")
            layers.append(lay)
    if sorted(layers) != list(range(len(layers))):
        raise _err(where, f"probe layers must be 0..{len(layers) - 1}, each once; got {sorted(layers)}")
    return len(layers)


def _check_chain(levels: Any, layered: bool, what: str) -> int:
    if not isinstance(levels, (list, tuple)) or not levels:
        raise ValueError(f"{what}: need a non-empty list of mip levels")
    a0 = np.asarray(levels[0])
    nd = 5 if layered else 4
    if a0.ndim != nd or a0.shape[-4] != 6 or a0.shape[-1] != 4 or a0.shape[-2] != a0.shape[-3] or a0.shape[-2] < 1:
        raise ValueError(f"{what}: level 0 must be {'(L, 6, N, N, 4)' if layered else '(6, N, N, 4)'}, got {a0.shape}")
    n = a0.shape[-2]
    for k, lev in enumerate(levels):
        a = np.asarray(lev)
        want = a0.shape[:-3] + (max(1, n >> k), max(1, n >> k), 4)
        if a.shape != want:
            raise ValueError(f"{what}: level {k} must have shape {want}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what}: level {k} contains NaN or Inf")
    return n


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"{type(o).__name__} is not JSON serializable")


def _plain_manifest(m: dict) -> dict:
    """Deep copy of ``m`` as plain JSON types (numpy scalars/arrays converted); strict JSON."""
    try:
        return json.loads(json.dumps(m, default=_json_default, allow_nan=False))
    except (TypeError, ValueError) as e:
        raise ValueError(f"manifest is not strict JSON (no NaN/Inf, only JSON types): {e}") from e


def _check_probe_set(ps: ProbeSet) -> None:
    layers = validate_manifest(ps.manifest)
    n = _check_chain(ps.levels, True, "probe levels")
    _check_chain(ps.sky_levels, False, "sky levels")
    L = ps.levels[0].shape[0]
    if L != layers or L < 1:
        raise ValueError(f"probe levels have {L} layers but the manifest lists {layers} probes")
    if n != ps.manifest["resolution"] or len(ps.levels) != len(ps.manifest["levels"]):
        raise ValueError(
            f"probe levels ({len(ps.levels)} levels of {n}) disagree with the manifest "
            f"({len(ps.manifest['levels'])} levels of {ps.manifest['resolution']})"
        )
    if ps.distance is not None:
        d = np.asarray(ps.distance)
        if d.shape != (L, 6, n, n):
            raise ValueError(f"distance must have shape {(L, 6, n, n)}, got {d.shape}")
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            raise ValueError("distance must be finite and >= 0 (meters)")
        if np.any((np.asarray(ps.levels[0])[..., 3] == 0) & (d != 0)):
            raise ValueError("distance must be 0 where alpha is 0 (sky)")


def write_probe_set(out_dir: str | os.PathLike[str], probe_set: ProbeSet, *, exr: bool = True, previews: bool = True) -> Path:
    """Write ``probe_set`` as a probe-set directory at ``out_dir``, atomically; return its path.

    Validates the manifest and the arrays first (``ValueError``); on any error nothing is left
    behind and an existing ``out_dir`` is untouched.  ``manifest["files"]`` is filled here (the
    caller's dict is not modified).  Probe data must fit half floats (±65504); the sky is float32.
    """
    from envcap.formats.png_preview import contact_sheet_png, cube_cross_png

    manifest = _plain_manifest(probe_set.manifest)
    ps = ProbeSet(manifest, probe_set.levels, probe_set.distance, probe_set.sky_levels)
    _check_probe_set(ps)
    L = ps.levels[0].shape[0]
    files: dict[str, Any] = {"probes": "probes.ktx2", "sky": "sky.ktx2"}
    kv = {"envcapManifest": "manifest.json", "envcapFormat": f"{FORMAT} {VERSION}"}
    with atomic_output_dir(out_dir) as tmp:
        write_ktx2(tmp / "probes.ktx2", [np.asarray(a) for a in ps.levels], layered=True, fmt="rgba16f",
                   kv={**kv, "envcapContent": "probes"}, premultiplied=True)
        write_ktx2(tmp / "sky.ktx2", [np.asarray(a) for a in ps.sky_levels], layered=False, fmt="rgba32f",
                   kv={**kv, "envcapContent": "sky"})
        if exr:
            (tmp / "exr").mkdir()
            files["exr"] = []
            for i in tqdm(range(L), desc="probe EXR", unit="probe", disable=None):
                name = f"exr/probe_{i:03d}.exr"
                dist = None if ps.distance is None else np.asarray(ps.distance[i])
                write_exr_cube(tmp / name, np.asarray(ps.levels[0][i]), dist, half=True)
                files["exr"].append(name)
        if previews:
            (tmp / "previews").mkdir()
            files["previews"] = []
            for i in tqdm(range(L), desc="previews", unit="probe", disable=None):
                name = f"previews/probe_{i:03d}.png"
                cube_cross_png(tmp / name, np.asarray(ps.levels[0][i]))
                files["previews"].append(name)
            cube_cross_png(tmp / "previews/sky.png", np.asarray(ps.sky_levels[0]))
            files["sky_preview"] = "previews/sky.png"
            labels = [f"layer {i}" for i in range(L)]
            for st in manifest["streets"]:
                for pr in st["probes"]:
                    labels[pr["layer"]] = f"{st['name']} #{pr['layer']}"
            contact_sheet_png(tmp / "previews/contact_sheet.png", [np.asarray(a) for a in ps.levels[0]], labels)
            files["contact_sheet"] = "previews/contact_sheet.png"
        manifest["files"] = files
        (tmp / "manifest.json").write_text(json.dumps(manifest, indent=2, allow_nan=False) + "\n")
    return Path(out_dir).resolve()


def read_probe_set(path: str | os.PathLike[str], *, distance: bool = True) -> ProbeSet:
    """Read a probe-set directory; validate the manifest and the textures against it.

    Probe levels come back as float32 (from RGBA16F, exact), the sky as float32.  ``distance``
    is read from the EXR files' Z channels when they exist (and ``distance`` is true), else
    ``None``.  Raises ``FileNotFoundError`` for missing files and ``ValueError`` for bad content.
    """
    root = Path(path)
    if not root.is_dir():
        raise FileNotFoundError(f"probe-set directory not found: {root}")
    mpath = root / "manifest.json"
    if not mpath.is_file():
        raise FileNotFoundError(f"{root} is not a probe set: manifest.json missing")
    try:
        manifest = json.loads(mpath.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{mpath}: not valid JSON ({e})") from e
    layers = validate_manifest(manifest, str(mpath))
    files = manifest["files"]
    for key in ("probes", "sky"):
        if not isinstance(files.get(key), str):
            raise ValueError(f"{mpath}: files.{key} missing")
    levels, info = read_ktx2(root / files["probes"])
    n = manifest["resolution"]
    if info["fmt"] != "rgba16f" or not info["layered"]:
        raise ValueError(f"{files['probes']}: expected an RGBA16F cube-map array, got {info['fmt']} layered={info['layered']}")
    if info["layers"] != layers or info["size"] != n or info["level_count"] != len(manifest["levels"]):
        raise ValueError(
            f"{files['probes']}: {info['layers']} layers x {info['level_count']} levels of {info['size']}, "
            f"manifest says {layers} probes x {len(manifest['levels'])} levels of {n}"
        )
    sky, sinfo = read_ktx2(root / files["sky"])
    if sinfo["fmt"] != "rgba32f" or sinfo["layered"]:
        raise ValueError(f"{files['sky']}: expected a plain RGBA32F cube map, got {sinfo['fmt']} layered={sinfo['layered']}")
    dist = None
    exr_files = files.get("exr")
    if distance and exr_files:
        if not isinstance(exr_files, list) or len(exr_files) != layers:
            raise ValueError(f"{mpath}: files.exr must list one EXR per probe ({layers})")
        ds = []
        for name in exr_files:
            _, d = read_exr_cube(root / name)
            if d is None or d.shape != (6, n, n):
                raise ValueError(f"{name}: missing or mis-sized Z (distance) channel")
            ds.append(d)
        dist = np.stack(ds).astype(np.float32)
    return ProbeSet(manifest=manifest, levels=levels, distance=dist, sky_levels=sky)

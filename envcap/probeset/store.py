"""Probe-set directories: written through the output writers, atomically; read back and checked.

Layout of a probe-set directory with envcap's writers (``docs/formats.md``)::

    manifest.json           format "envcap-probeset", version 1 (docs/manifest.schema.json)
    probes.ktx2             cube-map array RGBA16F, one layer per probe, premultiplied, all levels
    sky.ktx2                plain cube RGBA32F (the sun exceeds the half-float range), all levels
    exr/probe_NNN.exr       level 0 of layer NNN: R, G, B, A (half) and Z = distance (float32, m)
    previews/probe_NNN.png  inside-view cross of level 0
    previews/sky.png, previews/contact_sheet.png

Layers are global over streets: ``streets[i].probes[j].layer`` indexes the one texture array.
Which files are written is up to the writers (:mod:`envcap.formats.registry`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from envcap.core.contained_path import resolve_inside
from envcap.core.input_path import require_dir
from envcap.formats.exr_cube import read_exr_cube
from envcap.formats.ktx2 import read_ktx2
from envcap.formats.registry import default_writer_names, select_writers
from envcap.formats.writer import MANIFEST_FILE, FileEntries
from envcap.outputs import atomic_output_dir
from envcap.probeset.city_index import INDEX_FILE, merge_shards, read_city_index
from envcap.probeset.manifest import Files, ManifestError, read_manifest, write_manifest
from envcap.probeset.probe_set import ProbeSet, check_probe_set, check_texels
from envcap.probeset.progress import BakeProgress


def write_probe_set(
    out_dir: str | os.PathLike[str],
    probe_set: ProbeSet,
    *,
    exr: bool = True,
    previews: bool = True,
    writers: Iterable[str] | None = None,
) -> Path:
    """Write ``probe_set`` as a probe-set directory at ``out_dir`` (a path, or an
    :class:`envcap.outputs.OutputClaim` claimed before the bake), atomically; return its path.

    ``writers``: names of the output writers to run (default: every default writer); the
    required ones (``ktx2``) always run; ``exr=False`` / ``previews=False`` leave those writers
    out.  Checks the manifest and the arrays first (``ValueError``); on any error nothing is left
    behind and an existing ``out_dir`` is untouched.  The written manifest's ``files`` lists the
    writers' entries (``probe_set`` is not modified).  Probe data must fit half floats (±65504);
    the sky is float32.
    """
    names = [n for n in (default_writer_names() if writers is None else writers)
             if (exr or n != "exr") and (previews or n != "previews")]
    chosen = select_writers(names)
    probe_set.manifest.to_json()  # strict JSON and every manifest rule, before anything is written
    check_probe_set(probe_set)
    with atomic_output_dir(out_dir, kind="probe-set") as tmp:
        fill_probe_set_dir(tmp, probe_set, [w.name for w in chosen], checked=True)
    return Path(out_dir).resolve()


def fill_probe_set_dir(tmp: Path, probe_set: ProbeSet, writers: Iterable[str], *, written: FileEntries | None = None,
                       checked: bool = False, report: BakeProgress | None = None) -> None:
    """Run the output ``writers`` (plus the required ones) into ``tmp`` (a directory from
    :func:`envcap.outputs.atomic_output_dir`) and write the manifest: the body of
    :func:`write_probe_set`, for callers that write some files themselves while the bake runs
    (:class:`envcap.formats.probe_files.ProbeFileWriter`); ``written``: those files' entries.
    Checks the manifest and the arrays first unless ``checked`` (``ValueError``).  ``report``:
    one stage ``write <name>`` per writer."""
    chosen = select_writers(writers)
    if not checked:
        probe_set.manifest.to_json()
        check_probe_set(probe_set)
    entries: FileEntries = {}
    for writer in chosen:
        with (report or BakeProgress("off")).stage(f"write {writer.name}", probe_set.layer_count) as stage:
            got = writer.write(tmp, probe_set)
            stage.advance(probe_set.layer_count)
        taken = sorted(set(got) & set(entries))
        if taken:
            raise ValueError(f"probe-set writer {writer.name!r}: files entries {taken} already written")
        entries.update(got)
    taken = sorted(set(written or {}) & set(entries))
    if taken:
        raise ValueError(f"files entries {taken} written twice")
    entries.update(written or {})
    try:
        files = Files.from_json(entries)
    except ManifestError as e:
        raise ValueError(f"probe-set writers returned bad files entries: {e}") from None
    write_manifest(tmp / MANIFEST_FILE, replace(probe_set.manifest, files=files))


def distance_from_inverse(path: Path, shape: tuple[int, int, int, int]) -> NDArray[np.float32]:
    """The distance channel ``(L, 6, N, N)`` (m, float32; 0 where the probe sees the sky) from an
    ``inverse_distance.ktx2`` (:mod:`envcap.formats.inverse_distance_writer`): ``1 / texel``,
    within 2^-11 relative of the baked distance (half-float texels)."""
    levels, info = read_ktx2(path)
    if info["fmt"] != "r16f" or not info["layered"] or levels[0].shape[:4] != shape:
        raise ValueError(f"{path.name}: expected an R16F cube-map array of shape {shape}, "
                         f"got {info['fmt']} layered={info['layered']} {levels[0].shape[:4]}")
    inv = levels[0][..., 0].astype(np.float64)
    if not np.all(np.isfinite(inv)) or np.any(inv < 0):
        raise ValueError(f"{path.name}: inverse distances must be finite and >= 0")
    return np.where(inv > 0, 1.0 / np.where(inv > 0, inv, 1.0), 0.0).astype(np.float32)


def read_probe_set(path: str | os.PathLike[str], *, distance: bool = True) -> ProbeSet:
    """Read a probe-set directory, or a city probe set (a directory with ``city.json``: its
    shards merged, :func:`read_city_probe_set`); check the manifest and the textures against it.

    Probe levels come back as float32 (from RGBA16F, exact), the sky as float32.  ``distance``
    is read from the EXR files' Z channels when they exist (and ``distance`` is true), else from
    ``inverse_distance.ktx2`` when it exists (:func:`distance_from_inverse`), else ``None``.  Raises ``FileNotFoundError`` for missing files and ``ValueError`` for bad content,
    one line naming the file: every number of the manifest within float32 range, every texel of
    ``probes.ktx2`` and ``sky.ktx2`` finite with RGB >= 0 and alpha in [0, 1]
    (:func:`envcap.probeset.probe_set.check_texels`: the layer and level at fault), distances
    finite and >= 0.  A file the manifest names is read only from inside the set: a name or a
    symbolic link that leads outside it is a ``ValueError`` naming the entry
    (:func:`envcap.core.contained_path.resolve_inside`).
    """
    root = require_dir(path, "probe-set directory")
    if (root / INDEX_FILE).is_file() and not (root / MANIFEST_FILE).is_file():
        return read_city_probe_set(root, distance=distance)
    mpath = root / MANIFEST_FILE
    if not mpath.is_file():
        raise FileNotFoundError(f"{root} is not a probe set: {MANIFEST_FILE} missing")
    manifest = read_manifest(mpath)
    layers, n = manifest.layer_count, manifest.resolution
    files = manifest.files
    if files.probes is None or files.sky is None:
        raise ValueError(f"{mpath}: files.{'probes' if files.probes is None else 'sky'} missing")
    def inside(name: str, key: str) -> Path:   # a manifest is untrusted: never follow a name or a link out of the set
        return resolve_inside(root, name, f"{mpath}: files.{key}")

    levels, info = read_ktx2(inside(files.probes, "probes"))
    per = 1 if manifest.ladder is None else manifest.ladder.per_level   # a rung ladder: per layers per probe
    if info["fmt"] != "rgba16f" or not info["layered"]:
        raise ValueError(f"{files.probes}: expected an RGBA16F cube-map array, got {info['fmt']} layered={info['layered']}")
    if info["layers"] != layers * per or info["size"] != n or info["level_count"] != len(manifest.levels):
        raise ValueError(
            f"{files.probes}: {info['layers']} layers x {info['level_count']} levels of {info['size']}, "
            f"manifest says {layers} probes{f' x {per} rungs' if per > 1 else ''} x {len(manifest.levels)} levels of {n}"
        )
    check_texels(levels, True, str(root / files.probes))
    sky, sinfo = read_ktx2(inside(files.sky, "sky"))
    rungs = manifest.ladder is not None
    if sinfo["fmt"] != "rgba32f" or sinfo["layered"] != rungs or (rungs and sinfo["layers"] != per):
        raise ValueError(f"{files.sky}: expected {f'a {per}-layer RGBA32F cube-map array (manifest.ladder)' if rungs else 'a plain RGBA32F cube map'}, "
                         f"got {sinfo['fmt']} layered={sinfo['layered']} with {sinfo['layers']} layers")
    check_texels(sky, rungs, str(root / files.sky))
    dist = None
    if distance and not files.exr and files.extra.get("inverse_distance"):
        dist = distance_from_inverse(inside(files.extra["inverse_distance"], "inverse_distance"), (layers, 6, n, n))
    if distance and files.exr:
        if len(files.exr) != layers:
            raise ValueError(f"{mpath}: files.exr must list one EXR per probe ({layers})")
        ds = []
        for name in files.exr:
            _, d = read_exr_cube(inside(name, "exr"))
            if d is None or d.shape != (6, n, n):
                raise ValueError(f"{name}: missing or mis-sized Z (distance) channel")
            ds.append(d)
        dist = np.stack(ds).astype(np.float32)
    if not rungs:
        return ProbeSet(manifest=manifest, levels=levels, distance=dist, sky_levels=sky)
    return ProbeSet(manifest=manifest, levels=[lv[0::per] for lv in levels], distance=dist,
                    sky_levels=[lv[0] for lv in sky], rungs=levels, sky_rungs=sky)


def read_city_probe_set(path: str | os.PathLike[str], *, distance: bool = True) -> ProbeSet:
    """Read every shard of the city probe set at ``path`` (the directory of ``city.json``, or
    the file) and merge them into one probe set whose layers are the city's
    (:func:`envcap.probeset.city_index.merge_shards`); each shard is read and checked by
    :func:`read_probe_set`, then checked against the index."""
    root = Path(path)
    root = root.parent if root.name == INDEX_FILE and root.is_file() else root
    index = read_city_index(root)
    shards = [read_probe_set(resolve_inside(root, sh.path, f"{root / INDEX_FILE}: shards[{i}].path", "the city"),
                             distance=distance) for i, sh in enumerate(index.shards)]
    return merge_shards(index, shards, str(root / INDEX_FILE))

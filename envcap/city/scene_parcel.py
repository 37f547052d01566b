"""The scene as it travels to Dask workers: the scene the client loaded and hashed, with the bytes
of the files it still reads during a bake, and no path of the client's machine.

Why the built scene and not its files (issue 19, a cluster without a shared disk): a worker may
not see the client's disk at all, nor the same relative or absolute paths.  The client has
already parsed the TOML and imported every mesh (Mitsuba XML and the PLYs it names, OBJ with its
MTL and textures, a folder of meshes): what a bake needs of those is in the :class:`Scene`
arrays, whose content is the key the plan was made with (:func:`envcap.city.plan.scene_hash`).
Shipping that object means the set of files a mesh import reads never has to be known, a worker
bakes exactly what was hashed, and it imports nothing.  The only files a bake still opens are
those the sky parameters name (a ``latlong`` sky's image, read by ``SkySpec.build``): every
dataclass field of ``scene.sky.params`` that is a :class:`~pathlib.Path` to a file, the same
rule the scene hash uses to hash file bytes.  Their bytes travel in the parcel; a worker writes
each into a content-addressed folder (``SHA256/NAME``, :func:`unpack_scene`) and points the
field there.  Manifests name a sky file as the scene wrote it (``LatLongSky.file``), never by the
resolved path, so shard bytes do not depend on where the file lies.

The parcel is scattered once per bake (:mod:`envcap.city.dask_run`); Dask copies it to each
worker that runs a shard, and a worker unpacks it once (its baker caches scenes by digest).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from envcap.scene.model import Scene

SHIPPED = Path("<shipped>")
"""What a shipped file's field holds in the parcel (the client's path is not sent)."""


@dataclass(frozen=True)
class ShippedFile:
    """A file the scene reads during a bake: the sky parameter ``field`` that names it, the
    file's ``name`` (its extension picks the reader), ``sha256`` (hex) and ``data`` (bytes)."""

    field: str
    name: str
    sha256: str
    data: bytes


@dataclass(frozen=True)
class SceneParcel:
    """A scene for workers: its content hash ``digest`` (the plan's), the :class:`Scene` with
    no client path in it, and the files its sky reads (:class:`ShippedFile`)."""

    digest: str
    scene: Scene
    files: tuple[ShippedFile, ...] = ()

    @property
    def nbytes(self) -> int:
        """Bytes of the mesh arrays and the shipped files (what a transfer moves, roughly)."""
        m = self.scene.mesh
        arrays = (m.positions, m.normals, m.albedo, m.emission, m.indices, m.uv_layer, m.textures)
        return sum(a.nbytes for a in arrays if a is not None) + sum(len(f.data) for f in self.files)


def _file_fields(scene: Scene) -> list[tuple[str, Path]]:
    params = scene.sky.params
    if not dataclasses.is_dataclass(params):
        return []
    return [(f.name, v) for f in dataclasses.fields(params) if isinstance(v := getattr(params, f.name), Path)]


def _with_sky_paths(scene: Scene, paths: dict[str, Path], source: str) -> Scene:
    params = dataclasses.replace(scene.sky.params, **paths) if paths else scene.sky.params
    return dataclasses.replace(scene, sky=dataclasses.replace(scene.sky, params=params),
                               meta={**scene.meta, "source": source})


def pack_scene(scene: Scene, digest: str) -> SceneParcel:
    """The parcel of ``scene`` (content hash ``digest``): the files its sky names read now (on
    the client, where the paths resolve; ``FileNotFoundError`` naming a missing one), and every
    path of this machine replaced (the sky fields by :data:`SHIPPED`, ``meta["source"]`` by the
    file's name)."""
    files = []
    for name, path in _file_fields(scene):
        if not path.is_file():
            raise FileNotFoundError(f"scene {scene.name!r}: sky.{name}: {path} not found")
        data = path.read_bytes()
        files.append(ShippedFile(name, path.name, hashlib.sha256(data).hexdigest(), data))
    source = Path(str(scene.meta.get("source", ""))).name
    shipped = _with_sky_paths(scene, {f.field: SHIPPED for f in files}, source)
    return SceneParcel(digest, shipped, tuple(files))


def unpack_scene(parcel: SceneParcel, folder: str | os.PathLike[str]) -> Scene:
    """The parcel's scene with each shipped file written under ``folder`` as ``SHA256/NAME``
    (written once: an existing file of that content is reused; a new one is written under a
    temporary name and renamed) and its sky field pointing there."""
    paths = {}
    for f in parcel.files:
        if hashlib.sha256(f.data).hexdigest() != f.sha256:
            raise ValueError(f"shipped sky file {f.name!r} arrived damaged (SHA-256 differs)")
        target = Path(folder) / f.sha256 / Path(f.name).name
        if not target.is_file():
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.tmp-", dir=target.parent)
            with os.fdopen(fd, "wb") as out:
                out.write(f.data)
            os.replace(tmp, target)
        paths[f.field] = target
    return _with_sky_paths(parcel.scene, paths, str(parcel.scene.meta.get("source", "")))

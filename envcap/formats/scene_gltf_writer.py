"""Probe-set writer ``scene_gltf`` (opt-in: ``envcap capture --scene-gltf``): ``scene.glb``, the
scene's geometry near the streets as binary glTF for the viewer (``envcap view``) and engines.

* ``scene.glb``: the scene mesh cropped to the manifest streets' boxes grown by
  :data:`~envcap.formats.scene_gltf.DEFAULT_PAD_M` meters; layout (origin node, flat normals,
  linear albedo in ``COLOR_0``, ``_EMISSION``) in :mod:`envcap.formats.scene_gltf`.

Manifest entry: ``files.scene_gltf`` (a writer's extra ``files`` key, as ``probes_atlas``).
Parameters: the scene (the probe set does not hold its geometry) and the padding.

A probe-set writer gets only ``(out_dir, probe_set)``, so this writer is made for one scene by
:func:`scene_gltf_writer` and is in the registry only inside :func:`registered_scene_writer`
(``with registered_scene_writer(scene) as names: ... writers=[..., *names]``).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from envcap.formats.registry import WRITERS, register_writer, unregister_writer
from envcap.formats.scene_gltf import DEFAULT_PAD_M, SCENE_GLB, crop_to_streets, write_scene_glb
from envcap.formats.writer import FileEntries, ProbeSetWriter
from envcap.scene.model import Scene

if TYPE_CHECKING:
    from envcap.probeset.probe_set import ProbeSet

NAME = "scene_gltf"
"""The writer's registry name (and its manifest ``files`` key)."""


def scene_gltf_writer(scene: Scene, pad_m: float = DEFAULT_PAD_M) -> ProbeSetWriter:
    """The ``scene_gltf`` writer for ``scene`` (not registered; ``default=False``)."""

    def write(out_dir: Path, ps: ProbeSet) -> FileEntries:
        write_scene_glb(out_dir / SCENE_GLB, crop_to_streets(scene.mesh, ps.manifest.streets, pad_m))
        return {NAME: SCENE_GLB}

    return ProbeSetWriter(NAME, "scene.glb: the scene mesh near the streets as binary glTF (viewer, engines)",
                          write, default=False)


@contextmanager
def registered_scene_writer(scene: Scene | None, pad_m: float = DEFAULT_PAD_M) -> Iterator[list[str]]:
    """Register :func:`scene_gltf_writer` ``(scene)`` for the ``with`` block and yield
    ``["scene_gltf"]`` (the names to add to a bake's writers); ``scene=None`` yields ``[]`` and
    registers nothing.  ``ValueError`` if a ``scene_gltf`` writer is registered already."""
    if scene is None:
        yield []
        return
    if NAME in WRITERS:
        raise ValueError(f"a probe-set writer named {NAME!r} is already registered")
    register_writer(scene_gltf_writer(scene, pad_m))
    try:
        yield [NAME]
    finally:
        unregister_writer(NAME)

"""City scenes: the scene model, TOML parsing into typed specs, building, mesh import, bundled scenes.

Pipeline: :func:`load_scene` = :func:`~envcap.scene.parse.parse_scene` (TOML -> :class:`SceneSpec`,
every number within its range of :mod:`envcap.scene.limits`) then
:func:`~envcap.scene.build.build_scene` (-> :class:`Scene`, bounded first by
:mod:`envcap.scene.estimate`).
"""

from envcap.scene.build import build_scene
from envcap.scene.bundled import list_scenes, scene_path
from envcap.scene.load import load_scene, scene_from_dict
from envcap.scene.mesh_import import import_mesh, import_transform
from envcap.scene.model import EFFECTS, Scene, SceneMesh, Street
from envcap.scene.parse import parse_scene
from envcap.scene.spec import SceneSpec

__all__ = [
    "EFFECTS",
    "Scene",
    "SceneMesh",
    "SceneSpec",
    "Street",
    "build_scene",
    "import_mesh",
    "import_transform",
    "list_scenes",
    "load_scene",
    "parse_scene",
    "scene_from_dict",
    "scene_path",
]

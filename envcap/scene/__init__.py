"""City scenes: the scene model, and loaders for bundled TOML streets and imported meshes."""

from envcap.scene.mesh_import import import_mesh, import_transform
from envcap.scene.model import EFFECTS, Scene, SceneMesh, Street
from envcap.scene.toml_scene import list_scenes, load_scene, scene_from_dict

__all__ = [
    "EFFECTS",
    "Scene",
    "SceneMesh",
    "Street",
    "import_mesh",
    "import_transform",
    "list_scenes",
    "load_scene",
    "scene_from_dict",
]

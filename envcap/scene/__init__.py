"""City scenes: the scene model, and loaders for bundled TOML streets and imported meshes."""

from envcap.scene.model import EFFECTS, Scene, SceneMesh, Street

__all__ = ["EFFECTS", "Scene", "SceneMesh", "Street"]

"""The sky registry: ``[sky] type`` -> :class:`~envcap.sky.base.SkyModel`, and the typed :class:`SkySpec`.

A scene's ``[sky]`` table is parsed once (:func:`parse_sky_spec`) into a :class:`SkySpec`: the
model's name and its typed parameters.  :meth:`SkySpec.build` makes the :class:`Sky`.

Adding a sky model: write ``envcap/sky/<name>.py`` with the :class:`Sky` subclass, its parameters
dataclass (``parse`` / ``build``) and a ``SkyModel``, then import it here and list it in
:data:`BUILTIN_SKY_MODELS` (or call :func:`register_sky` from your own code).  ``docs/sky.md`` has
the recipe; ``tests/sky/test_sky_registry.py`` does it for a ``uniform_grey`` sky.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from envcap.sky import latlong, preetham, uniform
from envcap.sky.base import Sky, SkyModel
from envcap.core.checks import check_table_keys

BUILTIN_SKY_MODELS: tuple[SkyModel, ...] = (preetham.PREETHAM, latlong.LATLONG, uniform.UNIFORM)
"""The sky models envcap ships, registered at import."""

SKY_MODELS: dict[str, SkyModel] = {}
"""Registered sky models by ``[sky] type`` name (filled at import; :func:`register_sky` adds)."""


def register_sky(model: SkyModel) -> SkyModel:
    """Make ``model`` available as ``[sky] type = model.name``; a taken name is an error."""
    if not isinstance(model, SkyModel):
        raise TypeError(f"register_sky needs a SkyModel, got {type(model).__name__}")
    if model.name in SKY_MODELS:
        raise ValueError(f"sky type {model.name!r} is already registered")
    reserved = {"type", "sun_light"} & (model.required | model.optional)
    if reserved:
        raise ValueError(f"sky type {model.name!r}: keys {sorted(reserved)} are reserved")
    SKY_MODELS[model.name] = model
    return model


for _model in BUILTIN_SKY_MODELS:
    register_sky(_model)


@dataclass(frozen=True)
class SkySpec:
    """A scene's ``[sky]`` table, parsed: the registered model ``type`` and its typed ``params``.

    ``sun_light`` is the derived sun entry a :meth:`Sky.spec` output carries (manifests):
    ``sun_light_given`` says whether the table had the key; :meth:`build` then checks that it
    matches the sky the other keys give.
    """

    type: str
    params: Any
    sun_light: dict[str, Any] | None = None
    sun_light_given: bool = False

    def build(self) -> Sky:
        """The :class:`Sky` (lat-long files are read here).  ``ValueError`` if ``sun_light`` disagrees."""
        sky = SKY_MODELS[self.type].build(self.params)
        if self.sun_light_given:
            want = sky.sun_light()
            given = self.sun_light
            if (given is None) != (want is None) or (want is not None and not _close_tables(given, want)):
                raise ValueError("sky.sun_light is derived from the other keys and does not match them; "
                                 "edit the sun parameters instead (or drop sun_light)")
        return sky


def parse_sky_spec(table: Any, base_dir: Path | None = None) -> SkySpec:
    """Check a scene's ``[sky]`` table (or a :meth:`Sky.spec` output) and type it.

    The table's ``type`` selects a registered model (:data:`SKY_MODELS`); its keys must be the
    model's ``required`` plus any of its ``optional`` (and ``sun_light``).  Relative file names
    resolve against ``base_dir``.  Unknown keys or types raise ``ValueError`` naming them.
    """
    if not isinstance(table, dict):
        raise ValueError(f"sky spec must be a table, got {type(table).__name__}")
    kind = table.get("type")
    model = SKY_MODELS.get(kind) if isinstance(kind, str) else None
    if model is None:
        raise ValueError(f"sky: unknown type {kind!r}; known: {sorted(SKY_MODELS)}")
    check_table_keys(table, {"type", *model.required}, {"sun_light", *model.optional}, f"sky ({kind})")
    return SkySpec(kind, model.parse(table, base_dir), table.get("sun_light"), "sun_light" in table)


def sky_from_spec(table: Any, base_dir: Path | None = None) -> Sky:
    """Build a sky from a ``[sky]`` table or a :meth:`Sky.spec` output: ``parse_sky_spec(...).build()``.

    Kinds (see each model's module)::

        {"type": "preetham", "turbidity": 3.0, "sun_elevation_deg": 35, "sun_azimuth_deg": 120,
         "scale": 1.0, "ground_albedo": 0.2}
        {"type": "latlong", "file": "sky.exr", "scale": 1.0, "sanitize": false,
         "sun": {"elevation_deg": 40, "azimuth_deg": 0, "illuminance": 90000 or [r, g, b],
                 "angular_radius_deg": 0.2665}}
        {"type": "uniform", "radiance": [r, g, b], "sun": {...}}
    """
    return parse_sky_spec(table, base_dir).build()


def _close_tables(a: Any, b: dict) -> bool:
    if not isinstance(a, dict) or set(a) != set(b):
        return False
    for k, v in b.items():
        try:
            if not np.allclose(np.asarray(a[k], dtype=np.float64), np.asarray(v, dtype=np.float64),
                               rtol=1e-9, atol=1e-12):
                return False
        except (TypeError, ValueError):
            return False
    return True

"""The registry of parallax methods: how a lookup turns a shading point, a direction and a lobe
power into the street radiance fetched from the probes.

A method is a :class:`ParallaxMethod`: a name, a function ``street_rgba(chains, street, x, d, w,
**parameters) -> (..., 4)`` (premultiplied street RGBA; the caller composites the sky over it),
what it needs (the plane set its street carries, the distance channel) and its parameters.  The
built-in methods are registered by ``envcap/runtime/methods/__init__.py``; :func:`register` adds
one from anywhere (a plugin, a test).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.named_registry import NamedRegistry
from envcap.runtime.chains import ProbeChains
from envcap.runtime.street import PLANE_SETS, RuntimeStreet

StreetRGBA = Callable[..., NDArray[np.float64]]
"""``street_rgba(chains: ProbeChains, street: RuntimeStreet, x (..., 3), d (..., 3), w (...), **parameters)
-> (..., 4)``: ``x`` shading points (m), ``d`` unit directions, both in the street's frame (its
planes: ``street.lookup_planes``), ``w`` lobe powers (``inf`` = mirror),
all broadcast to one shape; returns premultiplied street RGBA (alpha < 1 where the sky shows)."""


@dataclass(frozen=True)
class ParallaxMethod:
    """One parallax method.

    ``name``: registry key.  ``street_rgba``: see :data:`StreetRGBA`.  ``summary``: one line for
    help texts.  ``planes``: the plane set (:data:`envcap.runtime.street.PLANE_SETS`) the caller
    puts into the :class:`RuntimeStreet`.  ``needs_distance``: the method reads
    ``ProbeChains.distance``.  ``parameters``: keyword arguments passed to ``street_rgba``
    (documented in the method's file).  ``glsl``: the runtime GLSL function that computes the same
    lookup (street and sky), ``None`` for a numpy-only (reference) method.
    """

    name: str
    street_rgba: StreetRGBA
    summary: str
    planes: str = "nominal"
    needs_distance: bool = False
    parameters: Mapping[str, Any] = field(default_factory=dict)
    glsl: str | None = None

    def __post_init__(self) -> None:
        if not self.name or not self.name.isidentifier():
            raise ValueError(f"method name must be an identifier, got {self.name!r}")
        if self.planes not in PLANE_SETS:
            raise ValueError(f"method {self.name}: planes must be one of {PLANE_SETS}, got {self.planes!r}")

    def __call__(self, chains: ProbeChains, street: RuntimeStreet, x: ArrayLike, d: ArrayLike,
                 w: ArrayLike) -> NDArray[np.float64]:
        """Street RGBA ``(..., 4)`` of WORLD shading points ``x`` along unit WORLD directions ``d`` at
        lobe powers ``w`` (broadcast; vectors ``(..., 3)``): both are turned into the street's frame
        (:meth:`RuntimeStreet.to_frame`) before ``street_rgba`` sees them, so a method works in
        the frame (probe positions, planes, fetch directions) and the caller keeps the world."""
        if self.needs_distance and chains.distance is None:
            raise ValueError(f"method {self.name} needs the probe set's distance channel (EXR files)")
        x = street.to_frame(np.asarray(x, dtype=np.float64))      # world -> the street's frame (a no-op
        d = street.direction_to_frame(np.asarray(d, dtype=np.float64))   # for a street without one)
        shape = np.broadcast_shapes(x.shape, d.shape)
        x, d = np.broadcast_to(x, shape), np.broadcast_to(d, shape)
        w = np.broadcast_to(np.asarray(w, dtype=np.float64), shape[:-1])
        return self.street_rgba(chains, street, x, d, w, **self.parameters)


_registry: NamedRegistry[ParallaxMethod] = NamedRegistry("parallax method", ParallaxMethod)

register = _registry.register
"""Add a parallax method under its name (``replace``: allow overriding one of the same name); returns it."""
unregister = _registry.unregister
"""Remove and return the parallax method of that name."""
get = _registry.get
"""The registered parallax method of that name (a :class:`ParallaxMethod` is returned as is; ``ValueError``
listing the known names)."""
registered = _registry.names
"""Names of the registered parallax methods, in registration order."""

"""The registry of placement strategies: how the probes of a street are placed along it.

A strategy is a :class:`PlacementStrategy`: a name, a function ``place(context, street, counts,
**parameters)`` that returns one :class:`StreetPlacement` per asked probe count (the probes'
along-street coordinates and what the strategy wants recorded about its choice), a summary, its
parameters with their defaults and whether it needs a GL context (pre-captures, evaluator passes).
The built-in strategies are registered by ``envcap/placement/__init__.py``; :func:`register` adds
one from anywhere (a plugin, a test): ``envcap capture --placement NAME`` and ``envcap bench
placement --strategies NAME`` find it by name.

Conventions: meters, along-street coordinates in the street's frame
(:class:`envcap.scene.model.Street`: ``start`` < ``end`` along its axis); a placement's
coordinates are strictly increasing and lie within ``[start, end]``
(:func:`envcap.probeset.placement.check_along`, checked on every call).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.named_registry import NamedRegistry
from envcap.probeset.placement import check_along
from envcap.scene.model import Scene, Street


@dataclass(frozen=True)
class PlacementContext:
    """What a strategy may use besides the street: the ``scene`` (its mesh and sky, for
    pre-captures), the probes' ``height`` above the ground (m), the bake's face size
    ``resolution`` (texels), ``gl``, a moderngl context (``None``: a strategy that needs one
    makes its own) and ``verbose``: say on stderr what a long placement will cost."""

    scene: Scene
    height: float = 2.0
    resolution: int = 64
    gl: Any = None
    verbose: bool = False


@dataclass(frozen=True)
class StreetPlacement:
    """The probes a strategy placed on one street: ``along`` ``(P,)`` coordinates (m, the street's
    frame, strictly increasing, within the street) and ``notes``, plain-JSON facts about the
    choice (recorded per street in the manifest's ``placement.streets``)."""

    along: NDArray[np.float64]
    notes: Mapping[str, Any] = field(default_factory=dict)


PlaceFn = Callable[..., Sequence[StreetPlacement]]
"""``place(context: PlacementContext, street: Street, counts: tuple[int, ...], **parameters) ->
one StreetPlacement per count`` (in the order of ``counts``; one analysis may serve several
counts, e.g. the Pareto curve of ``envcap bench placement``)."""


@dataclass(frozen=True)
class PlacementStrategy:
    """One placement strategy (module docstring).  ``parameters``: every keyword ``place`` takes,
    with its default (documented in the strategy's module); ``needs_gl``: ``place`` captures
    (``context.gl`` is then a context, made by :func:`envcap.placement.place.place_scene` if the
    caller has none)."""

    name: str
    place: PlaceFn
    summary: str
    parameters: Mapping[str, Any] = field(default_factory=dict)
    needs_gl: bool = False

    def __post_init__(self) -> None:
        if not self.name or not self.name.isidentifier():
            raise ValueError(f"placement strategy name must be an identifier, got {self.name!r}")

    def settings(self, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The parameters with ``overrides`` applied (``ValueError`` naming an unknown one)."""
        overrides = dict(overrides or {})
        unknown = sorted(set(overrides) - set(self.parameters))
        if unknown:
            raise ValueError(f"placement strategy {self.name!r} has no parameter(s) {unknown}; "
                             f"known: {', '.join(self.parameters) or 'none'}")
        return {**self.parameters, **overrides}

    def __call__(self, context: PlacementContext, street: Street, counts: Sequence[int],
                 **overrides: Any) -> tuple[StreetPlacement, ...]:
        """The placements of ``street`` for each of ``counts`` (each >= 1), checked: exactly that
        many probes, strictly increasing, inside the street (``ValueError`` naming the strategy)."""
        counts = tuple(int(n) for n in counts)
        if not counts or min(counts) < 1:
            raise ValueError(f"placement strategy {self.name!r}: probe counts must be >= 1, got {list(counts)}")
        out = tuple(self.place(context, street, counts, **self.settings(overrides)))
        if len(out) != len(counts):
            raise ValueError(f"placement strategy {self.name!r} returned {len(out)} placements for {len(counts)} counts")
        checked = []
        for n, placed in zip(counts, out):
            try:
                along = check_along(street, placed.along)
            except ValueError as e:
                raise ValueError(f"placement strategy {self.name!r}: {e}") from None
            if along.size != n:
                raise ValueError(f"placement strategy {self.name!r} placed {along.size} probes on street "
                                 f"'{street.name}', asked for {n}")
            checked.append(StreetPlacement(along, dict(placed.notes)))
        return tuple(checked)


_registry: NamedRegistry[PlacementStrategy] = NamedRegistry("placement strategy", PlacementStrategy)

register = _registry.register
"""Add a placement strategy under its name (``replace``: allow overriding one of the same name); returns it."""
unregister = _registry.unregister
"""Remove and return the placement strategy of that name."""
get = _registry.get
"""The registered placement strategy of that name (a :class:`PlacementStrategy` is returned as is; ``ValueError``
listing the known names)."""
registered = _registry.names
"""Names of the registered placement strategies, in registration order."""

"""The registry of capture effects: one module per effect, registered here by name.

A scene lists effects by name; the capture applies those whose needs the scene meets, in
registry order, which is also the order of their per-set passes in ``passes_run`` and of their
terms in the shader.  What an effect declares: :mod:`envcap.capture.effects.base`.

Adding an effect: write ``envcap/capture/effects/NAME.py`` defining ``EFFECT =
CaptureEffect(...)`` (see ``sky_light.py`` for one with a pass, ``emissive_windows.py`` for the
simplest), then import it below and add it to ``BUILTIN_EFFECTS``.  Code outside envcap (or a
test) can :func:`register` one at run time.
"""

from __future__ import annotations

from typing import Iterable

from envcap.capture.effects import emissive_windows, sky_light, sun_light, sun_shadows
from envcap.capture.effects.base import CaptureEffect

BUILTIN_EFFECTS: tuple[CaptureEffect, ...] = (
    sun_light.EFFECT,
    sky_light.EFFECT,
    sun_shadows.EFFECT,
    emissive_windows.EFFECT,
)

_REGISTRY: dict[str, CaptureEffect] = {}


def register(effect: CaptureEffect) -> None:
    """Add ``effect`` after those registered so far.  Raises ``ValueError`` if its name is
    taken or an effect it requires is not registered."""
    if effect.name in _REGISTRY:
        raise ValueError(f"capture effect '{effect.name}' is already registered")
    missing = [r for r in effect.requires if r not in _REGISTRY]
    if missing:
        raise ValueError(f"capture effect '{effect.name}' requires unregistered effect(s) {missing}")
    _REGISTRY[effect.name] = effect


def unregister(name: str) -> None:
    """Remove effect ``name`` (``KeyError`` if absent, ``ValueError`` if another requires it)."""
    users = [e.name for e in _REGISTRY.values() if name in e.requires]
    if users:
        raise ValueError(f"capture effect '{name}' is required by {users}")
    del _REGISTRY[name]


def registered_effects() -> tuple[CaptureEffect, ...]:
    """All registered effects, in registry order."""
    return tuple(_REGISTRY.values())


def effect_names() -> tuple[str, ...]:
    """Names of the registered effects, in registry order."""
    return tuple(_REGISTRY)


def get_effect(name: str) -> CaptureEffect:
    """The effect registered as ``name``; ``ValueError`` naming the known ones if none is."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown effect '{name}'; known: {list(_REGISTRY)}") from None


def check_effects(names: Iterable[str]) -> frozenset[str]:
    """``names`` as a frozenset, checked: each registered, and listed with the effects it
    requires.  Raises ``ValueError`` ("unknown effect(s) [...]", "effect 'a' needs 'b'")."""
    listed = frozenset(names)
    unknown = sorted(listed - set(_REGISTRY))
    if unknown:
        raise ValueError(f"unknown effect(s) {unknown}; known: {list(_REGISTRY)}")
    for e in _REGISTRY.values():
        for r in e.requires:
            if e.name in listed and r not in listed:
                raise ValueError(f"effect '{e.name}' needs '{r}'")
    return listed


for _effect in BUILTIN_EFFECTS:
    register(_effect)

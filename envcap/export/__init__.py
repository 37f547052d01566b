"""Exports of a baked probe set for a platform: ``envcap export TARGET DIR --out OUT``.

* :mod:`~envcap.export.registry`: what a target is (:class:`ExportTarget`) and the targets by name;
* :mod:`~envcap.export.web`: target ``web``, a static site for WebGL2 and three.js.

Add a target: one module defining ``TARGET = ExportTarget(...)`` and one line in
:data:`envcap.export.registry.BUILTIN_TARGETS` (docs/architecture.md, "Where to add").
"""

from envcap.export.registry import ExportTarget, get_target, register_target, target_names, unregister_target

__all__ = ["ExportTarget", "get_target", "register_target", "target_names", "unregister_target"]

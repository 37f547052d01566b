"""HDR cube capture of a scene: the renderer, its projections, per-face culling, the sky SH, the
capture outputs, and ``effects/`` (one module per effect pass, and their registry).

Kept import-free: :mod:`envcap.scene.model` imports :mod:`envcap.capture.effects` to check the
effects a scene lists, and the renderer imports the scene model.
"""

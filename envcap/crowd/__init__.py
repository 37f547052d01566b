"""A lit crowd: walkers placed along a street's sidewalks (:mod:`~envcap.crowd.walkers`), their
skins per frame (:mod:`~envcap.crowd.instances`), the spheres they block light with
(:mod:`~envcap.crowd.sphere_buffer`), drawn with the runtime GLSL (:mod:`~envcap.crowd.renderer`,
``shaders/crowd/``) and written as PNG frames (:mod:`~envcap.crowd.frames`).  ``docs/crowd.md``."""

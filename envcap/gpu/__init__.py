"""Headless OpenGL: the EGL context, cube-map-array textures, shader loading, the GLSL test harness."""

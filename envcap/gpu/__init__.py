"""Headless OpenGL: the EGL context (``context``), cube-map textures (``cube_array``), reversed
float32 depth (``float_depth``), the strict uniform setter (``uniforms``), the GLSL harness."""

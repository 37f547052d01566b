"""HDR cube capture of a scene with moderngl."""

"""The runtime sampling library (numpy twin of the GLSL in shaders/): parallax, mip shift, sky composite, Eq. 3."""

"""The runtime sampling library's numpy twin (GLSL in ``shaders/runtime/``).

``limits`` (constants shared with GLSL), ``mip`` (lobe table, z(w), mip shift), ``parallax``
(probe selection, three-plane parallax), ``street`` (streets and their GLSL uniform struct),
``chains`` (a probe set's textures and the sky chain, checked finite), ``methods/`` (the registry of parallax methods),
``sampling`` (the full lookup: method + sky composite), ``shading`` (Eq. 3), ``lafortune``
(Lafortune BRDFs and quadrature references), ``synthetic_street`` (an analytic test street).
"""

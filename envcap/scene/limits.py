"""The documented ranges of a scene's numbers and the bounds on what a scene may build.

Every numeric key of a scene file is checked against its own range when the file is parsed
(:mod:`envcap.scene.parse`, the table in ``docs/scenes.md``, "Ranges and limits"); these are
the constants those ranges are made of, with their reasons.  Lengths in meters, radiance in the
sky's units (:mod:`envcap.sky.base`).  Every value inside them is a finite float32 far from
float32's range (3.4e38), so no later stage can overflow on them.
"""

from __future__ import annotations

COORDINATE_LIMIT_M = 1.0e7
"""Largest world coordinate (m, each axis, either sign) of any street end, facade plane, probe
line, building corner, ground corner or imported-mesh vertex.  Projected coordinates of any place
on Earth fit (a UTM northing is below 10^7 m, a geocentric coordinate below 6.4·10^6 m); a larger
value is a unit mistake (millimeters read as meters) or a typo.  Precision far from the origin is
kept by :func:`envcap.scene.model.local_origin`."""

SPAN_LIMIT_M = 2.0 * COORDINATE_LIMIT_M
"""Largest distance along a street (m): its ``length``, ``start_offset``, a ``gap``, ``gap_width``."""

SIZE_LIMIT_M = 1.0e4
"""Largest size of one element (m): street ``width``; building ``width``, ``height``, ``depth``,
``setback``; window sizes; wall ``height``, ``tile``, ``thickness``.  Ten times the tallest
building ever built; anything larger is not a city element."""

MIN_SIZE_M = 0.01
"""Smallest size of one element (m): window ``width``, ``height``, ``spacing``, ``floor_height``;
building ``height``, ``depth``, ``gap_width``; wall ``height``, ``tile``, ``thickness``; ground
``extent``, ``checker_extent``.  A centimeter is below a texel of any probe a few meters away;
smaller values (``1e-300``) were accepted silently and built invisible or degenerate geometry
(issue 20)."""

MIN_STREET_WIDTH_M = 1.0
"""Smallest street ``width`` (m, between the facade planes): the probe line runs in the middle and
the evaluator samples within the facades; a narrower gap is not a street (``width = 1e-300`` was
accepted and gave facade planes 5e-301 m from the probe line)."""

MIN_STREET_LENGTH_M = 1.0
"""Smallest street length (m): ``length``, ``end - start``, or ``p0`` to ``p1``."""

MIN_PIECE_M = 0.5
"""Building pieces narrower than this (m, along the street) are dropped after clipping, so no
building may be narrower: ``width`` of a listed building and the minimum of a ``random`` width."""

GROUND_EXTENT_LIMIT_M = 1.0e4
"""Largest ``[ground] extent``, ``checker_extent`` and ``checker`` (m).  The ground is one quad,
and the cube face looking down sees its corner at horizontal distance ``d`` from a probe ``h``
above it at window coordinate ``(d / h) (N / 2)`` texels, which float32 (24-bit significand)
holds exactly only below 2^24 ≈ 1.7·10^7; past it the rasterizer loses the quad's diagonal or a
whole triangle.  Measured with llvmpipe: no loss below 2^24, a crack along the diagonal from
2.7·10^7, texels of sky from d/h ≈ 3.5·10^6, half the down face sky from d/h ≈ 2.5·10^7
(``extent = 1e12``).  With 10 km, a probe at the default 2 m anywhere on the ground stays below
2^24 up to N = 4096.  A larger ground adds nothing visible: from 2 m, everything past 5 km lies
within 0.023 degrees of the horizon."""

MESH_SCALE_RANGE = (1.0e-6, 1.0e6)
"""``[mesh] scale`` (file units to meters): micrometers to thousands of kilometers."""

ANGLE_LIMIT_DEG = 360.0
"""Largest absolute rotation or azimuth (degrees): ``[mesh] rotation_deg``."""

SEED_LIMIT = 2**64 - 1
"""Largest side ``seed`` (non-negative: numpy's seed sequences take no negative entries)."""

EMISSION_LIMIT = 65504.0
"""Largest window ``emission`` (radiance, each channel): the largest finite half float.  Probe
radiance is stored as RGBA16F (``probes.ktx2``), so a brighter surface could never be stored and
would fail only at write time, after the whole bake.  Light reflected on top of the emission (sun,
sky) can still pass it; the bake checks the captured probes before filtering them
(:mod:`envcap.probeset.half_range`)."""

FIRST_FLOOR_LIMIT = 10_000
"""Largest ``windows.first_floor`` (a floor index)."""

BUILDING_LIMIT = 20_000
"""Most buildings a scene may place (random rows are estimated before any is drawn: the street
length after ``start_offset`` over the minimum ``width``, or ``count`` if smaller).  About 30 s
to build at the limit on one shared core (measured 20,000 buildings without windows in 34 s;
each building is checked against every one placed before it, so time grows faster than the
count)."""

QUAD_LIMIT = 4_000_000
"""Most quads (2 triangles each) a scene may build, estimated before building: 5 per building
piece, 1 per window (5 with a frame), 1 per wall or ground checker tile.  About 40 s and 3 GiB
to build at the limit on one core (measured: ~10 µs and ~800 bytes per quad)."""

BYTES_PER_QUAD = 800
"""Peak memory per quad while a scene is built (float64 corners and attributes, their float32
mesh, measured ~770 bytes): the estimate :func:`envcap.core.budget.check_bytes` is given."""
